//! The `[telemetry]` table (resampling and windowing) and the `[mission]` table (the
//! mission facts the telemetry cannot tell), with the checks that name each key.

/// Mission facts the telemetry cannot tell: the data set records them per flight.
#[derive(Debug, Clone, Default, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct MissionConfig {
    /// Commanded cruise ground speed, m/s. Default: 10.
    pub speed_m_s: Option<f32>,
    /// Payload carried, g. Default: 0.
    pub payload_g: Option<f32>,
    /// Commanded cruise altitude above home, m. Default: 25.
    pub altitude_m: Option<f32>,
}

/// Resampling and windowing.
#[derive(Debug, Clone, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct TelemetryConfig {
    /// Fixed sample rate the models see, Hz. Default 10 (the shipped model's rate).
    pub rate_hz: f64,
    /// Window length T, samples. Default 10 (the paper's).
    pub window: usize,
    /// A signal with no update for this long is marked stale, s. Default 1.5. The floor:
    /// each signal's own limit is 2.5 of its observed periods when that is longer (a 1 Hz
    /// link's position is stale after 2.5 s), at most 5 s ([`super::resample`]).
    pub stale_after_s: f64,
    /// When the whole stream is silent for longer than this, s, nothing is interpolated
    /// across the silence: the window ring restarts after it. Default 1.0 (the data set's
    /// rows come every 0.1–0.21 s; it has ten gaps over 1 s, the longest 5.28 s). The
    /// floor: the limit is the fastest live signal's own stale limit when that is longer,
    /// so a link whose fastest message comes at 1 Hz is not a gap every second.
    pub max_gap_s: f64,
}

impl Default for TelemetryConfig {
    fn default() -> Self {
        Self {
            rate_hz: 10.0,
            window: crate::telemetry::window::DEFAULT_T,
            stale_after_s: 1.5,
            max_gap_s: 1.0,
        }
    }
}

impl TelemetryConfig {
    /// Range checks; each message names the key (several errors: one per line).
    pub fn validate(&self) -> Result<(), String> {
        use crate::validate::{above, above_to};
        let mut errs = crate::validate::Errors::new();
        errs.range(
            "telemetry.rate_hz",
            self.rate_hz,
            above_to(0.0, 100.0),
            "Hz",
        );
        errs.range("telemetry.window", self.window, 1..=1000, "samples");
        errs.range(
            "telemetry.stale_after_s",
            self.stale_after_s,
            above(0.0),
            "s",
        );
        if !(self.max_gap_s > 1.0 / self.rate_hz && self.max_gap_s.is_finite()) {
            errs.push(format!(
                "telemetry.max_gap_s = {}: must be longer than one sample period (1/rate_hz)",
                self.max_gap_s
            ));
        }
        errs.into_result()
    }
}
