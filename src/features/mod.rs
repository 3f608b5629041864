//! The floor every stage stands on: the fixed-rate [`Sample`] the telemetry stage builds
//! and every later stage reads, the paper's 21 feature names in model order, their indices
//! ([`idx`]), the home vector, and the frame and unit conversions between MAVLink and the
//! M100 data set's columns ([`frames`]), the float ↔ integer scaling every reader and
//! sink shares ([`units`]), and what kind of vehicle a sample is from ([`class`]). It
//! imports nothing of ours, so any stage may use it without tying itself to another.

pub mod class;
pub mod frames;
pub mod units;

pub use class::{Lift, VehicleClass, VehicleKind, VtolState};

/// Number of model input features (the paper's 21).
pub const N_FEATURES: usize = 21;

/// The paper's 21 features, in the order every model, card and file uses. Units and frames
/// are the M100 data set's (see `../shared/data/m100/SOURCE.md`), whatever the autopilot
/// sends: the telemetry stage converts at its boundary.
pub const FEATURE_NAMES: [&str; N_FEATURES] = [
    "wind_speed",    // m/s, anemometer airspeed (includes own motion)
    "wind_angle",    // deg, relative to north
    "position_x",    // deg longitude
    "position_y",    // deg latitude
    "position_z",    // m above sea level
    "orientation_x", // quaternion: body (x right, y forward, z up) → ENU, w ≥ 0
    "orientation_y",
    "orientation_z",
    "orientation_w",
    "velocity_x", // m/s ground velocity, heading frame: right
    "velocity_y", // m/s forward
    "velocity_z", // m/s up
    "angular_x",  // rad/s body rates, FRD
    "angular_y",
    "angular_z",
    "linear_acceleration_x", // m/s², specific force, FRD body (z ≈ −9.81 at rest)
    "linear_acceleration_y",
    "linear_acceleration_z",
    "speed",    // m/s commanded cruise ground speed (mission)
    "payload",  // g (mission)
    "altitude", // m commanded cruise altitude (mission)
];

/// The names of the features a stale mask marks (bit i: feature i), in feature order.
pub fn stale_names(mask: u32) -> Vec<&'static str> {
    FEATURE_NAMES
        .iter()
        .enumerate()
        .filter(|(i, _)| mask & (1 << i) != 0)
        .map(|(_, n)| *n)
        .collect()
}

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
    /// The 21 features, data-set units and frames, order of [`FEATURE_NAMES`] (frames as
    /// verified on the data set: see [`frames`]).
    pub features: [f32; N_FEATURES],
    /// Measured electrical power V × I, watts, when voltage and current are present
    /// (interpolated like the features; `None` while the battery source is stale).
    pub measured_w: Option<f32>,
    /// Battery voltage, volts, when present (`None` while stale).
    pub voltage_v: Option<f32>,
    /// Distance to home (horizontal, m) and height above home (m), when a home is known
    /// (HOME_POSITION, else the first GPS fix) and the position is not stale.
    pub home: Option<HomeVector>,
    /// Bit i set: feature i is stale (its source went quiet; the value is held).
    pub stale_mask: u32,
    /// The autopilot's own state of charge, %, when it reports one (BATTERY_STATUS or
    /// SYS_STATUS `battery_remaining`; −1 there means unknown and gives `None`). The latest
    /// value, not interpolated.
    pub battery_remaining_pct: Option<f32>,
    /// The vehicle's class and, for a VTOL, its flight state at this sample (the latest
    /// HEARTBEAT / EXTENDED_SYS_STATE, or the config): what picks the models that apply.
    pub vehicle: VehicleKind,
    /// Air data a fixed-wing model reads beside the features (latest values, not
    /// interpolated; each `None` while its source is stale).
    pub air: AirData,
}

impl Sample {
    /// A sample with these features and this measured power and nothing else known: no
    /// voltage, home or state of charge, nothing stale, the default vehicle class and no air
    /// data. What tests and tools build one from; set the rest with `..Sample::new(…)`.
    pub fn new(t_s: f64, features: [f32; N_FEATURES], measured_w: Option<f32>) -> Self {
        Self {
            t_s,
            features,
            measured_w,
            voltage_v: None,
            home: None,
            stale_mask: 0,
            battery_remaining_pct: None,
            vehicle: VehicleKind::default(),
            air: AirData::default(),
        }
    }
}

/// What the autopilot says about the air the vehicle flies through.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AirData {
    /// VFR_HUD `airspeed`, m/s: the autopilot's airspeed (from its sensor where
    /// [`AirData::airspeed_sensor`], else its own estimate).
    pub airspeed_m_s: Option<f32>,
    /// SYS_STATUS says a differential-pressure (airspeed) sensor is present, enabled and
    /// healthy: the VFR_HUD airspeed is measured.
    pub airspeed_sensor: bool,
    /// Horizontal ground velocity minus the WIND estimate, m/s (the airspeed without a
    /// sensor), while WIND is live.
    pub wind_airspeed_m_s: Option<f32>,
    /// Air temperature, °C, where the vehicle sends one (SCALED_PRESSURE `temperature`,
    /// taken only within −60…60 °C).
    pub temperature_c: Option<f32>,
    /// VFR_HUD `throttle`, % (0–100): what the first hover compares with ArduPilot's
    /// `MOT_THST_HOVER`.
    pub throttle_pct: Option<f32>,
}

/// Where home is from the vehicle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HomeVector {
    /// Horizontal distance to home, m.
    pub distance_m: f32,
    /// Height above home, m (positive when above).
    pub height_m: f32,
}
