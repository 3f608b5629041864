//! `[fixed_wing_flight]` of a vehicle profile: how a plane (and a VTOL) flies a mission,
//! for the mission forecast (`mission::trajectory::plane`). The power model's own figures
//! are [`super::Params`]; these are the autopilot's speeds and limits.
//!
//! Every default is the autopilot's own default parameter (ArduPlane 4.5 and PX4 1.14, as
//! their parameter references give them; remembered, not re-checked on a vehicle), so a
//! plane whose profile has no such table is flown as a stock autopilot would fly it.

use serde::{Deserialize, Serialize};

/// How the plane flies a plan.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Flight {
    /// Cruise airspeed, m/s (a DO_CHANGE_SPEED or `--speed` overrides it). Default 15:
    /// ArduPlane `AIRSPEED_CRUISE` (`TRIM_ARSPD_CM` 1500 before 4.5), PX4 `FW_AIRSPD_TRIM`.
    pub cruise_m_s: f64,
    /// Bank limit in turns, deg: turns are flown at it, radius R = V²/(g·tan φ). Default
    /// 45: ArduPlane `ROLL_LIMIT_DEG` (PX4's `FW_R_LIM` is 50).
    pub bank_limit_deg: f64,
    /// Climb rate on take-off and on climbing legs, m/s. Default 5: ArduPlane
    /// `TECS_CLMB_MAX`, PX4 `FW_T_CLMB_MAX`.
    pub climb_m_s: f64,
    /// Greatest sink rate on descending legs, m/s. Default 5: ArduPlane `TECS_SINK_MAX`,
    /// PX4 `FW_T_SINK_MAX`.
    pub sink_m_s: f64,
    /// Loiter radius when the item gives none, m. Default 60: ArduPlane `WP_LOITER_RAD`
    /// (PX4's `NAV_LOITER_RAD` is 80).
    pub loiter_radius_m: f64,
    /// Glide slope of a NAV_LAND approach, deg. Default 5: PX4 `FW_LND_ANG` (ArduPlane
    /// glides from the last waypoint's height, no single parameter).
    pub land_glide_deg: f64,
    /// Airspeed on the landing approach, m/s. Default none: the cruise airspeed (ArduPlane's
    /// `TECS_LAND_ARSPD` −1 flies the approach between cruise and the minimum).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub land_airspeed_m_s: Option<f64>,
    /// The landing is flown into the wind when there is one (over 1 m/s): over the landing
    /// point, out downwind to the start of the approach, back down the glide slope. Default
    /// true (what a pilot plans, and the simulated autopilot flies); false: the glide
    /// starts on the way in from the previous position.
    pub land_into_wind: bool,
    /// Level straight before the glide on an into-wind approach, m. Default 80.
    pub land_straight_m: f64,
    /// VTOL: climb rate of VTOL_TAKEOFF on the lift rotors, m/s. Default 2.5: ArduPlane
    /// `Q_WP_SPEED_UP` 250 cm/s (PX4 `MPC_Z_V_AUTO_UP` 3).
    pub vtol_climb_m_s: f64,
    /// VTOL: descent rate of VTOL_LAND above `vtol_land_final_m`, m/s. Default 1.5:
    /// ArduPlane `Q_WP_SPEED_DN` 150 cm/s (PX4 `MPC_Z_V_AUTO_DN` 1.5).
    pub vtol_descent_m_s: f64,
    /// VTOL: height of the last, slow part of the landing, m. Default 6: ArduPlane
    /// `Q_LAND_FINAL_ALT`.
    pub vtol_land_final_m: f64,
    /// VTOL: descent rate below `vtol_land_final_m`, m/s. Default 0.5: ArduPlane
    /// `Q_LAND_SPEED` 50 cm/s (PX4 `MPC_LAND_SPEED` 0.7).
    pub vtol_land_m_s: f64,
    /// VTOL: duration of the transition to forward flight, s. Default 5: PX4
    /// `VT_F_TRANS_DUR` (ArduPlane's `Q_TRANSITION_MS` 5000 ms). ASSUMPTION: a fixed time.
    pub transition_fw_s: f64,
    /// VTOL: duration of the back transition to hover, s. Default 4: PX4 `VT_B_TRANS_DUR`.
    /// ASSUMPTION: a fixed time.
    pub transition_mc_s: f64,
    /// VTOL: mean electrical power of a transition, W. Default none: the multirotor models
    /// on the transition's motion (level, accelerating to cruise on the lift rotors).
    /// ASSUMPTION either way: transitions are their own phase and no model is fitted to one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub transition_w: Option<f64>,
}

impl Default for Flight {
    fn default() -> Self {
        Self {
            cruise_m_s: 15.0,
            bank_limit_deg: 45.0,
            climb_m_s: 5.0,
            sink_m_s: 5.0,
            loiter_radius_m: 60.0,
            land_glide_deg: 5.0,
            land_airspeed_m_s: None,
            land_into_wind: true,
            land_straight_m: 80.0,
            vtol_climb_m_s: 2.5,
            vtol_descent_m_s: 1.5,
            vtol_land_final_m: 6.0,
            vtol_land_m_s: 0.5,
            transition_fw_s: 5.0,
            transition_mc_s: 4.0,
            transition_w: None,
        }
    }
}

/// Standard gravity, m/s².
use crate::features::units::G;

impl Flight {
    /// Range checks; each message names the key.
    pub fn validate(&self) -> Result<(), String> {
        let checks = [
            ("cruise_m_s", self.cruise_m_s, 3.0, 100.0),
            ("bank_limit_deg", self.bank_limit_deg, 5.0, 75.0),
            ("climb_m_s", self.climb_m_s, 0.1, 30.0),
            ("sink_m_s", self.sink_m_s, 0.1, 30.0),
            ("loiter_radius_m", self.loiter_radius_m, 1.0, 10_000.0),
            ("land_glide_deg", self.land_glide_deg, 0.5, 45.0),
            (
                "land_airspeed_m_s",
                self.land_airspeed_m_s.unwrap_or(self.cruise_m_s),
                3.0,
                100.0,
            ),
            ("land_straight_m", self.land_straight_m, 0.0, 10_000.0),
            ("vtol_climb_m_s", self.vtol_climb_m_s, 0.1, 20.0),
            ("vtol_descent_m_s", self.vtol_descent_m_s, 0.1, 20.0),
            ("vtol_land_final_m", self.vtol_land_final_m, 0.0, 1000.0),
            ("vtol_land_m_s", self.vtol_land_m_s, 0.05, 20.0),
            ("transition_fw_s", self.transition_fw_s, 0.0, 600.0),
            ("transition_mc_s", self.transition_mc_s, 0.0, 600.0),
            (
                "transition_w",
                self.transition_w.unwrap_or(0.0),
                0.0,
                100_000.0,
            ),
        ];
        super::check_ranges("fixed_wing_flight", &checks)
    }

    /// The radius of a turn at airspeed `v` m/s and the bank limit, m: V²/(g·tan φ_max).
    pub fn turn_radius_m(&self, v: f64) -> f64 {
        v * v / (G * self.bank_limit_deg.to_radians().tan())
    }
}

/// The bank angle of a steady level turn of radius `r` m at airspeed `v` m/s, rad:
/// tan φ = V²/(g·r).
pub fn bank_for_radius(v: f64, r: f64) -> f64 {
    (v * v / (G * r.max(1e-6))).atan()
}
