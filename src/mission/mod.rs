//! Mission energy forecast: will the planned mission, and the way home, finish above
//! reserve?
//!
//! - [`guidance`]: a list of waypoints (take-off, legs at their own speeds, holds,
//!   landing) turned into the velocity a multirotor's position controller would command,
//!   step by step: what the simulator flies;
//! - [`plan`]: the plan model (home, items, speeds, altitude frames) and its readers,
//!   QGroundControl `.plan` and `QGC WPL 110` `.waypoints`;
//! - [`trajectory`]: the plan flown on paper (climb, stop-to-stop legs, turns, holds,
//!   descent, landing) into the 21 features the power models read, with wind and payload;
//! - [`forecast`]: every power model along the trajectory, energy per leg, P50 and P90,
//!   and the live re-forecast of what is left from the current item and position.
//!
//! Pure apart from reading plan files: this module imports the models and the telemetry's
//! sample types, never energy, alerts, sinks or the pipeline. The `plan` and `plan-eval`
//! commands live in [`crate::offline::mission`].

pub mod forecast;
pub mod guidance;
pub mod plan;
pub mod trajectory;

/// The `[forecast]` table: how plans are flown on paper and how the forecast is corrected.
#[derive(Debug, Clone, Default, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ForecastConfig {
    /// `[forecast.kinematics]`: climb, descent, acceleration, stops.
    pub kinematics: trajectory::KinematicsConfig,
    /// `[forecast.calibration]`: forecast model, its correction, P90 ratio, live weight.
    pub calibration: forecast::Calibration,
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
