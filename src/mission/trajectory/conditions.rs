//! What a plan is flown with: the vehicle's kinematics (`[forecast.kinematics]`), the wind
//! and the rest of the conditions.

use nalgebra::Vector3;

/// How the vehicle flies a mission (`[forecast.kinematics]`).
#[derive(Debug, Clone, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct KinematicsConfig {
    /// Motors running on the ground before lift-off (the spin-up from arming to leaving
    /// the ground), s: part of the take-off, flown at hover. Default 4.4 (the M100's).
    pub spinup_s: f64,
    /// Vertical climb rate on take-off and on climbing legs, m/s. Default 3.0.
    pub climb_m_s: f64,
    /// Vertical descent rate above `slow_below_m`, m/s. Default 2.7.
    pub descent_m_s: f64,
    /// Descent rate below `slow_below_m` (the landing), m/s. Default 1.0.
    pub land_m_s: f64,
    /// Height above home under which the descent slows to `land_m_s`, m. Default 20.
    pub slow_below_m: f64,
    /// Horizontal acceleration and deceleration, m/s². Default 2.5.
    pub accel_m_s2: f64,
    /// Pause at every stop (after take-off, at each waypoint, before landing), s. Default 1.9.
    pub waypoint_pause_s: f64,
    /// Cruise speed when neither the plan nor the command line gives one, m/s. Default 10.
    pub default_speed_m_s: f64,
    /// Thrust tilt per airspeed², 1/m: tan θ = c·|u|². Default 0.0016 (9° at 10 m/s).
    pub tilt_per_airspeed2: f64,
}

impl Default for KinematicsConfig {
    fn default() -> Self {
        Self {
            spinup_s: 4.4,
            climb_m_s: 3.0,
            descent_m_s: 2.7,
            land_m_s: 1.0,
            slow_below_m: 20.0,
            accel_m_s2: 2.5,
            waypoint_pause_s: 1.9,
            default_speed_m_s: 10.0,
            tilt_per_airspeed2: 0.0016,
        }
    }
}

impl KinematicsConfig {
    /// Range checks; the message names the key.
    pub fn validate(&self) -> Result<(), String> {
        use crate::validate::{above, in_range};
        let key = |k: &str| format!("forecast.kinematics.{k}");
        for (k, v, unit) in [
            ("climb_m_s", self.climb_m_s, "m/s"),
            ("descent_m_s", self.descent_m_s, "m/s"),
            ("land_m_s", self.land_m_s, "m/s"),
            ("accel_m_s2", self.accel_m_s2, "m/s²"),
            ("default_speed_m_s", self.default_speed_m_s, "m/s"),
        ] {
            in_range(&key(k), v, above(0.0), unit)?;
        }
        for (k, v, unit) in [
            ("spinup_s", self.spinup_s, "s"),
            ("slow_below_m", self.slow_below_m, "m"),
            ("waypoint_pause_s", self.waypoint_pause_s, "s"),
            ("tilt_per_airspeed2", self.tilt_per_airspeed2, ""),
        ] {
            in_range(&key(k), v, 0.0.., unit)?;
        }
        Ok(())
    }
}

/// Ambient wind: speed and the bearing it blows from (meteorological convention).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Wind {
    /// m/s.
    pub speed_m_s: f64,
    /// Bearing the wind comes from, deg clockwise from north.
    pub from_deg: f64,
}

impl Wind {
    /// The air's velocity over the ground, ENU m/s (it blows *toward* `from_deg + 180°`).
    pub fn velocity_enu(&self) -> Vector3<f64> {
        let b = self.from_deg.to_radians();
        Vector3::new(-self.speed_m_s * b.sin(), -self.speed_m_s * b.cos(), 0.0)
    }
}

impl std::str::FromStr for Wind {
    type Err = String;
    /// `SPEED@FROM_DEG`, e.g. `5@270` (5 m/s from the west).
    fn from_str(s: &str) -> Result<Self, String> {
        let (a, b) = s
            .split_once('@')
            .ok_or_else(|| format!("wind {s:?}: expected SPEED@FROM_DEG, e.g. 5@270"))?;
        let speed_m_s: f64 = a
            .trim()
            .parse()
            .map_err(|_| format!("wind {s:?}: speed {a:?} is not a number"))?;
        let from_deg: f64 = b
            .trim()
            .parse()
            .map_err(|_| format!("wind {s:?}: bearing {b:?} is not a number"))?;
        if !(speed_m_s.is_finite() && (0.0..=40.0).contains(&speed_m_s)) {
            return Err(format!("wind {s:?}: speed must be 0..40 m/s"));
        }
        if !from_deg.is_finite() {
            return Err(format!("wind {s:?}: bearing must be a number of degrees"));
        }
        Ok(Wind {
            speed_m_s,
            from_deg: from_deg.rem_euclid(360.0),
        })
    }
}

/// What the trajectory needs besides the plan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Conditions {
    /// Ambient wind.
    pub wind: Wind,
    /// Payload, g.
    pub payload_g: f64,
    /// Cruise speed until a DO_CHANGE_SPEED, m/s (overrides the plan's `hoverSpeed`).
    pub speed_m_s: Option<f64>,
    /// Sample rate, Hz (the models' rate).
    pub rate_hz: f64,
}
