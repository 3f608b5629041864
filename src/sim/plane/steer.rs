//! One fixed-wing step of the simulated plane, and the courses it steers: to a point, and
//! round a loiter circle (the formulas are [`super`]'s docs).

use std::f64::consts::PI;

use nalgebra::Vector3;

use super::*;

/// One fixed-wing step of `st` (inertial velocity, position) and `fl` (bank, thrust) in the
/// air `st.wind`, asked `ask`, the autopilot's wind estimate `wind_est`, the pack at `bus_v`;
/// returns the pusher's draw. The formulas are the module docs'.
pub(super) fn fw_step(
    st: &mut State,
    fl: &mut Flight,
    craft: &Craft,
    ask: &Ask,
    wind_est: &Vector3<f64>,
    bus_v: f64,
) -> (PusherDraw, Aero) {
    let (wing, pusher, rho, cells) = (craft.wing, craft.pusher, craft.rho, craft.cells);
    let m = wing.mass_kg;
    let va = st.vel - st.wind;
    let v = va.norm().max(1.0);
    let chi = va.y.atan2(va.x);
    let gamma = (-va.z / v).clamp(-1.0, 1.0).asin();
    let v_stall = wing.stall_mps(rho);
    // Lateral: the air heading that makes good the ground course, as a turn rate, a bank.
    let w_perp = -wind_est.x * ask.course.sin() + wind_est.y * ask.course.cos();
    let heading = ask.course - (w_perp / v).clamp(-0.9, 0.9).asin();
    let phi_max = wing.p.bank_limit_deg.to_radians();
    let rate = 0.6 * wrap_pi(heading - chi) + ask.turn_ff;
    let phi_cmd = (rate * v / G).atan().clamp(-phi_max, phi_max);
    let dphi = ((phi_cmd - fl.phi) * DT / TAU_PHI).clamp(-ROLL_RATE_MAX * DT, ROLL_RATE_MAX * DT);
    fl.phi += dphi;
    // Vertical: climb rate from the height error, as a path angle, within the limits.
    let h = -st.pos.z;
    let mut climb = (0.25 * (ask.height_m - h)).clamp(-SINK_MAX, CLIMB_MAX);
    if ask.idle {
        climb = climb.min(-0.5);
    }
    let mut gamma_cmd = (climb / v)
        .clamp(-1.0, 1.0)
        .asin()
        .clamp(-GAMMA_MAX, GAMMA_MAX);
    let v_min = 1.15 * v_stall;
    if v < v_min {
        gamma_cmd -= 0.1 * (v_min - v);
    }
    let gamma_dot = 0.8 * (gamma_cmd - gamma);
    let q_max = 0.5 * rho * v * v * wing.p.wing_area_m2 * wing.p.cl_max;
    let n = ((v * gamma_dot / G + gamma.cos()) / fl.phi.cos()).clamp(0.0, q_max / (m * G));
    let lift = n * m * G;
    let cl = wing.cl(lift, v, rho);
    let drag = wing.drag_n(v, cl, rho);
    // Speed: the thrust that holds the airspeed, up to what the propeller gives.
    let t_max = pusher.max_thrust_n(v, bus_v, cells, rho);
    let t_cmd = if ask.idle {
        0.0
    } else {
        (drag + m * G * gamma.sin() + m * 0.5 * (ask.airspeed_mps - v)).clamp(0.0, t_max)
    };
    fl.thrust_n += (t_cmd - fl.thrust_n) * DT / TAU_T;
    // Integrate the air-relative motion; the inertial velocity changes by as much.
    let v_dot = (fl.thrust_n - drag) / m - G * gamma.sin();
    let chi_dot = G * fl.phi.tan() / v;
    let g_dot = G / v * (n * fl.phi.cos() - gamma.cos());
    let (v2, chi2, g2) = (
        (v + v_dot * DT).max(1.0),
        chi + chi_dot * DT,
        gamma + g_dot * DT,
    );
    let va2 = Vector3::new(
        v2 * g2.cos() * chi2.cos(),
        v2 * g2.cos() * chi2.sin(),
        -v2 * g2.sin(),
    );
    let vel2 = st.vel + (va2 - va);
    st.acc = (vel2 - st.vel) / DT;
    st.vel = vel2;
    st.pos += st.vel * DT;
    let draw = pusher.draw(fl.thrust_n, v, bus_v, rho);
    let alpha = cl / 5.0 - 0.03;
    (
        draw,
        Aero {
            v,
            drag_n: drag,
            alpha,
        },
    )
}

/// The course from `pos` toward `target` (NED), rad.
pub(super) fn course_to(pos: &Vector3<f64>, target: &Vector3<f64>) -> f64 {
    (target.y - pos.y).atan2(target.x - pos.x)
}

/// The ground course round a clockwise loiter circle of radius `r` about `c`, and the
/// turn rate a ground speed `v` needs on it.
pub fn loiter_course(pos: &Vector3<f64>, c: &Vector3<f64>, r: f64, v: f64) -> (f64, f64) {
    let d = Vector3::new(pos.x - c.x, pos.y - c.y, 0.0);
    let dist = d.norm().max(1e-3);
    let theta = d.y.atan2(d.x);
    let err = dist - r;
    let course = theta + PI / 2.0 + (err / (0.5 * r)).atan();
    let ff = if err.abs() < r { v / r } else { 0.0 };
    (course, ff)
}
