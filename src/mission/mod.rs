//! Mission energy forecast: will the planned mission, and the way home, finish above
//! reserve?
//!
//! - [`crate::sim::guidance`]: a list of waypoints (take-off, legs at their own speeds, holds,
//!   landing) turned into the velocity a multirotor's position controller would command,
//!   step by step: what the simulator flies;
//! - [`plan`]: the plan model (home, items, speeds, altitude frames) and its readers,
//!   QGroundControl `.plan` and `QGC WPL 110` `.waypoints`;
//! - [`trajectory`]: the plan flown on paper (climb, stop-to-stop legs, turns, holds,
//!   descent, landing) into the 21 features the power models read, with wind and payload;
//!   a plane and a VTOL as they fly ([`trajectory::plane`]: airspeed cruise, turns at the
//!   bank limit, loiter circles, the glide or the VTOL landing, transitions);
//! - [`forecast`]: every power model along the trajectory, energy per leg, P50 and P90,
//!   and the live re-forecast of what is left from the current item and position;
//! - [`protocol`]: the MAVLink mission protocol's client as a pure state machine
//!   (download with timeouts and resends, re-download on a changed mission, overheard
//!   items of a replayed log);
//! - [`live`]: the task that runs it on the link and re-forecasts the rest of the mission
//!   as the vehicle flies it (the one part of this module that does I/O: it sends the
//!   protocol's frames on the link).
//!
//! Pure apart from reading plan files and [`live`]'s frames: this module imports the models and the telemetry's
//! sample types, never energy, alerts, sinks or the pipeline. The `plan` and `plan-eval`
//! commands live in [`crate::offline::plan`] and the lab's `plan-eval` (`lab/src/plan_eval.rs`).

pub mod forecast;
pub mod live;
pub mod plan;
pub mod protocol;
pub mod trajectory;

/// The `[forecast]` table: how plans are flown on paper and how the forecast is corrected.
#[derive(Debug, Clone, Default, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ForecastConfig {
    /// `[forecast.kinematics]`: climb, descent, acceleration, stops.
    pub kinematics: trajectory::KinematicsConfig,
    /// `[forecast.calibration]`: forecast model, its correction, P90 ratio, live weight.
    pub calibration: forecast::Calibration,
    /// `[forecast.live]`: the live mission forecast.
    pub live: LiveForecastConfig,
}

/// The `[forecast.live]` table.
#[derive(Debug, Clone, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct LiveForecastConfig {
    /// Forecast the rest of the mission while `monitor` or `replay` runs: download the
    /// mission over a live link (MAVLink mission protocol), take it from a replayed
    /// `.tlog`'s logged items. Default true.
    pub enabled: bool,
    /// A calibrated vehicle profile (`dronewatt-lab calibrate`'s output, e.g.
    /// `vehicles/m100-calibrated.toml`; relative to the config file) whose `<model>_cal`
    /// physics models run beside the vehicle's own, so that the calibration's `model`
    /// gives the P50. Default: for the M100, its calibrated profile compiled into dronewatt
    /// (`config/vehicles/m100-calibrated.toml` as built); for another vehicle none, and then
    /// its first physics model gives the P50, uncorrected (a warning says so).
    pub calibrated_profile: Option<std::path::PathBuf>,
}

impl Default for LiveForecastConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            calibrated_profile: None,
        }
    }
}

impl ForecastConfig {
    /// Range checks; messages name the key.
    pub fn validate(&self) -> Result<(), String> {
        self.kinematics.validate()?;
        self.calibration.validate()
    }
}

/// Models run on every `MODEL_STRIDE`-th trajectory sample (at 10 Hz: 2 Hz), power held in
/// between: the legs are minutes of steady motion, and a 500-waypoint plan must forecast
/// in milliseconds.
pub const MODEL_STRIDE: usize = 5;
