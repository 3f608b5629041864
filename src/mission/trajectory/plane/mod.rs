//! Fly a plan on paper as a plane (and a VTOL) flies it, into the same samples and legs as
//! a multirotor's ([`super::fly`]), for the same forecast.
//!
//! ## The flight (profile `[fixed_wing_flight]`, [`Flight`])
//!
//! - **Cruise** at the airspeed V (`cruise_m_s`; a DO_CHANGE_SPEED or `--speed` sets it).
//!   On a straight leg the plane crabs into the wind to hold the track: ground speed
//!   `g = w·d + √(V_h² − (w×d)²)` along the track d, with V_h = √(V² − v_z²). A plane
//!   cannot hover: no hold at waypoints (ArduPlane ignores a waypoint's hold time too), no
//!   stop, no acceleration.
//! - **Height** changes on a leg at `v_z = Δh / t`, within `climb_m_s` and `sink_m_s`
//!   (TECS's limits); what a leg cannot climb is carried to the next.
//! - **Turns** at every waypoint, at the bank limit φ_max (`bank_limit_deg`): radius
//!   R = V²/(g·tan φ_max), from the heading it arrives on to the tangent that leads to the
//!   next position (the turn is flown over the waypoint, so a sharp turn adds distance),
//!   lasting Δψ·R/V, drifting with the wind. Power there has the load factor 1/cos φ (the
//!   fixed-wing model reads the bank from the attitude).
//! - **Loiters** (NAV_LOITER_TIME, NAV_LOITER_TURNS): the plane joins a circle of the item's
//!   radius (param 3; else `loiter_radius_m`; never tighter than R) round the position,
//!   clockwise, held over the ground: one turn lasts `∮ r dθ / g(θ)` with the ground speed
//!   g along the circle in the wind (2πr/V in calm air), at the bank tan φ = V²/(g·r).
//!   LOITER_TURNS flies its turns, LOITER_TIME its time; LOITER_UNLIM is flown through (no
//!   forecast can hold "for ever").
//! - **Take-off** (NAV_TAKEOFF): a climb at `climb_m_s` and airspeed V toward the next
//!   position, to the item's altitude (no ground run or launch: a few seconds).
//! - **Landing** (NAV_LAND, RETURN_TO_LAUNCH): into the wind where there is one
//!   (`land_into_wind`: over the landing point, out downwind to `land_straight_m` before
//!   the glide's start, back), else straight in from the previous position; then the glide
//!   of `land_glide_deg` at `land_airspeed_m_s` to the ground at the landing point (or
//!   home), the fixed-wing model's power with the climb term negative: little more than
//!   the avionics. No flare, no roll-out.
//!   ArduPlane's RTL loiters at home unless RTL_AUTOLAND: the forecast lands there.
//! - **VTOL** (class `vtol`): VTOL_TAKEOFF climbs vertically on the lift rotors
//!   (`vtol_climb_m_s`, the multirotor models on the vehicle's own mass and rotors), then a
//!   **transition** of `transition_fw_s` (level, accelerating to V on the rotors) before
//!   the first leg; VTOL_LAND (and RTL) flies there as a plane, a **back transition** of
//!   `transition_mc_s` (decelerating from V), then descends on the rotors
//!   (`vtol_descent_m_s`, the last `vtol_land_final_m` at `vtol_land_m_s`). Transitions
//!   are flown on the multirotor models, or at `transition_w` W where the profile gives it
//!   (an ASSUMPTION either way). DO_VTOL_TRANSITION to MC flies a back transition; the next
//!   positioned item transitions to forward flight again (legs are never flown on rotors).
//!
//! ## Samples
//!
//! Wing-borne samples carry the attitude (bank, flight-path pitch, the heading of the air
//! velocity), the ground velocity, the climb rate, the airspeed as a healthy sensor's
//! (`AirData`), the anemometer features as the multirotor's, and the vehicle kind
//! (`fixed_wing`, or `vtol` in `fw`), so that the forecast runs the fixed-wing model on
//! them. Rotor-borne ones (a VTOL's climb, descent and transitions) are the multirotor's
//! samples with the kind `vtol` in `mc` or in transition, for the rotor models.
//!
//! Pure: no I/O.

use nalgebra::{Vector2, Vector3};

use super::{
    enu_of, mission_sample, sampled, Conditions, KinematicsConfig, Leg, RotorFeatures, Trajectory,
};
use crate::features::{frames, idx, AirData, Sample, VehicleClass, VehicleKind, VtolState};
use crate::mission::plan::{ItemKind, Plan};
use crate::model::physics::fixed_wing::{bank_for_radius, Flight};

/// Standard gravity, m/s².
use crate::features::units::G;
/// The least ground speed a leg is flown at, m/s (a wind stronger than the airspeed).
const MIN_GROUND_M_S: f64 = 1.0;

type V2 = Vector2<f64>;
type V3 = Vector3<f64>;

/// A piece of the flight, closed form in its local time.
#[derive(Debug, Clone, Copy)]
enum Piece {
    /// Wing-borne and straight: ground velocity `vel` (ENU, v_z included) from `from`, at
    /// airspeed `airspeed` with the nose (air velocity) at ENU bearing `heading`.
    Straight {
        from: V3,
        vel: V3,
        airspeed: f64,
        heading: f64,
    },
    /// Wing-borne turn, a circle in the air mass: centre `c` at the start, radius `r`, from
    /// heading `psi0`, side `s` (+1 left, −1 right), drifting with the wind `drift`.
    Turn {
        c: V2,
        r: f64,
        psi0: f64,
        s: f64,
        airspeed: f64,
        drift: V2,
        z: f64,
    },
    /// Wing-borne circle held over the ground round `c`: position angle `a0 + s·rate·t`.
    Loiter {
        c: V2,
        r: f64,
        a0: f64,
        s: f64,
        rate: f64,
        z: f64,
        airspeed: f64,
    },
    /// Rotor-borne, vertical from `from` to height `z1`.
    Vertical { from: V3, z1: f64, heading: f64 },
    /// Rotor-borne transition: level along `heading` from `from`, speed from `v0` to `v1`.
    Transition {
        from: V3,
        heading: f64,
        v0: f64,
        v1: f64,
        to_fw: bool,
    },
}

#[derive(Debug, Clone, Copy)]
struct Seg {
    piece: Piece,
    duration_s: f64,
    leg: usize,
}

/// Where the vehicle is and how it flies at one instant.
enum At {
    Wing {
        p: V3,
        v: V3,
        airspeed: f64,
        heading: f64,
        bank: f64,
        yaw_rate: f64,
    },
    Rotor {
        p: V3,
        v: V3,
        a: V3,
        heading: f64,
        state: VtolState,
    },
}

fn unit(heading: f64) -> V2 {
    V2::new(heading.cos(), heading.sin())
}

/// Horizontal ground speed along the unit track `d` at horizontal airspeed `v_h` in the
/// wind `w`: `w·d + √(v_h² − (w×d)²)`, at least [`MIN_GROUND_M_S`].
fn ground_speed(d: V2, v_h: f64, w: V2) -> f64 {
    let cross = w.x * d.y - w.y * d.x;
    let along = w.dot(&d);
    (along + (v_h * v_h - cross * cross).max(0.0).sqrt()).max(MIN_GROUND_M_S)
}

/// The time of one turn round a circle of radius `r` held over the ground at airspeed `v`
/// in the wind `w`, s: ∮ r dθ / g(θ) (2πr/V in calm air).
pub fn loiter_turn_s(r: f64, v: f64, w: V2) -> f64 {
    const STEPS: usize = 360;
    let dth = std::f64::consts::TAU / STEPS as f64;
    (0..STEPS)
        .map(|i| {
            let th = (i as f64 + 0.5) * dth;
            r * dth / ground_speed(V2::new(-th.sin(), th.cos()), v, w)
        })
        .sum()
}

fn state(seg: &Seg, t: f64, flight: &Flight, w: V2) -> At {
    match seg.piece {
        Piece::Straight {
            from,
            vel,
            airspeed,
            heading,
        } => At::Wing {
            p: from + vel * t,
            v: vel,
            airspeed,
            heading,
            bank: 0.0,
            yaw_rate: 0.0,
        },
        Piece::Turn {
            c,
            r,
            psi0,
            s,
            airspeed,
            drift,
            z,
        } => {
            let rate = s * airspeed / r;
            let psi = psi0 + rate * t;
            let p = c + s * r * V2::new(psi.sin(), -psi.cos()) + drift * t;
            let v = airspeed * unit(psi) + drift;
            At::Wing {
                p: V3::new(p.x, p.y, z),
                v: V3::new(v.x, v.y, 0.0),
                airspeed,
                heading: psi,
                bank: s * flight.bank_limit_deg.to_radians(),
                yaw_rate: rate,
            }
        }
        Piece::Loiter {
            c,
            r,
            a0,
            s,
            rate,
            z,
            airspeed,
        } => {
            let a = a0 + s * rate * t;
            let p = c + r * unit(a);
            // along the circle over the ground; the nose into the wind's crab
            let track = s * r * rate * V2::new(-a.sin(), a.cos());
            let air = track - w;
            At::Wing {
                p: V3::new(p.x, p.y, z),
                v: V3::new(track.x, track.y, 0.0),
                airspeed,
                heading: air.y.atan2(air.x),
                bank: s * bank_for_radius(airspeed, r),
                yaw_rate: s * rate,
            }
        }
        Piece::Vertical { from, z1, heading } => {
            let vz = (z1 - from.z) / seg.duration_s.max(1e-9);
            At::Rotor {
                p: V3::new(from.x, from.y, from.z + vz * t),
                v: V3::new(0.0, 0.0, vz),
                a: V3::zeros(),
                heading,
                state: VtolState::Mc,
            }
        }
        Piece::Transition {
            from,
            heading,
            v0,
            v1,
            to_fw,
        } => {
            let d = unit(heading);
            let acc = (v1 - v0) / seg.duration_s.max(1e-9);
            let sp = v0 + acc * t;
            let s = v0 * t + 0.5 * acc * t * t;
            At::Rotor {
                p: V3::new(from.x + d.x * s, from.y + d.y * s, from.z),
                v: V3::new(d.x * sp, d.y * sp, 0.0),
                a: V3::new(d.x * acc, d.y * acc, 0.0),
                heading,
                state: if to_fw {
                    VtolState::TransitionToFw
                } else {
                    VtolState::TransitionToMc
                },
            }
        }
    }
}

/// A wing-borne sample.
#[allow(clippy::too_many_arguments)]
fn wing_sample(
    plan: &Plan,
    c: &Conditions,
    cmd_alt: f64,
    t: f64,
    (p, v): (V3, V3),
    (airspeed, heading, bank, yaw_rate): (f64, f64, f64, f64),
    wind: V2,
    kind: VehicleKind,
    speed: f64,
) -> Sample {
    let yaw_ned = std::f64::consts::FRAC_PI_2 - heading;
    let pitch = (v.z / airspeed.max(1e-6)).clamp(-1.0, 1.0).asin();
    // ENU left turn (s > 0) is a roll to the left: negative in FRD
    let q = frames::ned_to_ds(frames::quat_from_euler(-bank, pitch, yaw_ned));
    let vb = frames::ned_to_body_vel([v.y, v.x, -v.z], yaw_ned);
    let air = v.xy() - wind;
    let mut f = [0.0f32; crate::features::N_FEATURES];
    f[idx::QW] = q[0] as f32;
    f[idx::QX] = q[1] as f32;
    f[idx::QY] = q[2] as f32;
    f[idx::QZ] = q[3] as f32;
    f[idx::VX] = vb[0] as f32;
    f[idx::VY] = vb[1] as f32;
    f[idx::VZ] = vb[2] as f32;
    f[idx::WZ] = -yaw_rate as f32;
    f[idx::AZ] = -(G / bank.cos().max(0.1)) as f32;
    f[idx::WIND_SPEED] = airspeed as f32;
    f[idx::WIND_ANGLE] = air.x.atan2(air.y).to_degrees().rem_euclid(360.0) as f32;
    f[idx::SPEED] = speed as f32;
    let mut s = mission_sample(plan, c, cmd_alt, t, p, f);
    s.air = AirData {
        airspeed_m_s: Some(airspeed as f32),
        airspeed_sensor: true,
        wind_airspeed_m_s: Some(air.norm() as f32),
        temperature_c: None,
        throttle_pct: None,
    };
    s.vehicle = kind;
    s
}

/// Fly `plan` on paper as a plane (`vtol`: a VTOL). Never fails: a plan with no motion
/// gives no samples.
pub fn fly_plane(
    plan: &Plan,
    k: &KinematicsConfig,
    flight: &Flight,
    vtol: bool,
    c: &Conditions,
) -> Trajectory {
    let speed0 = c
        .speed_m_s
        .or(plan.cruise_speed_m_s)
        .unwrap_or(flight.cruise_m_s);
    let (segs, legs) = segments(plan, flight, vtol, c, speed0);
    let w = c.wind.velocity_enu();
    let wind = V2::new(w.x, w.y);
    let dt = 1.0 / c.rate_hz;
    let class = if vtol {
        VehicleClass::Vtol
    } else {
        VehicleClass::FixedWing
    };
    let kind = |state| VehicleKind {
        class,
        mav_type: None,
        vtol_state: if vtol { state } else { VtolState::Undefined },
        from_config: true,
    };
    let mut rotor = RotorFeatures::new(plan, k, c);
    let cmd_alt = rotor.cmd_alt;
    let mut given_w: Vec<(std::ops::Range<usize>, f64)> = Vec::new();
    let durations: Vec<f64> = segs.iter().map(|s| s.duration_s).collect();
    let mut tr = sampled(&durations, dt, legs, |j, t, i, local_t| {
        let seg = &segs[i];
        match state(seg, local_t, flight, wind) {
            At::Wing {
                p,
                v,
                airspeed,
                heading,
                bank,
                yaw_rate,
            } => (
                wing_sample(
                    plan,
                    c,
                    cmd_alt,
                    t,
                    (p, v),
                    (airspeed, heading, bank, yaw_rate),
                    wind,
                    kind(VtolState::Fw),
                    airspeed,
                ),
                p,
                seg.leg,
            ),
            At::Rotor {
                p,
                v,
                a,
                heading,
                state,
            } => {
                let mut s = rotor.sample(t, p, v, a, heading, 0.0, v.xy().norm());
                s.vehicle = kind(state);
                // a VTOL has its airspeed sensor on the rotors too
                let air = (v.xy() - wind).norm() as f32;
                s.air = AirData {
                    airspeed_m_s: Some(air),
                    airspeed_sensor: true,
                    wind_airspeed_m_s: Some(air),
                    temperature_c: None,
                    throttle_pct: None,
                };
                if let (Piece::Transition { .. }, Some(w)) = (seg.piece, flight.transition_w) {
                    match given_w.last_mut() {
                        Some((r, _)) if r.end == j => r.end = j + 1,
                        _ => given_w.push((j..j + 1, w)),
                    }
                }
                (s, p, seg.leg)
            }
        }
    });
    tr.given_w = given_w;
    tr
}

mod route;
use route::segments;
#[cfg(test)]
mod tests;
