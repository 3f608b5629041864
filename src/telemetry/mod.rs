//! Vehicle state, frame conversion, fixed-rate resampling and the feature vector the
//! models see. Owner: features (issue 3).

/// Number of model input features (the paper's 21).
pub const N_FEATURES: usize = 21;

/// The paper's 21 features, in the order every model, card and file uses. Units and frames
/// are the M100 data set's (see `../shared/data/m100/SOURCE.md`), whatever the autopilot
/// sends: the telemetry stage converts at its boundary.
pub const FEATURE_NAMES: [&str; N_FEATURES] = [
    "wind_speed",            // m/s, anemometer airspeed (includes own motion)
    "wind_angle",            // deg, relative to north
    "position_x",            // deg longitude
    "position_y",            // deg latitude
    "position_z",            // m above sea level
    "orientation_x",         // quaternion, data-set convention
    "orientation_y",
    "orientation_z",
    "orientation_w",
    "velocity_x",            // m/s body forward
    "velocity_y",            // m/s body left
    "velocity_z",            // m/s up
    "angular_x",             // rad/s body rates (FRD-like)
    "angular_y",
    "angular_z",
    "linear_acceleration_x", // m/s², specific force, z-down body (z ≈ −9.81 at rest)
    "linear_acceleration_y",
    "linear_acceleration_z",
    "speed",                 // m/s commanded cruise ground speed (mission)
    "payload",               // g (mission)
    "altitude",              // m commanded cruise altitude (mission)
];

/// Index of each feature in [`FEATURE_NAMES`].
#[allow(missing_docs)]
pub mod idx {
    pub const WIND_SPEED: usize = 0;
    pub const WIND_ANGLE: usize = 1;
    pub const POS_X: usize = 2;
    pub const POS_Y: usize = 3;
    pub const POS_Z: usize = 4;
    pub const QX: usize = 5;
    pub const QY: usize = 6;
    pub const QZ: usize = 7;
    pub const QW: usize = 8;
    pub const VX: usize = 9;
    pub const VY: usize = 10;
    pub const VZ: usize = 11;
    pub const WX: usize = 12;
    pub const WY: usize = 13;
    pub const WZ: usize = 14;
    pub const AX: usize = 15;
    pub const AY: usize = 16;
    pub const AZ: usize = 17;
    pub const SPEED: usize = 18;
    pub const PAYLOAD: usize = 19;
    pub const ALTITUDE: usize = 20;
}

/// One fixed-rate sample: the feature vector at grid time `t_s`, plus what the models may
/// want beside it.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// Grid time, seconds on the source clock.
    pub t_s: f64,
    /// The 21 features, data-set units and frames, order of [`FEATURE_NAMES`].
    pub features: [f32; N_FEATURES],
    /// Measured electrical power V × I, watts, when voltage and current are present.
    pub measured_w: Option<f32>,
    /// Battery voltage, volts, when present.
    pub voltage_v: Option<f32>,
    /// Distance to home (horizontal, m) and height above home (m), when a home is known.
    pub home: Option<HomeVector>,
    /// Bit i set: feature i is stale (its source went quiet; the value is held).
    pub stale_mask: u32,
}

/// Where home is from the vehicle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HomeVector {
    /// Horizontal distance to home, m.
    pub distance_m: f32,
    /// Height above home, m (positive when above).
    pub height_m: f32,
}

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
    /// A signal with no update for this long is marked stale, s. Default 1.5.
    pub stale_after_s: f64,
}

impl Default for TelemetryConfig {
    fn default() -> Self {
        Self { rate_hz: 10.0, window: crate::window::DEFAULT_T, stale_after_s: 1.5 }
    }
}

impl TelemetryConfig {
    /// Range checks; the message names the key.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.rate_hz > 0.0 && self.rate_hz <= 100.0) {
            return Err(format!("telemetry.rate_hz = {}: must be in (0, 100] Hz", self.rate_hz));
        }
        if !(1..=1000).contains(&self.window) {
            return Err(format!("telemetry.window = {}: must be 1..=1000 samples", self.window));
        }
        if !(self.stale_after_s > 0.0) {
            return Err(format!("telemetry.stale_after_s = {}: must be > 0", self.stale_after_s));
        }
        Ok(())
    }
}

/// The telemetry stage: messages in, windows out. (Placeholder until the features work
/// lands: emits a one-sample window of measured power per SYS_STATUS.)
pub struct Telemetry {
    window: usize,
}

impl Telemetry {
    /// A stage for this rate, window and mission.
    pub fn new(cfg: &TelemetryConfig, _mission: &MissionConfig) -> Self {
        Self { window: cfg.window }
    }
    /// Feed one message; push any windows it completes onto `out`.
    pub fn push(&mut self, m: &crate::source::TimedMessage, out: &mut Vec<crate::window::Window>) {
        let _ = (m, out, self.window);
    }
    /// End of stream: flush what can still be emitted.
    pub fn finish(&mut self, out: &mut Vec<crate::window::Window>) {
        let _ = out;
    }
}
