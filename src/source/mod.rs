//! Where MAVLink comes from. Every source yields [`TimedMessage`]s on a bounded channel
//! and counts what it could not use in a shared [`IngestStats`].
//!
//! ```text
//!  bytes ─▶ frame::FrameDecoder ─Frame─▶ frame::timed::TimedReader ─TimedMessage─▶ channel
//!  (links: udp/tcp/serial,     (CRC, resync,     (t_s: tlog stamp, time_boot_ms,
//!   logs: tlog / raw, dataset)  counters)         or arrival; clock jumps)
//! ```
//!
//! | module | what it is |
//! |---|---|
//! | [`links`] | live links and transports: the address grammar, one link (UDP, TCP, serial), several merged, signing, the `[link]` table |
//! | [`logs`] | recorded formats, each writer beside its reader: `.tlog`, raw streams, DataFlash `.bin`, ULog `.ulg`, the M100 data set |
//! | [`frame`] | the frame decoder (CRC, resynchronisation, counters) and the clock that stamps decoded frames |
//! | [`messages`] | what messages mean: which senders are vehicles, what a message says about the pack's power |
//!
//! The simulator that writes tlogs is [`crate::sim`].

pub mod frame;
pub mod links;
pub mod logs;
pub mod messages;
pub mod nats;

use crate::report::status::{IngestStats, LinkHandle};
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context;
use tokio::io::{AsyncRead, AsyncReadExt};
use tokio::sync::mpsc;
use tokio_util::sync::CancellationToken;

use frame::timed::TimedReader;

use crate::MavMessage;

/// One decoded MAVLink message with the time it belongs to.
#[derive(Debug, Clone)]
pub struct TimedMessage {
    /// Seconds on the source's clock: the tlog timestamp, the arrival time on a live link,
    /// or `time_boot_ms` for a raw stream. Monotonic within one source run.
    pub t_s: f64,
    /// Sender system/component and sequence.
    pub header: mavlink::MavHeader,
    /// The message.
    pub msg: MavMessage,
    /// When it reached dronewatt (monotonic): read off a live link, or handed on by a
    /// paced replay at its due time. What the message → estimate latency is measured from
    /// ([`crate::report::status::LatencyHistogram`]).
    pub arrived: std::time::Instant,
    /// The network it came on (`crate::report::VehicleId::network`): 0 unless the links
    /// are separate networks ([`links`]).
    pub network: u8,
}

impl TimedMessage {
    /// `msg` from `header` at `t_s` on the source's clock, arriving now on network 0 (a
    /// reader's or a synthesiser's output; a merged link sets its `network`).
    pub fn new(t_s: f64, header: mavlink::MavHeader, msg: MavMessage) -> Self {
        Self {
            t_s,
            header,
            msg,
            arrived: std::time::Instant::now(),
            network: 0,
        }
    }
}

/// How fast a recorded source plays (replay), or a simulated one is sent (`simulate --udp`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Speed {
    /// Honour the recorded timestamps, scaled: 1.0 is real time, 10.0 ten times faster.
    Factor(f64),
    /// As fast as the pipeline takes it.
    Max,
}

impl std::str::FromStr for Speed {
    type Err = String;
    /// `max`, `real` (= 1), or a factor from 0.001 to 1000000, optionally with an `x`
    /// (`10`, `10x`), all case-insensitive.
    fn from_str(s: &str) -> Result<Self, String> {
        if s.eq_ignore_ascii_case("max") {
            return Ok(Speed::Max);
        }
        if s.eq_ignore_ascii_case("real") {
            return Ok(Speed::Factor(1.0));
        }
        match s.trim_end_matches(['x', 'X']).parse::<f64>() {
            Ok(f) if (0.001..=1e6).contains(&f) => Ok(Speed::Factor(f)),
            _ => Err(format!("speed '{s}': expected a number from 0.001 to 1000000 (1 = real time), 'real' or 'max'")),
        }
    }
}

/// Which source a run reads.
#[derive(Debug, Clone)]
pub enum SourceSpec {
    /// A live link: `udpin:`/`udpout:`/`tcpin:`/`tcpout:`/`serial:` address.
    Link(String),
    /// Several live links, merged and deduplicated ([`links`]); dronewatt's own frames on
    /// the best live one, or on `every_link`.
    Links {
        addresses: Vec<String>,
        /// Each address's network (`[[links]] network`; `""`: the default). Links on one
        /// network are one set of vehicles; on different ones, separate fleets.
        networks: Vec<String>,
        every_link: bool,
    },
    /// A `.tlog` (8-byte big-endian µs timestamp before each frame).
    Tlog {
        path: std::path::PathBuf,
        speed: Speed,
    },
    /// An autopilot's own log, ArduPilot DataFlash `.bin` ([`logs::dataflash`]) or PX4 ULog
    /// `.ulg` ([`logs::ulog`]), as the MAVLink a tlog gives.
    AutopilotLog {
        path: std::path::PathBuf,
        speed: Speed,
    },
    /// A raw MAVLink byte stream with no timestamps.
    Raw {
        path: std::path::PathBuf,
        speed: Speed,
    },
    /// A fleet worker's share of the NATS JetStream frame stream (`monitor --nats`:
    /// [`crate::source::nats::worker`]).
    Nats(crate::source::nats::NatsArgs),
    /// One flight of the M100 data set's `flights.csv[.gz]`, encoded as MAVLink.
    Dataset {
        path: std::path::PathBuf,
        flight: u32,
        speed: Speed,
    },
}

impl SourceSpec {
    /// A live source: links, or a fleet worker's share of the NATS stream.
    pub fn is_live(&self) -> bool {
        matches!(self, Self::Link(_) | Self::Links { .. } | Self::Nats(_))
    }

    /// A recorded source played flat out (`--speed max`): nothing waits on the clock, so
    /// the pipeline may gather its windows into large batches.
    pub fn is_flat(&self) -> bool {
        matches!(
            self,
            Self::Tlog {
                speed: Speed::Max,
                ..
            } | Self::AutopilotLog {
                speed: Speed::Max,
                ..
            } | Self::Raw {
                speed: Speed::Max,
                ..
            } | Self::Dataset {
                speed: Speed::Max,
                ..
            }
        )
    }
}

/// A live link's signing set-up (`[link] signing_key_file`): the signer for what
/// dronewatt sends and the verifier every incoming frame must pass, shared by every task
/// of the link. The sinks see only its signing side ([`crate::report::status::FrameSigner`]).
pub struct LinkSigning {
    signer: std::sync::Mutex<links::signing::Signer>,
    verifier: frame::SharedVerifier,
}

impl LinkSigning {
    /// Signer and verifier for this key.
    pub fn new(s: links::signing::Signing) -> Self {
        Self {
            signer: std::sync::Mutex::new(links::signing::Signer::new(&s)),
            verifier: Arc::new(std::sync::Mutex::new(links::signing::Verifier::new(s))),
        }
    }
    /// The verifier incoming frames must pass.
    pub fn verifier(&self) -> frame::SharedVerifier {
        self.verifier.clone()
    }
}

impl crate::report::status::FrameSigner for LinkSigning {
    fn sign(&self, frame: &mut Vec<u8>) {
        if let Ok(mut signer) = self.signer.lock() {
            signer.sign(frame);
        }
    }
}

impl std::fmt::Debug for LinkSigning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("LinkSigning")
    }
}

/// Read `spec` until it ends or `shutdown` is cancelled, sending every decoded message.
/// A live link with `signing` verifies what it reads (recorded files are read as they were
/// recorded).
/// Returns an error only for what makes the source unusable (missing file, bad address,
/// a port that cannot be bound); everything else is counted in `stats` and logged.
///
/// Recorded sources are paced by their `t_s`: [`Speed::Factor`]`(f)` sends a message at
/// `t_s / f` after the start, [`Speed::Max`] as fast as the bounded channel takes them.
pub async fn run(
    spec: SourceSpec,
    tx: mpsc::Sender<TimedMessage>,
    stats: Arc<IngestStats>,
    link: LinkHandle,
    signing: Option<Arc<LinkSigning>>,
    shutdown: CancellationToken,
) -> anyhow::Result<()> {
    stats.queues.start();
    let io = links::link::LinkIo {
        tx,
        stats,
        link,
        verifier: signing.map(|s| s.verifier()),
        shutdown,
    };
    match spec {
        SourceSpec::Link(address) => links::link::run(address.parse()?, io).await,
        SourceSpec::Links {
            addresses,
            networks,
            every_link,
        } => {
            let addrs = addresses
                .iter()
                .map(|a| a.parse::<links::address::LinkAddress>())
                .collect::<Result<Vec<_>, _>>()?;
            links::run(addrs, &networks, every_link, io).await
        }
        SourceSpec::Nats(a) => crate::source::nats::worker::run(a, io).await,
        SourceSpec::Tlog { ref path, speed } | SourceSpec::Raw { ref path, speed } => {
            let reader = if matches!(spec, SourceSpec::Tlog { .. }) {
                TimedReader::tlog()
            } else {
                TimedReader::raw()
            };
            let f = open(path).await?;
            let name = path.display().to_string();
            replay(f, &name, reader, speed, io.tx, &io.stats, io.shutdown).await
        }
        SourceSpec::AutopilotLog { path, speed } => {
            let msgs = {
                let (stats, path) = (io.stats.clone(), path.clone());
                tokio::task::spawn_blocking(move || logs::decode_autopilot_log(&path, &stats))
                    .await??
            };
            let start = tokio::time::Instant::now();
            for mut m in msgs {
                if !pace(start, &mut m, speed, &io.shutdown).await
                    || !send(&io.tx, m, &io.stats, &io.shutdown).await
                {
                    return Ok(());
                }
            }
            Ok(())
        }
        SourceSpec::Dataset {
            path,
            flight,
            speed,
        } => {
            let name = format!("{} flight {flight}", path.display());
            let bytes =
                tokio::task::spawn_blocking(move || logs::dataset::flight_tlog(&path, flight))
                    .await??;
            replay(
                &bytes[..],
                &name,
                TimedReader::tlog(),
                speed,
                io.tx,
                &io.stats,
                io.shutdown,
            )
            .await
        }
    }
}

async fn open(path: &std::path::Path) -> anyhow::Result<tokio::fs::File> {
    tokio::fs::File::open(path)
        .await
        .with_context(|| format!("{}: cannot open", path.display()))
}

/// Feed `input` through `reader`, pacing by `t_s` at `speed`, until the input ends, the
/// receiver goes away or `shutdown` is cancelled.
async fn replay<R: AsyncRead + Unpin>(
    mut input: R,
    name: &str,
    mut reader: TimedReader,
    speed: Speed,
    tx: mpsc::Sender<TimedMessage>,
    stats: &IngestStats,
    shutdown: CancellationToken,
) -> anyhow::Result<()> {
    let mut buf = vec![0u8; 64 * 1024];
    let start = tokio::time::Instant::now();
    let mut eof = false;
    let mut bytes_read = 0u64;
    // The log time reached, and the bad frames counted before the end of input: one more at
    // the end is a record cut off (a truncated file), said with where the log ends.
    let (mut last_t, mut bad_at_end) = (None, 0);
    loop {
        while let Some(mut m) = reader.next_message(stats) {
            last_t = Some(m.t_s);
            if !pace(start, &mut m, speed, &shutdown).await || !send(&tx, m, stats, &shutdown).await
            {
                return Ok(());
            }
        }
        if eof {
            tracing::debug!("{name}: end of input");
            let s = stats.snapshot();
            if let (Some(t), true) = (last_t, s.frames_bad > bad_at_end) {
                tracing::warn!("{name}: truncated: the file ends inside a record ({bytes_read} bytes); played what it has, up to {t:.1} s of log time");
            }
            if bytes_read > 0 && s.frames_ok == 0 {
                tracing::warn!(
                    "{name}: no MAVLink in this file: {bytes_read} bytes and not one valid frame \
                     ({} bad, {} of unknown id, {} junk bytes). Expected {}",
                    s.frames_bad,
                    s.unknown,
                    s.junk_bytes,
                    reader.expected_format()
                );
            }
            return Ok(());
        }
        let n = tokio::select! {
            _ = shutdown.cancelled() => return Ok(()),
            r = input.read(&mut buf) => r.with_context(|| format!("{name}: read failed"))?,
        };
        if n == 0 {
            bad_at_end = stats.snapshot().frames_bad;
            reader.finish();
            eof = true;
        } else {
            reader.push(&buf[..n]);
            bytes_read += n as u64;
        }
    }
}

/// Wait until a recorded message is due at `speed` (from `start`); it arrives then, as on
/// a live link (a replay running late counts its own delay in the latency). False when
/// shutdown came first.
async fn pace(
    start: tokio::time::Instant,
    m: &mut TimedMessage,
    speed: Speed,
    shutdown: &CancellationToken,
) -> bool {
    if let Speed::Factor(f) = speed {
        // t_s is finite and never negative (timed::Clock), f is bounded (Speed).
        let due = start + Duration::try_from_secs_f64(m.t_s / f).unwrap_or(Duration::ZERO);
        if due > tokio::time::Instant::now() + Duration::from_millis(1) {
            tokio::select! {
                _ = shutdown.cancelled() => return false,
                _ = tokio::time::sleep_until(due) => {}
            }
        }
        m.arrived = due.into_std().min(std::time::Instant::now());
    }
    true
}

/// Send one message, waiting for room (back-pressure) unless shutdown comes first.
/// False when the run is over (shutdown, or nobody listens any more).
async fn send(
    tx: &mpsc::Sender<TimedMessage>,
    m: TimedMessage,
    stats: &IngestStats,
    shutdown: &CancellationToken,
) -> bool {
    if shutdown.is_cancelled() {
        return false;
    }
    let sent = match tx.try_send(m) {
        Ok(()) => true,
        Err(mpsc::error::TrySendError::Closed(_)) => false,
        Err(mpsc::error::TrySendError::Full(m)) => tokio::select! {
            _ = shutdown.cancelled() => false,
            r = tx.send(m) => r.is_ok(),
        },
    };
    stats.queues.observe(tx);
    sent
}

#[cfg(test)]
mod tests {
    use super::Speed;

    #[test]
    fn speed_takes_what_replay_speed_and_simulate_rate_both_took() {
        let ok = |s: &str| s.parse::<Speed>().unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(ok("max"), Speed::Max);
        assert_eq!(ok("MAX"), Speed::Max);
        assert_eq!(ok("real"), Speed::Factor(1.0));
        assert_eq!(ok("Real"), Speed::Factor(1.0));
        assert_eq!(ok("40"), Speed::Factor(40.0));
        assert_eq!(ok("5x"), Speed::Factor(5.0));
        assert_eq!(ok("0.5X"), Speed::Factor(0.5));
        for bad in ["0", "-2", "fast", "nan", "inf", "2e6"] {
            let e = bad.parse::<Speed>().unwrap_err();
            assert!(e.contains(bad) && e.contains("real"), "{e}");
        }
    }
}
