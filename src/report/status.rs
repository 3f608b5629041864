//! The floor for what the chain's stages say about themselves beside the data: the
//! source's ingest counters ([`IngestStats`]), the telemetry stage's signal health
//! ([`SignalHealth`]) and the uplink a sink may send frames back on ([`LinkHandle`]). A
//! sink gets all three as one typed handle, [`ChainStatus`], and never imports the stages
//! that fill it. Imports nothing of ours.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::Instant;

/// What one vehicle chain publishes about itself, shared by every sink of that chain.
#[derive(Debug, Clone, Default)]
pub struct ChainStatus {
    /// The source's counters (frames, junk, gaps, windows, silences).
    pub stats: Arc<IngestStats>,
    /// Which message feeds each signal and what is stale (refreshed about once a second).
    pub health: HealthHandle,
    /// Frames a sink sends back on the live link the source reads.
    pub link: LinkHandle,
    /// Cancelled when the run is asked to stop (Ctrl-C, SIGTERM): the one stop signal, so
    /// a sink that outlives its reports (the dashboard lingering) ends with everyone else.
    pub shutdown: tokio_util::sync::CancellationToken,
    /// The MAVLink system id of the vehicle the chain follows, once the telemetry stage has
    /// locked onto one (0 until then).
    pub system_id: Arc<std::sync::atomic::AtomicU8>,
    /// The network the chain's vehicle flies on (`crate::report::VehicleId::network`; 0: the
    /// only one). Set when the chain starts, with [`ChainStatus::link`] that network's.
    pub network: u8,
    /// Message → estimate latency of every report (all vehicles), for the run's summary.
    pub latency: Arc<LatencyHistogram>,
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
    /// however many frames it lost; see `source::frame`) plus clock jumps (see
    /// `source::frame::timed::Clock`).
    pub gaps: AtomicU64,
    /// The clock jumps among `gaps`: a tlog stamp or `time_boot_ms` that went backwards,
    /// leapt ahead or was absurd.
    pub clock_jumps: AtomicU64,
    /// Bytes that were not part of any frame (line noise, garbage between frames).
    pub junk_bytes: AtomicU64,
    /// Windows built by the telemetry stage.
    pub windows: AtomicU64,
    /// Times a live link went silent (no good frame for the link's silence limit (`source::links::link::SILENCE`)).
    pub silences: AtomicU64,
    /// Whether the live link is silent right now (the terminal view shows it).
    pub silent: AtomicBool,
    /// Frames whose MAVLink 2 signature checked against the link's key (among `frames_ok`).
    pub signed_ok: AtomicU64,
    /// Frames dropped because their signature did not match the key (`source::links::signing`).
    pub signature_bad: AtomicU64,
    /// Signed frames dropped as replays: a timestamp not newer than the stream's last, or
    /// a new stream over a minute behind.
    pub signature_replay: AtomicU64,
    /// Unsigned frames dropped because `[link] require_signing` is set.
    pub unsigned_refused: AtomicU64,
    /// How deep the queues between the stages have been.
    pub queues: QueueGauge,
    /// Several links: copies of a message already heard on another link, dropped.
    pub duplicates: AtomicU64,
    /// Several links: each link's health, refreshed about once a second (empty with one).
    pub links: std::sync::Mutex<Vec<LinkHealth>>,
    /// A recorded log's first timestamp, µs since the Unix epoch (0: none, or not a Unix
    /// clock): messages' times count from it. The vehicle store measures the gap between two
    /// replayed flights on it.
    pub log_origin_us: AtomicU64,
}

impl IngestStats {
    /// [`Self::log_origin_us`] in seconds, when it is a Unix time.
    pub fn log_origin_s(&self) -> Option<f64> {
        let us = self
            .log_origin_us
            .load(std::sync::atomic::Ordering::Relaxed);
        crate::features::units::unix_clock(us as f64 * 1e-6)
    }
}

/// One link's health when a source reads several (`source::links`): what the summary,
/// the terminal and the dashboard show per link.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct LinkHealth {
    /// The link's address as given.
    pub name: String,
    /// The network it belongs to (`[[links]] network`), when the links are separate
    /// networks: its name and number (`crate::report::VehicleId::network`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub network: Option<(String, u8)>,
    /// Messages it brought, copies included.
    pub frames: u64,
    /// Of those, copies of a message another link brought first.
    pub duplicates: u64,
    /// Messages it brought in the last second.
    pub rate_hz: f64,
    /// The share of the last second's merged stream it did not bring, %.
    pub loss_pct: f64,
    /// How far behind the first copy its messages came in the last second (0 for the ones
    /// it brought first), mean, ms.
    pub latency_ms: f64,
    /// Seconds since it last brought a message; `None` before the first.
    pub last_heard_s: Option<f64>,
    /// Heard within the silence limit.
    pub live: bool,
}

/// The deepest any bounded queue between the stages has been (items waiting in one queue),
/// and when it first got that deep. The queues' memory grows with their depth and, bounded,
/// no further: growth of the process after the mark is not theirs (`scripts/soak.sh` reads
/// it so). Watched where items are sent: messages, windows, jobs, estimates, reports.
#[derive(Debug, Default)]
pub struct QueueGauge {
    peak: AtomicU64,
    peak_at_ms: AtomicU64,
    started: OnceLock<Instant>,
}

impl QueueGauge {
    /// Start the clock `peak_at_s` counts from (the run's start; else the first send).
    pub fn start(&self) {
        self.started.get_or_init(Instant::now);
    }
    /// A queue just sent to: its depth now.
    pub fn observe<T>(&self, tx: &tokio::sync::mpsc::Sender<T>) {
        let depth = (tx.max_capacity() - tx.capacity()) as u64;
        if depth > self.peak.load(Ordering::Relaxed)
            && self.peak.fetch_max(depth, Ordering::Relaxed) < depth
        {
            let ms = self.started.get_or_init(Instant::now).elapsed().as_millis();
            self.peak_at_ms
                .store(u64::try_from(ms).unwrap_or(u64::MAX), Ordering::Relaxed);
        }
    }
    /// (deepest, seconds after the start when it was reached).
    pub fn peak(&self) -> (u64, f64) {
        (
            self.peak.load(Ordering::Relaxed),
            self.peak_at_ms.load(Ordering::Relaxed) as f64 / 1000.0,
        )
    }
}

impl IngestStats {
    /// Add `n` to one counter.
    pub fn add(counter: &AtomicU64, n: u64) {
        counter.fetch_add(n, Ordering::Relaxed);
    }
    /// Each link's health, when the source reads several (empty otherwise).
    pub fn links(&self) -> Vec<LinkHealth> {
        self.links.lock().map(|g| g.clone()).unwrap_or_default()
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
            signed_ok: self.signed_ok.load(Ordering::Relaxed),
            signature_bad: self.signature_bad.load(Ordering::Relaxed),
            signature_replay: self.signature_replay.load(Ordering::Relaxed),
            unsigned_refused: self.unsigned_refused.load(Ordering::Relaxed),
            duplicates: self.duplicates.load(Ordering::Relaxed),
        }
    }
}

/// A plain copy of [`IngestStats`], as the summary line prints it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
/// Field order is the JSON summary line's contract (`sink::jsonl`).
pub struct StatsSnapshot {
    pub frames_ok: u64,
    pub frames_bad: u64,
    pub unknown: u64,
    pub gaps: u64,
    pub windows: u64,
    pub junk_bytes: u64,
    pub clock_jumps: u64,
    pub silences: u64,
    pub signed_ok: u64,
    pub signature_bad: u64,
    pub signature_replay: u64,
    pub unsigned_refused: u64,
    pub duplicates: u64,
}

/// The telemetry stage's latest `Telemetry::health`, shared with the terminal view (the
/// pipeline refreshes it about once a second; a reader only ever copies it).
pub type HealthHandle = std::sync::Arc<std::sync::Mutex<Vec<SignalHealth>>>;

/// Which source feeds one signal and whether it is stale: what the terminal view shows.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SignalHealth {
    /// Signal name (`attitude`, `velocity`, …; `mission` for speed/payload/altitude).
    pub signal: &'static str,
    /// Indices into [`crate::features::FEATURE_NAMES`] this signal fills (empty for power).
    pub features: Vec<usize>,
    /// MAVLink message currently feeding it (`config`/`default` for the mission); `None`
    /// when nothing has arrived yet.
    pub source: Option<&'static str>,
    /// Seconds since its last update, on the source clock.
    pub age_s: Option<f64>,
    /// No update for more than `stale_after_s`: its features are held and stale-marked.
    pub stale: bool,
}

/// A way for sinks to send frames back out on the live link the source reads (MAVLink
/// publishing "on the same link"). Empty unless the source is a live link. Where a frame
/// goes is the link's business (see `source::links::link`): the last UDP peer heard (`udpin:`), the
/// target (`udpout:`), every TCP client (`tcpin:`), the open connection (`tcpout:`,
/// `serial:`). Frames are whole encoded MAVLink frames.
///
/// It is also the one writer of dronewatt's own MAVLink identities on its link
/// ([`LinkHandle::send_as`]): the sink, the parameter reader and the mission client all
/// send as (the vehicle's system id, component 191), and one counter per identity on the
/// link numbers their frames, in the order they are queued, so a receiver counts no loss
/// that did not happen.
///
/// Where the links are separate networks (`source::links`), the handle a source was given
/// also holds one handle per network ([`LinkHandle::network`]): a vehicle's chain, the
/// sink and the mission client send to a vehicle on its own network's links only, each
/// network's writer numbering its own identities.
#[derive(Debug, Clone, Default)]
pub struct LinkHandle {
    writer: Arc<std::sync::Mutex<Writer>>,
    signer: Option<Arc<dyn FrameSigner>>,
    /// Per network (index = network number; index 0 unused), once the source has set them.
    networks: Arc<OnceLock<Vec<LinkHandle>>>,
}

/// The link's queue and the next sequence number of each identity sent as on it: one lock,
/// so a frame's number and its place in the queue are taken together.
#[derive(Debug, Default)]
struct Writer {
    tx: Option<tokio::sync::mpsc::Sender<Vec<u8>>>,
    seq: std::collections::HashMap<(u8, u8), u8>,
}

/// Signs outgoing MAVLink 2 frames with a link's key (MAVLink 1 or already signed frames
/// are left as they are). The link's own signing (`source::LinkSigning`) implements it.
pub trait FrameSigner: Send + Sync + std::fmt::Debug {
    fn sign(&self, frame: &mut Vec<u8>);
}

impl LinkHandle {
    /// A handle whose frames are signed by `signer` (none: sent as they are).
    pub fn with_signer(signer: Option<Arc<dyn FrameSigner>>) -> Self {
        Self {
            writer: Arc::default(),
            signer,
            networks: Arc::default(),
        }
    }
    /// The handle for network `n` (`crate::report::VehicleId::network`): its own when the
    /// source has separate networks and `n` is one of them, else this one.
    pub fn network(&self, n: u8) -> LinkHandle {
        self.networks
            .get()
            .and_then(|v| v.get(usize::from(n)))
            .filter(|_| n != 0)
            .cloned()
            .unwrap_or_else(|| self.clone())
    }
    /// Called once by a source with separate networks: one handle per network, index =
    /// network number (index 0: this handle's own place, unused).
    pub fn set_networks(&self, handles: Vec<LinkHandle>) {
        let _ = self.networks.set(handles);
    }
    /// The signer this handle signs with.
    pub fn signer(&self) -> Option<Arc<dyn FrameSigner>> {
        self.signer.clone()
    }
    /// Sign one frame in place when the link has a key.
    pub fn sign(&self, frame: &mut Vec<u8>) {
        if let Some(s) = &self.signer {
            s.sign(frame);
        }
    }
    /// Called by a live-link source once it can write.
    pub fn attach(&self, tx: tokio::sync::mpsc::Sender<Vec<u8>>) {
        if let Ok(mut g) = self.writer.lock() {
            g.tx = Some(tx);
        }
    }
    /// Queue one encoded frame for the link (signed first when the link has a key); false
    /// if there is no link or it is full. A frame of dronewatt's own goes through
    /// [`LinkHandle::send_as`] instead, which numbers it.
    pub fn try_send(&self, mut frame: Vec<u8>) -> bool {
        self.sign(&mut frame);
        match self.writer.lock() {
            Ok(g) => g.tx.as_ref().is_some_and(|tx| tx.try_send(frame).is_ok()),
            Err(_) => false,
        }
    }
    /// Send `msg` as (`system_id`, `component_id`): MAVLink 2, numbered by this link's one
    /// counter for that identity, signed when the link has a key, queued. False (and no
    /// number used) if there is no link or it is full.
    pub fn send_as(
        &self,
        system_id: u8,
        component_id: u8,
        msg: &mavlink::dialects::ardupilotmega::MavMessage,
    ) -> bool {
        let Ok(mut g) = self.writer.lock() else {
            return false;
        };
        let Writer { tx, seq } = &mut *g;
        let Some(permit) = tx.as_ref().and_then(|tx| tx.try_reserve().ok()) else {
            return false;
        };
        let seq = seq.entry((system_id, component_id)).or_insert(0);
        let header = mavlink::MavHeader {
            system_id: u32::from(system_id),
            component_id,
            sequence: *seq,
        };
        *seq = seq.wrapping_add(1);
        let mut frame = Vec::with_capacity(64);
        // Writing into a Vec cannot fail.
        let _ = mavlink::write_versioned_msg(&mut frame, mavlink::MavlinkVersion::V2, header, msg);
        self.sign(&mut frame);
        permit.send(frame);
        true
    }
    /// Frames queued and not yet written (0 without a link).
    pub fn pending(&self) -> usize {
        self.writer
            .lock()
            .ok()
            .and_then(|g| g.tx.as_ref().map(|tx| tx.max_capacity() - tx.capacity()))
            .unwrap_or(0)
    }
    /// Whether a live link is attached.
    pub fn is_attached(&self) -> bool {
        self.writer.lock().map(|g| g.tx.is_some()).unwrap_or(false)
    }
}

/// Message → estimate latency: how long from the arrival of the newest message behind an
/// estimate to its report being handed to the sinks. A fixed histogram of atomic counters
/// (no allocation per sample, shared by every vehicle's chain): log-spaced buckets, 8 per
/// octave of microseconds (a quantile is the bucket's upper edge, at most 12.5 % high;
/// the maximum is exact), from 1 µs to 2^39 µs (6 days; anything longer counts in the last).
#[derive(Debug)]
pub struct LatencyHistogram {
    buckets: [AtomicU64; LATENCY_BUCKETS],
    count: AtomicU64,
    max_us: AtomicU64,
}

/// Sub-buckets per octave, as a power of two.
const SUB_BITS: u32 = 3;
const LATENCY_BUCKETS: usize = (37 << SUB_BITS) as usize;

impl Default for LatencyHistogram {
    fn default() -> Self {
        Self {
            buckets: std::array::from_fn(|_| AtomicU64::new(0)),
            count: AtomicU64::new(0),
            max_us: AtomicU64::new(0),
        }
    }
}

/// Bucket of a latency in µs: values below 2^SUB_BITS exactly, then SUB_BITS bits of mantissa.
fn bucket(us: u64) -> usize {
    let sub = 1u64 << SUB_BITS;
    if us < sub {
        return us as usize;
    }
    let octave = 63 - us.leading_zeros(); // ≥ SUB_BITS
    let mantissa = (us >> (octave - SUB_BITS)) - sub; // 0..sub
    (((octave - SUB_BITS + 1) as u64 * sub + mantissa) as usize).min(LATENCY_BUCKETS - 1)
}

/// The largest µs value in bucket `i`.
fn bucket_top(i: usize) -> u64 {
    let sub = 1u64 << SUB_BITS;
    let i = i as u64;
    if i < sub {
        return i;
    }
    let octave = i / sub - 1 + u64::from(SUB_BITS);
    let mantissa = i % sub;
    ((sub + mantissa + 1) << (octave - u64::from(SUB_BITS))) - 1
}

impl LatencyHistogram {
    /// Count one latency.
    pub fn record(&self, d: std::time::Duration) {
        let us = u64::try_from(d.as_micros()).unwrap_or(u64::MAX);
        self.buckets[bucket(us)].fetch_add(1, Ordering::Relaxed);
        self.count.fetch_add(1, Ordering::Relaxed);
        self.max_us.fetch_max(us, Ordering::Relaxed);
    }
    /// Count, p50, p99 and maximum so far (`None` when nothing was counted).
    pub fn summary(&self) -> Option<LatencySummary> {
        let counts: Vec<u64> = self
            .buckets
            .iter()
            .map(|b| b.load(Ordering::Relaxed))
            .collect();
        let count: u64 = counts.iter().sum();
        if count == 0 {
            return None;
        }
        let max_us = self.max_us.load(Ordering::Relaxed);
        let quantile = |q: f64| {
            let rank = crate::features::units::ceil_ratio(q * count as f64, 1.0)
                .map_or(count, |r| r as u64)
                .clamp(1, count);
            let mut seen = 0;
            for (i, c) in counts.iter().enumerate() {
                seen += c;
                if seen >= rank {
                    return bucket_top(i).min(max_us);
                }
            }
            max_us
        };
        let ms = |us: u64| us as f64 / 1e3;
        Some(LatencySummary {
            count,
            p50_ms: ms(quantile(0.50)),
            p99_ms: ms(quantile(0.99)),
            max_ms: ms(max_us),
        })
    }
}

/// What [`LatencyHistogram::summary`] says: the summary line's `latency`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct LatencySummary {
    /// Estimates counted (every report made from a source's messages).
    pub count: u64,
    pub p50_ms: f64,
    pub p99_ms: f64,
    pub max_ms: f64,
}

impl std::fmt::Display for LatencySummary {
    /// `message → estimate p50 0.41 ms, p99 3.2 ms, max 12.0 ms (18465 estimates)`
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "message → estimate p50 {:.2} ms, p99 {:.2} ms, max {:.2} ms ({} estimates)",
            self.p50_ms, self.p99_ms, self.max_ms, self.count
        )
    }
}

#[cfg(test)]
mod latency_tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn buckets_are_contiguous_and_a_value_lies_in_its_own() {
        let mut prev_top = None;
        for i in 0..LATENCY_BUCKETS {
            let top = bucket_top(i);
            if let Some(p) = prev_top {
                assert!(top > p, "bucket {i}");
                assert_eq!(bucket(p + 1), i, "first value of bucket {i}");
            }
            assert_eq!(bucket(top), i, "top of bucket {i}");
            prev_top = Some(top);
        }
        for us in [0, 1, 7, 8, 9, 15, 16, 17, 1000, 12_345, 50_000, 10_000_000] {
            let i = bucket(us);
            assert!(
                bucket_top(i) >= us && bucket_top(i) as f64 <= us as f64 * 1.125 + 1.0,
                "{us} in bucket {i} (top {})",
                bucket_top(i)
            );
        }
        assert_eq!(bucket(u64::MAX), LATENCY_BUCKETS - 1);
    }

    #[test]
    fn quantiles_of_a_known_spread() {
        let h = LatencyHistogram::default();
        assert_eq!(h.summary(), None);
        // 1 ms … 100 ms, one each: p50 ≈ 50 ms, p99 ≈ 99 ms, max 100 ms exactly.
        for ms in 1..=100 {
            h.record(Duration::from_millis(ms));
        }
        let s = h.summary().unwrap();
        assert_eq!(s.count, 100);
        assert_eq!(s.max_ms, 100.0);
        assert!((50.0..=50.0 * 1.125).contains(&s.p50_ms), "{s:?}");
        assert!((99.0..=100.0).contains(&s.p99_ms), "{s:?}");
    }
}
