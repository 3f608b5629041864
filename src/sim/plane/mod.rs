//! A simulated plane, and a quadplane: fixed-wing flight and the truth power it draws.
//!
//! ## Flight model (point mass, coordinated turns)
//! The state is the inertial velocity; the aerodynamics see the air-relative velocity
//! `v_a = v − w` (wind with gusts, so a gust changes the airspeed at once and the airspeed
//! loop answers it). With airspeed V, course through the air χ, flight-path angle γ and
//! bank φ:
//! - `V̇ = (T − D)/m − g·sin γ`, `χ̇ = g·tan φ / V` (a coordinated turn: the steady turn
//!   radius is V²/(g·tan φ)), `γ̇ = (g/V)(n·cos φ − cos γ)`, the load factor n the one the
//!   climb command asks, capped by C_L,max;
//! - lateral guidance: the ground course to the target (or round the loiter circle, or down
//!   the approach line), corrected for the autopilot's wind estimate, becomes a turn rate,
//!   then a bank (at most `[plane] bank_limit_deg`) that the roll follows with τ = 0.5 s and
//!   60°/s at most;
//! - TECS-like height and speed: the climb rate asked is 0.25/s × the height error, within
//!   +3 / −3 m/s and a 15° path (a pitch limit); the thrust holds the airspeed
//!   (`T = D + m·g·sin γ + m·0.5·(V_cmd − V)`, lagged τ = 1.5 s: TECS moves the throttle
//!   smoothly and does not chase each gust) up to the propeller's thrust at that
//!   speed, and the climb gives way when the airspeed sags below 1.15 × stall (a power limit);
//! - take-off: a ground roll at full throttle (rolling friction 0.05) toward the first
//!   waypoint, rotation at 1.25 × stall, the climb straight ahead to 15 m, then toward the
//!   first waypoint until the take-off altitude; loiter: a circle of
//!   max(60 m, 1.5 × the minimum turn radius) round a waypoint with a hold time (ArduPlane's
//!   `WP_LOITER_RAD` is 60 m); landing: to an approach point upwind of the last waypoint,
//!   down a 6° glide path at 1.3 × stall, a flare with the motor off below 2 m, a roll to a
//!   stop braking at 2 m/s².
//!
//! ## The quadplane
//! VTOL take-off on the lift rotors (the multirotor simulator's velocity loop,
//! `vtol_state` MC); the forward transition (TRANSITION_TO_FW: the pusher accelerating at up
//! to 2 m/s² while the rotors carry what the wing cannot yet, until `[plane]
//! transition_mps` and then a 3 s blend); forward flight as a plane (FW); at the last
//! waypoint the back transition (TRANSITION_TO_MC: pusher off, braking at 2 m/s², the lift
//! rotors spun up at once to carry at least 30 % of the weight and the rest as the wing slows); then MC: back over the landing point and
//! a vertical landing (QLAND) as the multirotor's descent.
//!
//! ## Truth power (not the fixed-wing model's formula)
//! - Drag polar `C_D = C_D0·(V_ref/V)^0.2 + C_L²/(π·e·AR) + 0.1·max(0, C_L − 0.75·C_L,max)²`
//!   (skin friction falling with Reynolds number, induced drag, the rise near stall).
//! - Propeller: momentum theory `P_ideal = T·(V + v_i)`, `v_i = (−V + √(V² + 2T/(ρA)))/2`
//!   (valid static and in flight), over a blade efficiency that falls away from its best
//!   advance ratio, `η_b = η_max·(1 − 0.3·((J/J_0 − 0.65)/0.65)²)`; the revolutions from
//!   a thrust coefficient falling linearly to zero at `J_0 = 1.1·pitch/D`.
//! - Motor: `I = Q·K_v + I_0`, `P_in = V_emf·I + I²·R` (copper and iron losses), then the
//!   ESC's efficiency; the motor stops when no thrust is asked (a glide).
//! - Avionics plus servos, the servos working harder with roll rate and gusts
//!   (`P_servo = servo_w·(1 + 0.3·|p| + 0.5·|gust|)`).
//! - Quadplane rotors: the multirotor truth of [`super::physics::Airframe::power`] for the
//!   share of the weight the wing does not carry, and the braking force.

use std::f64::consts::PI;

use super::{wrap_pi, State, DT};
use crate::features::units::G;
use crate::model::profile::PlaneSim;
pub use powertrain::{Pusher, PusherDraw, Wing};

mod fly;
mod powertrain;
mod steer;
pub use fly::simulate;
pub use steer::loiter_course;
use steer::{course_to, fw_step};

/// Bank-angle time constant, s, and roll-rate limit, rad/s.
const TAU_PHI: f64 = 0.5;
const ROLL_RATE_MAX: f64 = 60.0 * PI / 180.0;
/// Thrust lag, s: TECS moves the throttle smoothly (ArduPlane's `TECS_TIME_CONST` is 5 s
/// and its airspeed is filtered), it does not chase each gust.
const TAU_T: f64 = 1.5;
/// Climb and sink limits, m/s, and the path-angle (pitch) limit, rad.
const CLIMB_MAX: f64 = 3.0;
const SINK_MAX: f64 = 3.0;
const GAMMA_MAX: f64 = 15.0 * PI / 180.0;
/// Glide-path angle of the approach, rad.
const GLIDE: f64 = 6.0 * PI / 180.0;
/// ArduPlane's WP_LOITER_RAD default, m.
const LOITER_M: f64 = 60.0;
/// A leg's waypoint counts as reached within this, or once passed abeam, m.
const ARRIVAL_M: f64 = 25.0;
/// The forward transition's blend after the transition airspeed, s.
const BLEND_S: f64 = 3.0;
/// Deceleration of the back transition, m/s² (ArduPlane `Q_TRANS_DECEL` 2).
const BACK_DECEL: f64 = 2.0;

/// The plane's own dynamic state besides [`State`].
#[derive(Debug, Clone, Copy)]
pub struct Flight {
    /// Bank, rad.
    pub phi: f64,
    /// Thrust of the pusher, N.
    pub thrust_n: f64,
    /// On the ground (take-off roll, landing roll).
    pub on_ground: bool,
    /// Landing: on the final approach line (else flying to its start).
    pub on_final: bool,
    /// Seconds in the current VTOL stage (the blend).
    pub stage_s: f64,
}

/// The aerodynamic result of one fixed-wing step: airspeed (m/s), drag (N), angle of
/// attack (rad), all at the start of the step.
struct Aero {
    v: f64,
    #[cfg_attr(not(test), allow(dead_code))] // the energy-balance test reads it
    drag_n: f64,
    alpha: f64,
}

/// What the lateral and vertical guidance ask in one step.
#[derive(Debug, Clone, Copy)]
pub struct Ask {
    /// Ground course, rad.
    pub course: f64,
    /// Feed-forward turn rate (loiter), rad/s.
    pub turn_ff: f64,
    /// Height above home, m.
    pub height_m: f64,
    /// Airspeed, m/s.
    pub airspeed_mps: f64,
    /// Motor off (flare, glide).
    pub idle: bool,
}

/// The plane's wing and pusher in the air it flies, on a pack of `cells`.
pub struct Craft<'a> {
    pub wing: &'a Wing,
    pub pusher: &'a Pusher,
    /// Air density, kg/m³.
    pub rho: f64,
    pub cells: f64,
}

#[cfg(test)]
mod tests;
