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

use anyhow::Context;
use nalgebra::{Rotation3, Vector3};
use rand::rngs::StdRng;
use rand::SeedableRng;

use super::guidance::{self, Phase};
use super::physics::{Airframe, Battery};
use super::{
    check_steps, mc_velocity_step, set_attitude, wrap_pi, Frame, Recorder, SimFlight, SimOptions,
    State, Weather, DISARMED_FRAC, DT,
};
use crate::features::units::G;
use crate::features::VtolState;
use crate::model::profile::PlaneSim;
pub use powertrain::{Pusher, PusherDraw, Wing};

mod powertrain;
mod steer;
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

/// Fly a plane or a quadplane (`opts.vehicle` has `[plane]`); see the module docs.
pub fn simulate(opts: &SimOptions) -> anyhow::Result<SimFlight> {
    let p = opts
        .vehicle
        .plane
        .as_ref()
        .context("the vehicle profile has no [plane] section: not a plane")?;
    let frame = Frame::of(&opts.vehicle);
    let quad = frame == Frame::Quadplane;
    let rotors = if quad {
        Some(Airframe::from_profile(&opts.vehicle)?)
    } else {
        None
    };
    let mut battery = Battery::from_profile(&opts.vehicle, opts.battery)?;
    let cells = battery.cells;
    let mut rng = StdRng::seed_from_u64(opts.seed);
    let mass = opts.vehicle.mass_kg(opts.payload_g / 1000.0);
    let wing = Wing::new(p, mass);
    let pusher = Pusher::new(p, cells);
    let rho = opts.vehicle.air.rho_kg_m3;
    let v_stall = wing.stall_mps(rho);
    let route = &opts.route;
    let last = route.waypoints.len() - 1;
    let min_turn_r = p.cruise_mps.powi(2) / (G * p.bank_limit_deg.to_radians().tan());
    let loiter_r = LOITER_M.max(1.5 * min_turn_r);
    // Where it lands, and the approach into the wind (else along the last leg).
    let land = Vector3::new(
        route.waypoints[last].north_m,
        route.waypoints[last].east_m,
        0.0,
    );
    let w = opts.wind_ned();
    let from = if last > 0 {
        route.waypoints[last - 1].ned()
    } else {
        Vector3::zeros()
    };
    let mut u = if w.norm() > 1.0 {
        -w / w.norm()
    } else {
        Vector3::new(land.x - from.x, land.y - from.y, 0.0)
    };
    u.z = 0.0;
    let u = if u.norm() > 1e-6 {
        u / u.norm()
    } else {
        Vector3::new(1.0, 0.0, 0.0)
    };
    let avionics_w = if let Some(r) = &rotors {
        r.avionics_w
    } else {
        p.avionics_w
    };
    let mut weather = Weather::new(opts);
    let mut st = State::at_home(DISARMED_FRAC * avionics_w, battery.ocv_v());
    st.airspeed_mps = Some(0.0);
    st.vtol = if quad {
        VtolState::Mc
    } else {
        VtolState::Undefined
    };
    let runway = course_to(&Vector3::zeros(), &route.waypoints[0].ned());
    st.yaw = runway;
    let mut fl = Flight {
        phi: 0.0,
        thrust_n: 0.0,
        on_ground: true,
        on_final: false,
        stage_s: 0.0,
    };
    let mut phase = Phase::PreArm;
    let mut phase_t = 0.0;
    let mut rec = Recorder::new(opts);
    let mut step: u64 = 0;
    let speed_of = |i: usize| route.waypoints[i].speed_mps.max(1.25 * v_stall);
    loop {
        st.wind = weather.wind(&mut rng);
        let gust = (st.wind - w).norm();
        let bus_v = st.voltage_v.max(1.0);
        let mut next: Option<Phase> = None;
        let mut rotor_w = 0.0;
        let mut pusher_w = 0.0;
        let mut throttle = 0.0;
        let mut att: Option<Rotation3<f64>> = None;
        let mc = quad && matches!(st.vtol, VtolState::Mc);
        // Ground phases.
        match phase {
            Phase::PreArm if phase_t >= guidance::PREARM_S => next = Some(Phase::Spinup),
            Phase::Spinup if phase_t >= guidance::SPINUP_S => next = Some(Phase::Climb),
            Phase::Landed if phase_t >= guidance::LANDED_S => next = Some(Phase::Done),
            Phase::Done if phase_t >= guidance::DONE_S => break,
            _ => {}
        }
        let in_air_phase = matches!(
            phase,
            Phase::Climb | Phase::Leg(_) | Phase::Hold(_) | Phase::Descent
        );
        if in_air_phase && mc {
            // On the lift rotors: climb over home, or come back over the landing point and land.
            let r = rotors.as_ref().context("a quadplane needs its rotors")?;
            let vd = if phase == Phase::Climb {
                let vd = guidance::toward(
                    &st.pos,
                    &Vector3::new(0.0, 0.0, -route.takeoff_alt_m),
                    route.waypoints[0].speed_mps.min(5.0),
                    route.climb_mps,
                );
                if (st.pos.z + route.takeoff_alt_m).abs() < 0.3 {
                    next = Some(Phase::Leg(0));
                    st.vtol = VtolState::TransitionToFw;
                    fl.stage_s = 0.0;
                    fl.thrust_n = 0.0;
                    fl.on_ground = false;
                }
                vd
            } else {
                let hd = Vector3::new(land.x - st.pos.x, land.y - st.pos.y, 0.0).norm();
                let height = -st.pos.z;
                let (rate, z) = if hd > 2.0 {
                    (0.0, st.pos.z)
                } else if height > guidance::FLARE_M {
                    (route.descent_mps, 0.0)
                } else {
                    (guidance::LAND_MPS, 1.0)
                };
                if height <= 0.02 {
                    st.pos.z = 0.0;
                    next = Some(Phase::Landed);
                }
                guidance::toward(
                    &st.pos,
                    &Vector3::new(land.x, land.y, z),
                    5.0,
                    rate.max(0.5),
                )
            };
            mc_velocity_step(&mut st, vd);
            let va = st.vel - st.wind;
            let pw = r.power(mass, va, st.acc);
            rotor_w = pw.electrical_w;
            att = Some(super::attitude_from_thrust(
                &r.thrust_ned(mass, va, st.acc),
                st.yaw,
            ));
            throttle = 0.5
                * (rotor_w
                    / r.power(mass, Vector3::zeros(), Vector3::zeros())
                        .electrical_w)
                    .sqrt();
            st.airspeed_mps = Some(va.norm());
        } else if in_air_phase
            && quad
            && matches!(
                st.vtol,
                VtolState::TransitionToFw | VtolState::TransitionToMc
            )
        {
            // Transitions: both sets of rotors; height held by the lift rotors.
            let r = rotors.as_ref().context("a quadplane needs its rotors")?;
            // The lift rotors hold the track: the ground velocity stays along `dir` (to the
            // leg's waypoint going forward, the way it was flying coming back).
            let to_fw = st.vtol == VtolState::TransitionToFw;
            let gvel = Vector3::new(st.vel.x, st.vel.y, 0.0);
            let dir = if to_fw {
                let i = match phase {
                    Phase::Leg(i) | Phase::Hold(i) => i,
                    _ => 0,
                };
                let d = route.waypoints[i].ned() - st.pos;
                Vector3::new(d.x, d.y, 0.0)
            } else {
                gvel
            };
            let dir = if dir.norm() > 0.5 {
                dir / dir.norm()
            } else {
                Vector3::new(st.yaw.cos(), st.yaw.sin(), 0.0)
            };
            let gs = gvel.dot(&dir).max(0.0);
            let va = dir * gs - st.wind;
            let v = va.norm();
            let chi = dir.y.atan2(dir.x);
            let q = 0.5 * rho * v * v * p.wing_area_m2;
            // Going back the lift rotors spin up at once and take at least 30 % of the
            // weight (ArduPlane spools them before it slows); the wing the rest it can.
            let rotor_min = if to_fw { 0.0 } else { 0.3 * mass * G };
            let lift = (q * 0.8 * p.cl_max).min(mass * G - rotor_min);
            let cl = wing.cl(lift, v, rho);
            let drag = wing.drag_n(v, cl, rho);
            fl.stage_s += DT;
            // The rotors' share of the weight falls to zero over the blend.
            let blend = if to_fw && v >= p.transition_mps {
                (1.0 - fl.stage_s / BLEND_S).clamp(0.0, 1.0)
            } else {
                if to_fw {
                    fl.stage_s = 0.0;
                }
                1.0
            };
            let (a_along, t_push, brake) = if to_fw {
                let t_max = pusher.max_thrust_n(v, bus_v, cells, rho);
                let t = (drag + mass * 2.0).min(t_max);
                ((t - drag) / mass, t, 0.0)
            } else {
                let brake = (mass * BACK_DECEL - drag).max(0.0);
                (-(drag + brake) / mass, 0.0, brake)
            };
            fl.thrust_n = t_push;
            let gs2 = (gs + a_along * DT).max(0.0);
            st.acc = (dir * gs2 - gvel) / DT;
            st.vel = dir * gs2;
            st.pos += st.vel * DT;
            // Rotor thrust: the weight the wing leaves, and the braking force.
            let carried = (mass * G - lift) * blend;
            let m_eff = (carried / G).max(0.0);
            if m_eff > 1e-3 {
                let a_rot = -dir * brake / m_eff;
                rotor_w = r.power(m_eff, va, a_rot).electrical_w - r.avionics_w;
            }
            let draw = pusher.draw(t_push, v, bus_v, rho);
            pusher_w = draw.electrical_w;
            throttle = draw.throttle;
            fl.phi = 0.0;
            st.yaw = chi;
            let alpha = cl / 5.0 - 0.03;
            att = Some(Rotation3::from_euler_angles(0.0, alpha, chi));
            st.airspeed_mps = Some(va.norm());
            if to_fw && v >= p.transition_mps && fl.stage_s >= BLEND_S {
                st.vtol = VtolState::Fw;
            }
            if !to_fw && gs2 < 1.0 {
                st.vtol = VtolState::Mc;
                st.acc = Vector3::zeros();
            }
            rotor_w += r.avionics_w;
        } else if in_air_phase {
            // Fixed-wing flight (and the plane's take-off and landing rolls).
            let h = -st.pos.z;
            let mut ask = Ask {
                course: runway,
                turn_ff: 0.0,
                height_m: route.takeoff_alt_m,
                airspeed_mps: speed_of(0),
                idle: false,
            };
            match phase {
                Phase::Climb => {
                    if h > 15.0 {
                        ask.course = course_to(&st.pos, &route.waypoints[0].ned());
                    }
                    if h >= route.takeoff_alt_m - 2.0 {
                        next = Some(Phase::Leg(0));
                    }
                }
                Phase::Leg(i) => {
                    let wp = route.waypoints[i].ned();
                    let prev = if i == 0 {
                        Vector3::zeros()
                    } else {
                        route.waypoints[i - 1].ned()
                    };
                    ask.course = course_to(&st.pos, &wp);
                    ask.height_m = route.waypoints[i].alt_m;
                    ask.airspeed_mps = speed_of(i);
                    let d = Vector3::new(wp.x - st.pos.x, wp.y - st.pos.y, 0.0);
                    let leg = Vector3::new(wp.x - prev.x, wp.y - prev.y, 0.0);
                    if d.norm() < ARRIVAL_M || (leg.norm() > 1.0 && d.dot(&leg) < 0.0) {
                        next = Some(if route.waypoints[i].hold_s > 0.0 {
                            Phase::Hold(i)
                        } else if i < last {
                            Phase::Leg(i + 1)
                        } else {
                            Phase::Descent
                        });
                        if next == Some(Phase::Descent) && quad {
                            st.vtol = VtolState::TransitionToMc;
                        }
                    }
                }
                Phase::Hold(i) => {
                    let c = route.waypoints[i].ned();
                    let vg = (st.vel.x * st.vel.x + st.vel.y * st.vel.y).sqrt();
                    (ask.course, ask.turn_ff) = loiter_course(&st.pos, &c, loiter_r, vg);
                    ask.height_m = route.waypoints[i].alt_m;
                    ask.airspeed_mps = speed_of(i);
                    if phase_t >= route.waypoints[i].hold_s {
                        next = Some(if i < last {
                            Phase::Leg(i + 1)
                        } else {
                            Phase::Descent
                        });
                        if next == Some(Phase::Descent) && quad {
                            st.vtol = VtolState::TransitionToMc;
                        }
                    }
                }
                Phase::Descent => {
                    // To the approach start, then down the glide path.
                    let h0 = route.waypoints[last].alt_m;
                    let start = land - u * (h0 / GLIDE.tan() + 80.0);
                    let along = (land - st.pos).dot(&u);
                    if !fl.on_final {
                        ask.course = course_to(&st.pos, &start);
                        ask.height_m = h0;
                        let d = Vector3::new(start.x - st.pos.x, start.y - st.pos.y, 0.0);
                        if d.norm() < 2.0 * ARRIVAL_M {
                            fl.on_final = true;
                        }
                    } else {
                        let rel = st.pos - land;
                        let xtrack = -rel.x * u.y + rel.y * u.x;
                        let chi_line = u.y.atan2(u.x);
                        ask.course = chi_line - (xtrack / 30.0).atan().clamp(-1.0, 1.0);
                        ask.height_m = (along * GLIDE.tan()).clamp(0.0, h0);
                        ask.airspeed_mps = 1.3 * v_stall;
                        ask.idle = h < 2.0;
                    }
                }
                _ => {}
            }
            if fl.on_ground {
                // Take-off or landing roll along the runway (the ground stops the sink).
                let va = st.vel - st.wind;
                let vdir = Vector3::new(st.yaw.cos(), st.yaw.sin(), 0.0);
                let v_air = va.dot(&vdir).max(0.0);
                let q = 0.5 * rho * v_air * v_air * p.wing_area_m2;
                let lift = q * 0.3;
                let drag = wing.drag_n(v_air, 0.3, rho);
                let gs = st.vel.dot(&vdir);
                let (t, decel) = if phase == Phase::Climb {
                    (
                        pusher.max_thrust_n(v_air, bus_v, cells, rho),
                        0.05 * (mass * G - lift).max(0.0),
                    )
                } else {
                    (0.0, mass * 2.0)
                };
                fl.thrust_n = t;
                let a = ((t - drag - decel) / mass).max(if gs > 0.0 { -50.0 } else { 0.0 });
                let gs2 = (gs + a * DT).max(0.0);
                st.acc = vdir * (gs2 - gs) / DT;
                st.vel = vdir * gs2;
                st.pos += st.vel * DT;
                st.pos.z = 0.0;
                let draw = pusher.draw(t, v_air, bus_v, rho);
                pusher_w = draw.electrical_w;
                throttle = draw.throttle;
                att = Some(Rotation3::from_euler_angles(0.0, 0.0, st.yaw));
                st.airspeed_mps = Some(v_air);
                if phase == Phase::Climb && v_air >= 1.25 * v_stall {
                    fl.on_ground = false;
                }
                if phase == Phase::Descent && gs2 <= 0.01 {
                    next = Some(Phase::Landed);
                }
            } else {
                let craft = Craft {
                    wing: &wing,
                    pusher: &pusher,
                    rho,
                    cells,
                };
                let (draw, aero) =
                    fw_step(&mut st, &mut fl, &craft, &ask, &weather.wind_est, bus_v);
                pusher_w = draw.electrical_w;
                throttle = draw.throttle;
                let va = st.vel - st.wind;
                let chi = va.y.atan2(va.x);
                let gamma = (-va.z / aero.v).clamp(-1.0, 1.0).asin();
                st.yaw = chi;
                att = Some(Rotation3::from_euler_angles(
                    fl.phi,
                    gamma + aero.alpha,
                    chi,
                ));
                st.airspeed_mps = Some(va.norm());
                if phase == Phase::Descent && st.pos.z >= 0.0 {
                    st.pos.z = 0.0;
                    st.vel.z = 0.0;
                    fl.on_ground = true;
                }
            }
        }
        if let Some(nx) = next {
            phase = nx;
            phase_t = 0.0;
        }
        phase_t += DT;
        st.armed = phase.armed();
        st.in_air = in_air_phase
            && if quad {
                st.pos.z < -0.05 || st.vtol != VtolState::Mc
            } else {
                !fl.on_ground
            };
        if !in_air_phase {
            st.vel = Vector3::zeros();
            st.acc = Vector3::zeros();
        }
        let rot = att.unwrap_or_else(|| Rotation3::from_euler_angles(0.0, 0.0, st.yaw));
        set_attitude(&mut st, rot);
        // The truth power: the motors' draw, avionics, servos.
        let servo = p.servo_w * (1.0 + 0.3 * st.rates.x.abs() + 0.5 * gust);
        let ground_w = match phase {
            Phase::PreArm | Phase::Done => DISARMED_FRAC * avionics_w,
            Phase::Spinup | Phase::Landed => match &rotors {
                Some(r) => r.idle_w,
                None => avionics_w + p.servo_w,
            },
            _ => 0.0,
        };
        let power = if ground_w > 0.0 {
            ground_w
        } else if quad && rotor_w > 0.0 {
            rotor_w + pusher_w + servo
        } else {
            pusher_w + avionics_w + servo
        };
        st.power_w = power;
        st.throttle = (100.0 * throttle).clamp(0.0, 100.0);
        (st.voltage_v, st.current_a) = battery.step(power, DT);
        rec.record(step, phase, &st, &battery, &mut weather, &mut rng);
        step += 1;
        check_steps(step, opts)?;
    }
    Ok(rec.finish())
}

#[cfg(test)]
mod tests;
