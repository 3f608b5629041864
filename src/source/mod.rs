//! Where MAVLink comes from. Every source yields [`TimedMessage`]s on a bounded channel
//! and counts what it could not use in a shared [`IngestStats`].
//!
//! ```text
//!  bytes ─▶ frame::FrameDecoder ─Frame─▶ timed::TimedReader ─TimedMessage─▶ channel
//!  (link.rs: udp/tcp/serial,   (CRC, resync,     (t_s: tlog stamp, time_boot_ms,
//!   tlog / raw files, dataset)  counters)         or arrival; clock jumps)
//! ```
//!
//! Owner: foundation (issue 2) for frame/timed/tlog/raw/link; features (issue 3) for
//! dataset and sim.

pub mod dataset;
pub mod frame;
pub mod link;
pub mod raw;
pub mod sim;
pub mod timed;
pub mod tlog;

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context;
use tokio::io::{AsyncRead, AsyncReadExt};
use tokio::sync::mpsc;
use tokio_util::sync::CancellationToken;

use timed::TimedReader;

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
}

/// Counters a source keeps of what it read and what it had to skip. Shared (Arc) so the
/// terminal view and the final summary can read them without a channel running backwards.
#[derive(Debug, Default)]
pub struct IngestStats {
    /// Frames whose CRC checked and whose payload decoded.
    pub frames_ok: AtomicU64,
    /// Frames with a bad CRC, a truncated body, or a payload that failed to decode.
    pub frames_bad: AtomicU64,
    /// Frames with a valid layout whose message id this dialect does not know.
    pub unknown: AtomicU64,
    /// Discontinuities: sequence-number gaps (one per break in a sender's sequence,
    /// however many frames it lost; see [`frame`]) plus clock jumps (see
    /// [`timed::Clock`]).
    pub gaps: AtomicU64,
    /// The clock jumps among `gaps`: a tlog stamp or `time_boot_ms` that went backwards,
    /// leapt ahead or was absurd.
    pub clock_jumps: AtomicU64,
    /// Bytes that were not part of any frame (line noise, garbage between frames).
    pub junk_bytes: AtomicU64,
    /// Windows built by the telemetry stage.
    pub windows: AtomicU64,
    /// Times a live link went silent (no good frame for [`link::SILENCE`]).
    pub silences: AtomicU64,
    /// Whether the live link is silent right now (the terminal view shows it).
    pub silent: AtomicBool,
}

impl IngestStats {
    /// Add `n` to one counter.
    pub fn add(counter: &AtomicU64, n: u64) {
        counter.fetch_add(n, Ordering::Relaxed);
    }
    /// A plain copy of the counters.
    pub fn snapshot(&self) -> StatsSnapshot {
        StatsSnapshot {
            frames_ok: self.frames_ok.load(Ordering::Relaxed),
            frames_bad: self.frames_bad.load(Ordering::Relaxed),
            unknown: self.unknown.load(Ordering::Relaxed),
            gaps: self.gaps.load(Ordering::Relaxed),
            junk_bytes: self.junk_bytes.load(Ordering::Relaxed),
            windows: self.windows.load(Ordering::Relaxed),
            clock_jumps: self.clock_jumps.load(Ordering::Relaxed),
            silences: self.silences.load(Ordering::Relaxed),
        }
    }
}

/// A plain copy of [`IngestStats`], as the summary line prints it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct StatsSnapshot {
    pub frames_ok: u64,
    pub frames_bad: u64,
    pub unknown: u64,
    pub gaps: u64,
    pub junk_bytes: u64,
    pub windows: u64,
    pub clock_jumps: u64,
    pub silences: u64,
}

/// How fast a recorded source plays.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Speed {
    /// Honour the recorded timestamps, scaled: 1.0 is real time, 10.0 ten times faster.
    Factor(f64),
    /// As fast as the pipeline takes it.
    Max,
}

impl std::str::FromStr for Speed {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        if s.eq_ignore_ascii_case("max") {
            return Ok(Speed::Max);
        }
        match s.trim_end_matches(['x', 'X']).parse::<f64>() {
            Ok(f) if (0.001..=1e6).contains(&f) => Ok(Speed::Factor(f)),
            _ => Err(format!("speed '{s}': expected a number from 0.001 to 1000000 (1 = real time) or 'max'")),
        }
    }
}

/// Which source a run reads.
#[derive(Debug, Clone)]
pub enum SourceSpec {
    /// A live link: `udpin:`/`udpout:`/`tcpin:`/`tcpout:`/`serial:` address.
    Link(String),
    /// A `.tlog` (8-byte big-endian µs timestamp before each frame).
    Tlog { path: std::path::PathBuf, speed: Speed },
    /// A raw MAVLink byte stream with no timestamps.
    Raw { path: std::path::PathBuf, speed: Speed },
    /// One flight of the M100 data set's `flights.csv[.gz]`, encoded as MAVLink.
    Dataset { path: std::path::PathBuf, flight: u32, speed: Speed },
}

/// A way for sinks to send frames back out on the live link the source reads (MAVLink
/// publishing "on the same link"). Empty unless the source is a live link. Where a frame
/// goes is the link's business (see [`link`]): the last UDP peer heard (`udpin:`), the
/// target (`udpout:`), every TCP client (`tcpin:`), the open connection (`tcpout:`,
/// `serial:`). Frames are whole encoded MAVLink frames.
#[derive(Debug, Clone, Default)]
pub struct LinkHandle(std::sync::Arc<std::sync::Mutex<Option<tokio::sync::mpsc::Sender<Vec<u8>>>>>);

impl LinkHandle {
    /// Called by a live-link source once it can write.
    pub fn attach(&self, tx: tokio::sync::mpsc::Sender<Vec<u8>>) {
        if let Ok(mut g) = self.0.lock() {
            *g = Some(tx);
        }
    }
    /// Queue one encoded frame for the link; false if there is no link or it is full.
    pub fn try_send(&self, frame: Vec<u8>) -> bool {
        match self.0.lock() {
            Ok(g) => g.as_ref().is_some_and(|tx| tx.try_send(frame).is_ok()),
            Err(_) => false,
        }
    }
    /// Whether a live link is attached.
    pub fn is_attached(&self) -> bool {
        self.0.lock().map(|g| g.is_some()).unwrap_or(false)
    }
}

/// Read `spec` until it ends or `shutdown` is cancelled, sending every decoded message.
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
    shutdown: CancellationToken,
) -> anyhow::Result<()> {
    match spec {
        SourceSpec::Link(address) => {
            let addr: link::LinkAddress = address.parse()?;
            link::run(addr, tx, stats, link, shutdown).await
        }
        SourceSpec::Tlog { path, speed } => {
            let f = open(&path).await?;
            replay(f, &path.display().to_string(), TimedReader::tlog(), speed, tx, &stats, shutdown).await
        }
        SourceSpec::Raw { path, speed } => {
            let f = open(&path).await?;
            replay(f, &path.display().to_string(), TimedReader::raw(), speed, tx, &stats, shutdown).await
        }
        SourceSpec::Dataset { path, flight, speed } => {
            let name = format!("{} flight {flight}", path.display());
            let bytes = tokio::task::spawn_blocking(move || dataset::flight_tlog(&path, flight)).await??;
            replay(&bytes[..], &name, TimedReader::tlog(), speed, tx, &stats, shutdown).await
        }
    }
}

async fn open(path: &std::path::Path) -> anyhow::Result<tokio::fs::File> {
    tokio::fs::File::open(path).await.with_context(|| format!("{}: cannot open", path.display()))
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
    loop {
        while let Some(m) = reader.next_message(stats) {
            if let Speed::Factor(f) = speed {
                // t_s is finite and never negative (timed::Clock), f is bounded (Speed).
                let due = start + Duration::try_from_secs_f64(m.t_s / f).unwrap_or(Duration::ZERO);
                if due > tokio::time::Instant::now() + Duration::from_millis(1) {
                    tokio::select! {
                        _ = shutdown.cancelled() => return Ok(()),
                        _ = tokio::time::sleep_until(due) => {}
                    }
                }
            }
            if !send(&tx, m, &shutdown).await {
                return Ok(());
            }
        }
        if eof {
            tracing::debug!("{name}: end of input");
            let s = stats.snapshot();
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
            reader.finish();
            eof = true;
        } else {
            reader.push(&buf[..n]);
            bytes_read += n as u64;
        }
    }
}

/// Send one message, waiting for room (back-pressure) unless shutdown comes first.
/// False when the run is over (shutdown, or nobody listens any more).
async fn send(tx: &mpsc::Sender<TimedMessage>, m: TimedMessage, shutdown: &CancellationToken) -> bool {
    if shutdown.is_cancelled() {
        return false;
    }
    match tx.try_send(m) {
        Ok(()) => true,
        Err(mpsc::error::TrySendError::Closed(_)) => false,
        Err(mpsc::error::TrySendError::Full(m)) => tokio::select! {
            _ = shutdown.cancelled() => false,
            r = tx.send(m) => r.is_ok(),
        },
    }
}
