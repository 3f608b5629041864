//! One fixed-rate resampler for every path: data-set rows at irregular 0.1/0.2 s and live
//! streams at mixed rates go through the same code, so training and live samples are built
//! the same way.
//!
//! - **Signals.** Each [`Signal`] is a small vector already in the data set's frame and
//!   units, updated at its own times. Times are integer microseconds on the source clock,
//!   so the grid and the interpolation weights are exact and identical whether a row comes
//!   from the CSV (`time` s) or from a `.tlog` (µs stamps).
//! - **Grid.** `t_k = t_0 + k / rate_hz`, `t_0` the first update. Grid point `t_k` is
//!   emitted once every signal is *ready*: it has an update at or past `t_k`, or it is
//!   *quiet* (no update for more than `stale_after_s`), in which case its last value is held
//!   and its features are marked stale. Latency is therefore bounded by the slowest source's
//!   period (1 s behind real time when the battery comes at 1 Hz, as on PX4: power is
//!   interpolated like the rest, since it is the models' target), and by `stale_after_s`
//!   when a source stops. Silence is counted from the start of the stream or from the end
//!   of the last gap, whichever is later.
//! - **Interpolation.** Linear between the bracketing updates; `wind_angle` along the
//!   shorter arc, in [0, 360); the quaternion by normalised lerp with sign continuity, then
//!   put in the `w ≥ 0` hemisphere (as every data-set row is). Two updates of one signal
//!   more than `stale_after_s` apart are never interpolated across: the older is held and
//!   marked stale.
//! - **Any link rate.** Each signal's period is the median of its newest 16 intervals, as
//!   the link delivers them (0.5–50 Hz, with a radio's jitter). Its stale limit is 2.5 of its
//!   periods, never under `stale_after_s` and never over 5 s: position at 1 Hz with 0.25 s
//!   of jitter is stale after 2.5 s, not after 1.5 s. The whole-stream gap limit is the
//!   stale limit of the fastest signal still arriving, never under `max_gap_s`: a link whose
//!   fastest message comes at 1 Hz is silent for about a second between bursts as a matter
//!   of course, and that is no gap. On the data set (rows every 0.1–0.21 s) both limits are
//!   the configured ones. [`super::rates`] says what a slow or stopped signal means.
//! - **Gaps.** When the whole stream goes silent for more than that limit (the data set has
//!   ten gaps over 1 s, the longest 5.28 s, in flight 278), nothing is emitted inside the
//!   gap, the buffers are cleared and [`Resampler::take_restart`] tells the window builder
//!   to start a new ring: no window ever spans a gap. Sampling resumes at the first grid
//!   point at which every signal has an update at or before it.
//! - **Start.** Sampling starts at the first grid point every signal brackets; a signal
//!   still never seen `stale_after_s` after the first update is filled with a neutral value
//!   (0; identity quaternion; −9.81 m/s² for `linear_acceleration_z`) and marked stale.

use std::collections::VecDeque;

use crate::features::{idx, HomeVector, Sample, N_FEATURES};

/// The resampled signals; each maps onto a few features (or onto the measured power).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(usize)]
pub enum Signal {
    /// `[wind_speed m/s, wind_angle deg]`.
    Wind = 0,
    /// `[longitude deg, latitude deg, altitude m AMSL]`.
    Position,
    /// Data-set quaternion `[w, x, y, z]`.
    Attitude,
    /// `[forward, left, up]` m/s.
    Velocity,
    /// Body rates `[x, y, z]` rad/s (FRD).
    Rates,
    /// Specific force `[x, y, z]` m/s² (FRD).
    Accel,
    /// `[voltage V, current A, power W]`.
    Power,
}

/// Number of [`Signal`]s.
pub const N_SIGNALS: usize = 7;
/// Every signal, in index order.
pub const SIGNALS: [Signal; N_SIGNALS] = [
    Signal::Wind,
    Signal::Position,
    Signal::Attitude,
    Signal::Velocity,
    Signal::Rates,
    Signal::Accel,
    Signal::Power,
];

impl Signal {
    /// Human name (terminal health view).
    pub fn name(self) -> &'static str {
        [
            "wind",
            "position",
            "attitude",
            "velocity",
            "angular rate",
            "acceleration",
            "power",
        ][self as usize]
    }
    /// Number of values an update carries.
    pub fn dims(self) -> usize {
        [2, 3, 4, 3, 3, 3, 3][self as usize]
    }
    /// The features this signal fills, in value order (empty for power).
    pub fn features(self) -> &'static [usize] {
        use idx::*;
        match self {
            Signal::Wind => &[WIND_SPEED, WIND_ANGLE],
            Signal::Position => &[POS_X, POS_Y, POS_Z],
            Signal::Attitude => &[QW, QX, QY, QZ],
            Signal::Velocity => &[VX, VY, VZ],
            Signal::Rates => &[WX, WY, WZ],
            Signal::Accel => &[AX, AY, AZ],
            Signal::Power => &[],
        }
    }
    fn neutral(self) -> [f64; 4] {
        match self {
            Signal::Attitude => [1.0, 0.0, 0.0, 0.0],
            Signal::Accel => [0.0, 0.0, -9.81, 0.0],
            _ => [0.0; 4],
        }
    }
}

/// Intervals of one signal remembered for its period (the median of the newest ones).
const INTERVALS: usize = 16;
/// A signal's own stale limit is this many of its periods (the configured limit is the
/// floor): 2.5 periods hold a 1 Hz stream with ±0.5 s of radio jitter.
const STALE_PERIODS: f64 = 2.5;
/// The adaptive limits never exceed this, µs: a period over 2 s (under 0.5 Hz) is too slow
/// to carry a window, and its updates go stale between them.
const MAX_ADAPTIVE_US: i64 = 5_000_000;

#[derive(Debug, Default, Clone)]
struct Track {
    /// Updates not yet consumed; the front is at or before the next grid point once sampling runs.
    buf: VecDeque<(i64, [f64; 4])>,
    /// Last update ever (survives gap restarts, for holding).
    last: Option<(i64, [f64; 4])>,
    /// The newest intervals between updates, µs (survive gap restarts).
    intervals: VecDeque<i64>,
    /// Their median, µs: the signal's period as the link delivers it.
    period_us: Option<i64>,
}

impl Track {
    fn note_interval(&mut self, dt_us: i64) {
        if self.intervals.len() == INTERVALS {
            self.intervals.pop_front();
        }
        self.intervals.push_back(dt_us);
        let mut v: Vec<i64> = self.intervals.iter().copied().collect();
        v.sort_unstable();
        self.period_us = Some(v[v.len() / 2]);
    }

    /// This signal's stale limit: `STALE_PERIODS` of its period, at least `floor_us`.
    fn stale_limit_us(&self, floor_us: i64) -> i64 {
        match self.period_us {
            Some(p) => floor_us.max(((p as f64 * STALE_PERIODS) as i64).min(MAX_ADAPTIVE_US)),
            None => floor_us,
        }
    }
}

/// Fixed-rate resampler (see the module docs).
#[derive(Debug, Clone)]
pub struct Resampler {
    dt_us: i64,
    stale_us: i64,
    gap_us: i64,
    tracks: [Track; N_SIGNALS],
    /// Grid anchor (first update) and next grid index.
    t0_us: Option<i64>,
    next_k: i64,
    /// Newest update time seen.
    now_us: i64,
    /// Start of the current run of data (first update, or the first one after a gap):
    /// silence is counted from here, so nothing is quiet just because of the gap.
    epoch_us: i64,
    /// Home (latitude deg, longitude deg, altitude m) for [`Sample::home`].
    home: Option<[f64; 3]>,
    /// Mission features (speed, payload, altitude): held, never stale.
    mission: [f32; 3],
    restart: bool,
    restarts: u64,
}

impl Resampler {
    /// A resampler at `rate_hz`, marking a signal stale after `stale_after_s` of silence and
    /// restarting after a whole-stream gap over `max_gap_s`.
    pub fn new(rate_hz: f64, stale_after_s: f64, max_gap_s: f64) -> Self {
        Self {
            dt_us: ((1e6 / rate_hz).round() as i64).max(1),
            stale_us: (stale_after_s * 1e6).round() as i64,
            gap_us: (max_gap_s * 1e6).round() as i64,
            tracks: Default::default(),
            t0_us: None,
            next_k: 0,
            now_us: i64::MIN,
            epoch_us: i64::MIN,
            home: None,
            mission: [0.0; 3],
            restart: false,
            restarts: 0,
        }
    }

    /// Set the mission features (commanded speed m/s, payload g, altitude m).
    pub fn set_mission(&mut self, speed_m_s: f32, payload_g: f32, altitude_m: f32) {
        self.mission = [speed_m_s, payload_g, altitude_m];
    }

    /// One update of `sig` at `t_us` (µs on the source clock). Values must be finite (the
    /// caller filters). An update older than the newest one of its signal is dropped.
    pub fn update(&mut self, sig: Signal, t_us: i64, v: &[f64]) {
        if self.t0_us.is_none() {
            self.t0_us = Some(t_us);
            self.epoch_us = t_us;
        } else if t_us > self.now_us.saturating_add(self.gap_limit_us()) {
            self.restart_at(t_us);
        }
        self.now_us = self.now_us.max(t_us);
        let mut val = [0.0; 4];
        val[..v.len()].copy_from_slice(v);
        let tr = &mut self.tracks[sig as usize];
        if let Some((t_last, _)) = tr.last.filter(|l| t_us > l.0) {
            tr.note_interval(t_us - t_last);
        }
        match tr.buf.back_mut() {
            Some(b) if b.0 == t_us => b.1 = val,
            Some(b) if b.0 > t_us => return,
            _ => tr.buf.push_back((t_us, val)),
        }
        tr.last = Some((t_us, val));
    }

    fn restart_at(&mut self, t_us: i64) {
        for tr in &mut self.tracks {
            tr.buf.clear();
        }
        let t0 = self.t0_us.unwrap_or(t_us);
        self.next_k = (t_us - t0 + self.dt_us - 1).div_euclid(self.dt_us);
        self.epoch_us = t_us;
        self.restart = true;
        self.restarts += 1;
        tracing::debug!(
            t_s = t_us as f64 / 1e6,
            "telemetry gap: restarting the window ring"
        );
    }

    /// True once after each gap restart: the window builder must start a new ring.
    pub fn take_restart(&mut self) -> bool {
        std::mem::take(&mut self.restart)
    }

    /// Gap restarts so far.
    pub fn restarts(&self) -> u64 {
        self.restarts
    }

    /// Whether `sig` has been silent for more than its stale limit at the newest time seen.
    pub fn is_quiet(&self, sig: Signal) -> bool {
        let tr = &self.tracks[sig as usize];
        let last = tr.last.map_or(i64::MIN, |u| u.0);
        self.t0_us.is_some()
            && self.now_us - last.max(self.epoch_us) > tr.stale_limit_us(self.stale_us)
    }

    /// The period of `sig` as the link delivers it (the median of its newest intervals), s;
    /// `None` before its second update.
    pub fn period_s(&self, sig: Signal) -> Option<f64> {
        self.tracks[sig as usize].period_us.map(|p| p as f64 / 1e6)
    }

    /// Intervals of `sig` seen so far (at most the newest 16 are kept).
    pub fn intervals_seen(&self, sig: Signal) -> usize {
        self.tracks[sig as usize].intervals.len()
    }

    /// How long `sig` may be silent before it is stale, s: 2.5 of its own periods, never
    /// under `stale_after_s`, never over 5 s.
    pub fn stale_limit_s(&self, sig: Signal) -> f64 {
        self.tracks[sig as usize].stale_limit_us(self.stale_us) as f64 / 1e6
    }

    /// The whole-stream silence after which the ring restarts, µs: the stale limit of the
    /// fastest signal still arriving (a stream whose fastest message comes at 1 Hz is
    /// silent for a second between updates as a matter of course), never under `max_gap_s`.
    fn gap_limit_us(&self) -> i64 {
        SIGNALS
            .iter()
            .filter(|&&s| self.tracks[s as usize].period_us.is_some() && !self.is_quiet(s))
            .map(|&s| self.tracks[s as usize].stale_limit_us(0))
            .min()
            .map_or(self.gap_us, |l| l.max(self.gap_us))
    }

    /// The whole-stream gap limit as it stands, s: the fastest live signal's stale limit,
    /// never under `max_gap_s`.
    pub fn gap_limit_s(&self) -> f64 {
        self.gap_limit_us() as f64 / 1e6
    }

    /// Set home (latitude deg, longitude deg, altitude m AMSL): samples then carry the
    /// distance and height to it, computed from the f64 position (not the f32 features).
    pub fn set_home(&mut self, home: [f64; 3]) {
        self.home = Some(home);
    }

    /// Age of the newest update of `sig` at the newest time seen, seconds.
    pub fn age_s(&self, sig: Signal) -> Option<f64> {
        self.tracks[sig as usize]
            .last
            .map(|(t, _)| (self.now_us - t) as f64 / 1e6)
    }

    /// Emit every grid sample that is ready.
    pub fn poll(&mut self, out: &mut Vec<Sample>) {
        self.emit(out, false);
    }

    /// End of stream: emit what is left up to the newest update, holding (and, past the
    /// stale limit, stale-marking) signals that stopped earlier.
    pub fn finish(&mut self, out: &mut Vec<Sample>) {
        self.emit(out, true);
    }

    fn emit(&mut self, out: &mut Vec<Sample>, end: bool) {
        let Some(t0) = self.t0_us else { return };
        loop {
            let g = t0 + self.next_k * self.dt_us;
            if g > self.now_us {
                return;
            }
            let mut skip = false;
            for (i, tr) in self.tracks.iter().enumerate() {
                if self.is_quiet(SIGNALS[i]) {
                    continue;
                }
                match (tr.buf.front(), tr.buf.back()) {
                    (Some(f), _) if f.0 > g => skip = true,
                    (Some(_), Some(b)) if b.0 >= g || end => {}
                    (None, _) if end => {}
                    _ => return,
                }
            }
            self.next_k += 1;
            if !skip {
                out.push(self.sample_at(g));
            }
            for tr in &mut self.tracks {
                while tr.buf.len() >= 2 && tr.buf[1].0 <= g {
                    tr.buf.pop_front();
                }
            }
        }
    }

    fn sample_at(&self, g: i64) -> Sample {
        let mut features = [0f32; N_FEATURES];
        let mut stale_mask = 0u32;
        let mut power = None;
        let mut home = None;
        for sig in SIGNALS {
            let tr = &self.tracks[sig as usize];
            let (v, stale) = self.value_at(sig, tr, g);
            if sig == Signal::Power {
                power = tr.last.map(|_| (v, stale));
                continue;
            }
            if let (Signal::Position, Some(h), false, Some(_)) = (sig, self.home, stale, tr.last) {
                home = Some(HomeVector {
                    distance_m: super::frames::ground_distance_m(h[0], h[1], v[1], v[0]) as f32,
                    height_m: (v[2] - h[2]) as f32,
                });
            }
            for (k, &f) in sig.features().iter().enumerate() {
                features[f] = v[k] as f32;
                if stale {
                    stale_mask |= 1 << f;
                }
            }
        }
        features[idx::SPEED] = self.mission[0];
        features[idx::PAYLOAD] = self.mission[1];
        features[idx::ALTITUDE] = self.mission[2];
        let (measured_w, voltage_v) = match power {
            Some((v, false)) => (Some(v[2] as f32), Some(v[0] as f32)),
            _ => (None, None),
        };
        Sample {
            t_s: g as f64 / 1e6,
            features,
            measured_w,
            voltage_v,
            home,
            stale_mask,
            battery_remaining_pct: None,
            vehicle: Default::default(),
            air: Default::default(),
        }
    }

    /// Value of one signal at grid time `g`, and whether it is stale there.
    fn value_at(&self, sig: Signal, tr: &Track, g: i64) -> ([f64; 4], bool) {
        let prev = tr.buf.iter().rev().find(|u| u.0 <= g);
        let next = tr.buf.iter().find(|u| u.0 >= g);
        match (prev, next) {
            (Some(p), Some(n)) if n.0 == p.0 => (canonical(sig, p.1), false),
            (Some(p), Some(n)) if n.0 - p.0 <= tr.stale_limit_us(self.stale_us) => {
                let a = (g - p.0) as f64 / (n.0 - p.0) as f64;
                (lerp(sig, &p.1, &n.1, a), false)
            }
            // The bracket spans a silence longer than the stale limit: hold, never bridge.
            (Some(p), Some(_)) => (canonical(sig, p.1), true),
            // No newer update: the signal went quiet (or the stream ended).
            (Some(p), None) => (
                canonical(sig, p.1),
                self.is_quiet(sig) || g - p.0 > tr.stale_limit_us(self.stale_us),
            ),
            (None, Some(n)) => (canonical(sig, n.1), true),
            (None, None) => match tr.last {
                Some(l) => (canonical(sig, l.1), true),
                None => (sig.neutral(), true),
            },
        }
    }
}

/// Canonical form of a held value (quaternion normalised into `w ≥ 0`).
fn canonical(sig: Signal, v: [f64; 4]) -> [f64; 4] {
    if sig == Signal::Attitude {
        normalise_q(v)
    } else {
        v
    }
}

#[allow(clippy::neg_cmp_op_on_partial_ord)] // `!(n > 0)` also catches NaN, on purpose
fn normalise_q(q: [f64; 4]) -> [f64; 4] {
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    if !(n > 0.0) {
        return [1.0, 0.0, 0.0, 0.0];
    }
    let s = if q[0] < 0.0 { -1.0 / n } else { 1.0 / n };
    [q[0] * s, q[1] * s, q[2] * s, q[3] * s]
}

fn lerp(sig: Signal, p: &[f64; 4], n: &[f64; 4], a: f64) -> [f64; 4] {
    let mut r = [0.0; 4];
    match sig {
        Signal::Attitude => {
            let dot: f64 = (0..4).map(|i| p[i] * n[i]).sum();
            let s = if dot < 0.0 { -1.0 } else { 1.0 };
            for i in 0..4 {
                r[i] = p[i] + a * (s * n[i] - p[i]);
            }
            normalise_q(r)
        }
        Signal::Wind => {
            r[0] = p[0] + a * (n[0] - p[0]);
            let d = (n[1] - p[1] + 180.0).rem_euclid(360.0) - 180.0;
            let ang = (p[1] + a * d).rem_euclid(360.0);
            r[1] = if ang >= 360.0 { 0.0 } else { ang };
            r
        }
        _ => {
            for i in 0..sig.dims() {
                r[i] = p[i] + a * (n[i] - p[i]);
            }
            r
        }
    }
}
