//! A plane's or a quadplane's flight, step by step: what stays fixed over the flight
//! ([`Setup`]), then each step by what the vehicle is doing: on its lift rotors, in a
//! transition, on its wing in the air, or rolling on the runway; then the truth power.

use anyhow::Context;
use nalgebra::{Rotation3, Vector3};
use rand::rngs::StdRng;
use rand::SeedableRng;

use super::*;
use crate::features::units::G;
use crate::features::VtolState;
use crate::model::profile::PlaneSim;
use crate::sim::guidance::{self, Phase, Route};
use crate::sim::physics::{Airframe, Battery};
use crate::sim::{
    attitude_from_thrust, check_steps, mc_velocity_step, set_attitude, Frame, Recorder, SimFlight,
    SimOptions, State, Weather, DISARMED_FRAC, DT,
};

/// What stays fixed over one flight: the airframe, the route, and where and how it lands.
struct Setup<'a> {
    p: &'a PlaneSim,
    quad: bool,
    /// The lift rotors of a quadplane.
    rotors: Option<Airframe>,
    mass: f64,
    wing: Wing,
    pusher: Pusher,
    rho: f64,
    cells: f64,
    v_stall: f64,
    route: &'a Route,
    /// The last waypoint's index.
    last: usize,
    loiter_r: f64,
    /// Where it lands, and the approach's direction (into the wind, else along the last leg).
    land: Vector3<f64>,
    u: Vector3<f64>,
    /// The take-off course.
    runway: f64,
    avionics_w: f64,
}

impl<'a> Setup<'a> {
    fn new(opts: &'a SimOptions, cells: f64) -> anyhow::Result<Self> {
        let p = opts
            .vehicle
            .plane
            .as_ref()
            .context("the vehicle profile has no [plane] section: not a plane")?;
        let quad = Frame::of(&opts.vehicle) == Frame::Quadplane;
        let rotors = if quad {
            Some(Airframe::from_profile(&opts.vehicle)?)
        } else {
            None
        };
        let mass = opts.vehicle.mass_kg(opts.payload_g / 1000.0);
        let wing = Wing::new(p, mass);
        let pusher = Pusher::new(p, cells);
        let rho = opts.vehicle.air.rho_kg_m3;
        let v_stall = wing.stall_mps(rho);
        let route = &opts.route;
        let last = route.waypoints.len() - 1;
        let min_turn_r = p.cruise_mps.powi(2) / (G * p.bank_limit_deg.to_radians().tan());
        let loiter_r = LOITER_M.max(1.5 * min_turn_r);
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
        let runway = course_to(&Vector3::zeros(), &route.waypoints[0].ned());
        Ok(Self {
            p,
            quad,
            rotors,
            mass,
            wing,
            pusher,
            rho,
            cells,
            v_stall,
            route,
            last,
            loiter_r,
            land,
            u,
            runway,
            avionics_w,
        })
    }

    fn speed_of(&self, i: usize) -> f64 {
        self.route.waypoints[i].speed_mps.max(1.25 * self.v_stall)
    }
}

/// What one step leaves: the next phase, the draws, the throttle (0–1) and the attitude.
#[derive(Default)]
struct StepOut {
    next: Option<Phase>,
    rotor_w: f64,
    pusher_w: f64,
    throttle: f64,
    att: Option<Rotation3<f64>>,
}

/// Fly a plane or a quadplane (`opts.vehicle` has `[plane]`); see the module docs.
pub fn simulate(opts: &SimOptions) -> anyhow::Result<SimFlight> {
    let mut battery = Battery::from_profile(&opts.vehicle, opts.battery)?;
    let s = Setup::new(opts, battery.cells)?;
    let mut rng = StdRng::seed_from_u64(opts.seed);
    let w = opts.wind_ned();
    let mut weather = Weather::new(opts);
    let mut st = State::at_home(DISARMED_FRAC * s.avionics_w, battery.ocv_v());
    st.airspeed_mps = Some(0.0);
    st.vtol = if s.quad {
        VtolState::Mc
    } else {
        VtolState::Undefined
    };
    st.yaw = s.runway;
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
    loop {
        st.wind = weather.wind(&mut rng);
        let gust = (st.wind - w).norm();
        let bus_v = st.voltage_v.max(1.0);
        let mut out = StepOut::default();
        let mc = s.quad && matches!(st.vtol, VtolState::Mc);
        // Ground phases.
        match phase {
            Phase::PreArm if phase_t >= guidance::PREARM_S => out.next = Some(Phase::Spinup),
            Phase::Spinup if phase_t >= guidance::SPINUP_S => out.next = Some(Phase::Climb),
            Phase::Landed if phase_t >= guidance::LANDED_S => out.next = Some(Phase::Done),
            Phase::Done if phase_t >= guidance::DONE_S => break,
            _ => {}
        }
        let in_air_phase = matches!(
            phase,
            Phase::Climb | Phase::Leg(_) | Phase::Hold(_) | Phase::Descent
        );
        let transition = matches!(
            st.vtol,
            VtolState::TransitionToFw | VtolState::TransitionToMc
        );
        if in_air_phase && mc {
            on_rotors(&s, &mut st, &mut fl, phase, &mut out)?;
        } else if in_air_phase && s.quad && transition {
            in_transition(&s, &mut st, &mut fl, phase, bus_v, &mut out)?;
        } else if in_air_phase {
            let ask = wing_ask(&s, &mut st, &mut fl, phase, phase_t, &mut out);
            if fl.on_ground {
                ground_roll(&s, &mut st, &mut fl, phase, bus_v, &mut out);
            } else {
                on_wing(
                    &s,
                    &mut st,
                    &mut fl,
                    phase,
                    &ask,
                    &weather.wind_est,
                    bus_v,
                    &mut out,
                );
            }
        }
        if let Some(nx) = out.next {
            phase = nx;
            phase_t = 0.0;
        }
        phase_t += DT;
        st.armed = phase.armed();
        st.in_air = in_air_phase
            && if s.quad {
                st.pos.z < -0.05 || st.vtol != VtolState::Mc
            } else {
                !fl.on_ground
            };
        if !in_air_phase {
            st.vel = Vector3::zeros();
            st.acc = Vector3::zeros();
        }
        let rot = out
            .att
            .unwrap_or_else(|| Rotation3::from_euler_angles(0.0, 0.0, st.yaw));
        set_attitude(&mut st, rot);
        let power = truth_power(&s, &st, phase, &out, gust);
        st.power_w = power;
        st.throttle = (100.0 * out.throttle).clamp(0.0, 100.0);
        (st.voltage_v, st.current_a) = battery.step(power, DT);
        rec.record(step, phase, &st, &battery, &mut weather, &mut rng);
        step += 1;
        check_steps(step, opts)?;
    }
    Ok(rec.finish())
}

/// The truth power: the motors' draw, avionics, servos (the servos working harder with
/// roll rate and gusts); on the ground, the disarmed share or the idle draw.
fn truth_power(s: &Setup, st: &State, phase: Phase, out: &StepOut, gust: f64) -> f64 {
    let servo = s.p.servo_w * (1.0 + 0.3 * st.rates.x.abs() + 0.5 * gust);
    let ground_w = match phase {
        Phase::PreArm | Phase::Done => DISARMED_FRAC * s.avionics_w,
        Phase::Spinup | Phase::Landed => match &s.rotors {
            Some(r) => r.idle_w,
            None => s.avionics_w + s.p.servo_w,
        },
        _ => 0.0,
    };
    if ground_w > 0.0 {
        ground_w
    } else if s.quad && out.rotor_w > 0.0 {
        out.rotor_w + out.pusher_w + servo
    } else {
        out.pusher_w + s.avionics_w + servo
    }
}

/// On the lift rotors (a quadplane): climb over home, or come back over the landing point
/// and land.
fn on_rotors(
    s: &Setup,
    st: &mut State,
    fl: &mut Flight,
    phase: Phase,
    out: &mut StepOut,
) -> anyhow::Result<()> {
    // On the lift rotors: climb over home, or come back over the landing point and land.
    let r = s.rotors.as_ref().context("a quadplane needs its rotors")?;
    let vd = if phase == Phase::Climb {
        let vd = guidance::toward(
            &st.pos,
            &Vector3::new(0.0, 0.0, -s.route.takeoff_alt_m),
            s.route.waypoints[0].speed_mps.min(5.0),
            s.route.climb_mps,
        );
        if (st.pos.z + s.route.takeoff_alt_m).abs() < 0.3 {
            out.next = Some(Phase::Leg(0));
            st.vtol = VtolState::TransitionToFw;
            fl.stage_s = 0.0;
            fl.thrust_n = 0.0;
            fl.on_ground = false;
        }
        vd
    } else {
        let hd = Vector3::new(s.land.x - st.pos.x, s.land.y - st.pos.y, 0.0).norm();
        let height = -st.pos.z;
        let (rate, z) = if hd > 2.0 {
            (0.0, st.pos.z)
        } else if height > guidance::FLARE_M {
            (s.route.descent_mps, 0.0)
        } else {
            (guidance::LAND_MPS, 1.0)
        };
        if height <= 0.02 {
            st.pos.z = 0.0;
            out.next = Some(Phase::Landed);
        }
        guidance::toward(
            &st.pos,
            &Vector3::new(s.land.x, s.land.y, z),
            5.0,
            rate.max(0.5),
        )
    };
    mc_velocity_step(st, vd);
    let va = st.vel - st.wind;
    let pw = r.power(s.mass, va, st.acc);
    out.rotor_w = pw.electrical_w;
    out.att = Some(attitude_from_thrust(
        &r.thrust_ned(s.mass, va, st.acc),
        st.yaw,
    ));
    out.throttle = 0.5
        * (out.rotor_w
            / r.power(s.mass, Vector3::zeros(), Vector3::zeros())
                .electrical_w)
            .sqrt();
    st.airspeed_mps = Some(va.norm());
    Ok(())
}

/// A quadplane's transition, either way: both sets of rotors, the height held by the lift
/// rotors, the wing carrying what it can.
fn in_transition(
    s: &Setup,
    st: &mut State,
    fl: &mut Flight,
    phase: Phase,
    bus_v: f64,
    out: &mut StepOut,
) -> anyhow::Result<()> {
    // Transitions: both sets of rotors; height held by the lift rotors.
    let r = s.rotors.as_ref().context("a quadplane needs its rotors")?;
    // The lift rotors hold the track: the ground velocity stays along `dir` (to the
    // leg's waypoint going forward, the way it was flying coming back).
    let to_fw = st.vtol == VtolState::TransitionToFw;
    let gvel = Vector3::new(st.vel.x, st.vel.y, 0.0);
    let dir = if to_fw {
        let i = match phase {
            Phase::Leg(i) | Phase::Hold(i) => i,
            _ => 0,
        };
        let d = s.route.waypoints[i].ned() - st.pos;
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
    let q = 0.5 * s.rho * v * v * s.p.wing_area_m2;
    // Going back the lift rotors spin up at once and take at least 30 % of the
    // weight (ArduPlane spools them before it slows); the wing the rest it can.
    let rotor_min = if to_fw { 0.0 } else { 0.3 * s.mass * G };
    let lift = (q * 0.8 * s.p.cl_max).min(s.mass * G - rotor_min);
    let cl = s.wing.cl(lift, v, s.rho);
    let drag = s.wing.drag_n(v, cl, s.rho);
    fl.stage_s += DT;
    // The rotors' share of the weight falls to zero over the blend.
    let blend = if to_fw && v >= s.p.transition_mps {
        (1.0 - fl.stage_s / BLEND_S).clamp(0.0, 1.0)
    } else {
        if to_fw {
            fl.stage_s = 0.0;
        }
        1.0
    };
    let (a_along, t_push, brake) = if to_fw {
        let t_max = s.pusher.max_thrust_n(v, bus_v, s.cells, s.rho);
        let t = (drag + s.mass * 2.0).min(t_max);
        ((t - drag) / s.mass, t, 0.0)
    } else {
        let brake = (s.mass * BACK_DECEL - drag).max(0.0);
        (-(drag + brake) / s.mass, 0.0, brake)
    };
    fl.thrust_n = t_push;
    let gs2 = (gs + a_along * DT).max(0.0);
    st.acc = (dir * gs2 - gvel) / DT;
    st.vel = dir * gs2;
    st.pos += st.vel * DT;
    // Rotor thrust: the weight the wing leaves, and the braking force.
    let carried = (s.mass * G - lift) * blend;
    let m_eff = (carried / G).max(0.0);
    if m_eff > 1e-3 {
        let a_rot = -dir * brake / m_eff;
        out.rotor_w = r.power(m_eff, va, a_rot).electrical_w - r.avionics_w;
    }
    let draw = s.pusher.draw(t_push, v, bus_v, s.rho);
    out.pusher_w = draw.electrical_w;
    out.throttle = draw.throttle;
    fl.phi = 0.0;
    st.yaw = chi;
    let alpha = cl / 5.0 - 0.03;
    out.att = Some(Rotation3::from_euler_angles(0.0, alpha, chi));
    st.airspeed_mps = Some(va.norm());
    if to_fw && v >= s.p.transition_mps && fl.stage_s >= BLEND_S {
        st.vtol = VtolState::Fw;
    }
    if !to_fw && gs2 < 1.0 {
        st.vtol = VtolState::Mc;
        st.acc = Vector3::zeros();
    }
    out.rotor_w += r.avionics_w;
    Ok(())
}

/// On the wing: what the autopilot asks in this phase (course, height, airspeed), and the
/// next phase when this one is done.
fn wing_ask(
    s: &Setup,
    st: &mut State,
    fl: &mut Flight,
    phase: Phase,
    phase_t: f64,
    out: &mut StepOut,
) -> Ask {
    let h = -st.pos.z;
    let mut ask = Ask {
        course: s.runway,
        turn_ff: 0.0,
        height_m: s.route.takeoff_alt_m,
        airspeed_mps: s.speed_of(0),
        idle: false,
    };
    match phase {
        Phase::Climb => {
            if h > 15.0 {
                ask.course = course_to(&st.pos, &s.route.waypoints[0].ned());
            }
            if h >= s.route.takeoff_alt_m - 2.0 {
                out.next = Some(Phase::Leg(0));
            }
        }
        Phase::Leg(i) => {
            let wp = s.route.waypoints[i].ned();
            let prev = if i == 0 {
                Vector3::zeros()
            } else {
                s.route.waypoints[i - 1].ned()
            };
            ask.course = course_to(&st.pos, &wp);
            ask.height_m = s.route.waypoints[i].alt_m;
            ask.airspeed_mps = s.speed_of(i);
            let d = Vector3::new(wp.x - st.pos.x, wp.y - st.pos.y, 0.0);
            let leg = Vector3::new(wp.x - prev.x, wp.y - prev.y, 0.0);
            if d.norm() < ARRIVAL_M || (leg.norm() > 1.0 && d.dot(&leg) < 0.0) {
                out.next = Some(if s.route.waypoints[i].hold_s > 0.0 {
                    Phase::Hold(i)
                } else if i < s.last {
                    Phase::Leg(i + 1)
                } else {
                    Phase::Descent
                });
                if out.next == Some(Phase::Descent) && s.quad {
                    st.vtol = VtolState::TransitionToMc;
                }
            }
        }
        Phase::Hold(i) => {
            let c = s.route.waypoints[i].ned();
            let vg = (st.vel.x * st.vel.x + st.vel.y * st.vel.y).sqrt();
            (ask.course, ask.turn_ff) = loiter_course(&st.pos, &c, s.loiter_r, vg);
            ask.height_m = s.route.waypoints[i].alt_m;
            ask.airspeed_mps = s.speed_of(i);
            if phase_t >= s.route.waypoints[i].hold_s {
                out.next = Some(if i < s.last {
                    Phase::Leg(i + 1)
                } else {
                    Phase::Descent
                });
                if out.next == Some(Phase::Descent) && s.quad {
                    st.vtol = VtolState::TransitionToMc;
                }
            }
        }
        Phase::Descent => {
            // To the approach start, then down the glide path.
            let h0 = s.route.waypoints[s.last].alt_m;
            let start = s.land - s.u * (h0 / GLIDE.tan() + 80.0);
            let along = (s.land - st.pos).dot(&s.u);
            if !fl.on_final {
                ask.course = course_to(&st.pos, &start);
                ask.height_m = h0;
                let d = Vector3::new(start.x - st.pos.x, start.y - st.pos.y, 0.0);
                if d.norm() < 2.0 * ARRIVAL_M {
                    fl.on_final = true;
                }
            } else {
                let rel = st.pos - s.land;
                let xtrack = -rel.x * s.u.y + rel.y * s.u.x;
                let chi_line = s.u.y.atan2(s.u.x);
                ask.course = chi_line - (xtrack / 30.0).atan().clamp(-1.0, 1.0);
                ask.height_m = (along * GLIDE.tan()).clamp(0.0, h0);
                ask.airspeed_mps = 1.3 * s.v_stall;
                ask.idle = h < 2.0;
            }
        }
        _ => {}
    }
    ask
}

/// The take-off or landing roll along the runway (the ground stops the sink).
fn ground_roll(
    s: &Setup,
    st: &mut State,
    fl: &mut Flight,
    phase: Phase,
    bus_v: f64,
    out: &mut StepOut,
) {
    // Take-off or landing roll along the runway (the ground stops the sink).
    let va = st.vel - st.wind;
    let vdir = Vector3::new(st.yaw.cos(), st.yaw.sin(), 0.0);
    let v_air = va.dot(&vdir).max(0.0);
    let q = 0.5 * s.rho * v_air * v_air * s.p.wing_area_m2;
    let lift = q * 0.3;
    let drag = s.wing.drag_n(v_air, 0.3, s.rho);
    let gs = st.vel.dot(&vdir);
    let (t, decel) = if phase == Phase::Climb {
        (
            s.pusher.max_thrust_n(v_air, bus_v, s.cells, s.rho),
            0.05 * (s.mass * G - lift).max(0.0),
        )
    } else {
        (0.0, s.mass * 2.0)
    };
    fl.thrust_n = t;
    let a = ((t - drag - decel) / s.mass).max(if gs > 0.0 { -50.0 } else { 0.0 });
    let gs2 = (gs + a * DT).max(0.0);
    st.acc = vdir * (gs2 - gs) / DT;
    st.vel = vdir * gs2;
    st.pos += st.vel * DT;
    st.pos.z = 0.0;
    let draw = s.pusher.draw(t, v_air, bus_v, s.rho);
    out.pusher_w = draw.electrical_w;
    out.throttle = draw.throttle;
    out.att = Some(Rotation3::from_euler_angles(0.0, 0.0, st.yaw));
    st.airspeed_mps = Some(v_air);
    if phase == Phase::Climb && v_air >= 1.25 * s.v_stall {
        fl.on_ground = false;
    }
    if phase == Phase::Descent && gs2 <= 0.01 {
        out.next = Some(Phase::Landed);
    }
}

/// Fixed-wing flight in the air: one step of [`fw_step`] toward `ask`; a landing plane
/// meets the ground.
#[allow(clippy::too_many_arguments)] // one step: the setup, the state, the ask, the air
fn on_wing(
    s: &Setup,
    st: &mut State,
    fl: &mut Flight,
    phase: Phase,
    ask: &Ask,
    wind_est: &Vector3<f64>,
    bus_v: f64,
    out: &mut StepOut,
) {
    let craft = Craft {
        wing: &s.wing,
        pusher: &s.pusher,
        rho: s.rho,
        cells: s.cells,
    };
    let (draw, aero) = fw_step(st, fl, &craft, ask, wind_est, bus_v);
    out.pusher_w = draw.electrical_w;
    out.throttle = draw.throttle;
    let va = st.vel - st.wind;
    let chi = va.y.atan2(va.x);
    let gamma = (-va.z / aero.v).clamp(-1.0, 1.0).asin();
    st.yaw = chi;
    out.att = Some(Rotation3::from_euler_angles(
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
