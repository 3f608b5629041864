//! Where MAVLink comes from. Every source yields [`TimedMessage`]s on a bounded channel
//! and counts what it could not use in a shared [`IngestStats`].
//!
//! Owner: foundation (issue 2) for frame/tlog/raw/link; features (issue 3) for dataset
//! and sim.

pub mod dataset;
pub mod tlog;
pub mod sim;

use std::sync::atomic::{AtomicU64, Ordering};

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
    /// Discontinuities: sequence-number gaps (lost frames) and clock jumps.
    pub gaps: AtomicU64,
    /// Bytes that were not part of any frame (line noise, garbage between frames).
    pub junk_bytes: AtomicU64,
    /// Windows built by the telemetry stage.
    pub windows: AtomicU64,
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
            Ok(f) if f > 0.0 && f.is_finite() => Ok(Speed::Factor(f)),
            _ => Err(format!("speed '{s}': expected a positive number (1 = real time) or 'max'")),
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
/// publishing "on the same link"). Empty unless the source is a live link.
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
/// Returns an error only for what makes the source unusable (missing file, bad address).
pub async fn run(
    spec: SourceSpec,
    tx: tokio::sync::mpsc::Sender<TimedMessage>,
    stats: std::sync::Arc<IngestStats>,
    link: LinkHandle,
    shutdown: tokio_util::sync::CancellationToken,
) -> anyhow::Result<()> {
    let _ = (spec, tx, stats, link, shutdown);
    anyhow::bail!("sources are not implemented yet")
}
