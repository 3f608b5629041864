//! Fly a plan on paper: a kinematic model of how a multirotor flies a waypoint mission,
//! sampled at the models' rate into the 21 features they read. A plane and a VTOL fly it
//! as [`plane`] does ([`fly_as`] picks by the vehicle class).
//!
//! ## The flight
//!
//! The plan becomes a list of segments, each a closed-form function of time:
//! - **climb** (TAKEOFF): vertical, at `climb_m_s`;
//! - **legs** (WAYPOINT, LOITER_TIME, LAND's and RTL's approach, a not-modelled NAV item
//!   with a position): a straight line, stop to stop (the M100's waypoint missions stop at
//!   every waypoint): accelerate at `accel_m_s2` to the cruise speed, cruise, decelerate,
//!   a trapezoidal speed profile over the horizontal distance (triangular when too short to
//!   reach the speed). A height change on a leg is spread evenly over it, and the leg lasts
//!   at least as long as the climb or descent needs at `climb_m_s` / `descent_m_s`;
//! - **pauses** of `waypoint_pause_s` at every stop, during which the vehicle turns to the
//!   next leg's heading (the turn is the yaw rate `angular_z`), plus the item's hold or
//!   loiter time;
//! - **descent** (LAND, RTL): vertical, at `descent_m_s` down to `slow_below_m` above
//!   home, then `land_m_s` to the ground;
//! - **spin-up**: before every lift-off the motors run `spinup_s` on the ground (held at
//!   hover): the M100 spends ~4.4 s between its motors passing 150 W and leaving the ground.
//!
//! The defaults are the M100's, each measured on its own on the data set's training flights
//! (`lab/scripts/measure-kinematics.py`: the 130 R1 training flights whose stops match the
//! route's three legs; medians): spin-up 4.4 s; climb 2.9 m/s (3.0 kept). The script cuts
//! legs from stops at a horizontal speed of 1 m/s, which moves the slow ends of every
//! acceleration into the stops: a trapezoid at `a` shows as a leg of distance/speed +
//! (v − 2)/a and a stop of pause + 2/a. Fitted through that cut, the legs (their time over
//! distance/speed: 0.7, 1.6, 2.3, 3.2, 4.2 s at 4, 6, 8, 10, 12 m/s) give a = 2.5 m/s² and
//! the stops (2.7 s) a pause of 1.9 s, which the stop after the climb (2.35 s = pause + 1/a)
//! confirms on its own; the last stop and descent (24, 35, 44, 52 s from 25, 50, 75, 100 m)
//! give 2.7 m/s, then 1 m/s in the last 20 m. Measured this way, not fitted to the total,
//! the plan's clock also agrees with the flight's *during* it: where the vehicle is at half
//! time is where the plan has it (median |lag| 1.1 s on the training flights, 3.1 s with the
//! first defaults that matched only the total), and the plan's time left at half time is
//! within 1.4 % (median; 1.9 % with a = 3.2 m/s² and 2.7 s pauses read off the cut as they
//! were), which is what the live forecast's "what is left" rests on.
//!
//! ## Features (the data set's frames and units, see [`crate::telemetry`])
//!
//! Positions are a flat-earth offset (east, north, up; metres) from home, turned into
//! longitude/latitude (deg) and altitude above sea level. The vehicle's forward axis (body
//! y of the data set's quaternion) points along the leg; its thrust axis tilts toward the
//! horizontal force it needs, `tan θ = |a_h / g + c·|u|·u|`, with `u` the airspeed and
//! `c = tilt_per_airspeed2` (≈ 9° nose-down at 10 m/s, as the data set shows). From that:
//! the quaternion, the heading-frame ground velocity (`velocity_x` right, `velocity_y`
//! forward, `velocity_z` up), the body rates (FRD; only the yaw rate is non-zero), the
//! specific force (FRD, `z ≈ −9.81` at rest), the anemometer airspeed and its bearing
//! (`wind_speed`, `wind_angle`: the airspeed vector is ground velocity minus wind), and the
//! mission features (`speed` the current commanded speed, `payload`, `altitude` the
//! plan's highest altitude above home, as the data set records multi-stage altitudes).
//!
//! Pure: no I/O.

mod conditions;
pub mod plane;
mod route;

pub use conditions::{Conditions, KinematicsConfig, Wind};

use nalgebra::{UnitQuaternion, Vector3};

use super::plan::{GeoPoint, ItemKind, Plan};
use crate::features::units::wrap_pi;
use crate::features::{idx, HomeVector, Sample, N_FEATURES};
use route::segments;

/// Standard gravity, m/s².
const G_M_S2: f64 = 9.81;

/// One leg: the part of the flight that serves one plan item (climb, flight to a
/// waypoint and the stop there, descent).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Leg {
    /// The plan item it serves (index into [`Plan::items`]).
    pub item: usize,
    /// What it is, for tables: `takeoff`, `waypoint`, `loiter`, `land`, `rtl`, `not modelled 31`.
    pub label: String,
    /// Start and end time from the motors' start (the take-off's spin-up), s.
    pub t_start_s: f64,
    pub t_end_s: f64,
    /// Horizontal distance flown, m.
    pub distance_m: f64,
    /// First sample and one past the last, indices into [`Trajectory::samples`].
    pub samples: std::ops::Range<usize>,
}

/// A plan flown on paper.
#[derive(Debug, Clone)]
pub struct Trajectory {
    /// One sample per 1/rate_hz from the motors' start (spin-up) to touchdown.
    pub samples: Vec<Sample>,
    /// East, north, up from home, m, per sample.
    pub enu_m: Vec<[f32; 3]>,
    /// Index into `legs` per sample.
    pub leg_of: Vec<u32>,
    /// The legs in order.
    pub legs: Vec<Leg>,
    /// Sample period, s.
    pub dt_s: f64,
    /// Samples whose power is given rather than modelled (a VTOL's transitions with the
    /// profile's `transition_w`): sample range and power, W.
    pub given_w: Vec<(std::ops::Range<usize>, f64)>,
}

/// A piece of motion, closed form in its local time.
#[derive(Debug, Clone, Copy)]
enum Motion {
    /// Stay at `at`, turning from heading `yaw0` to `yaw1` (rad, ENU bearing of forward).
    Hover {
        at: Vector3<f64>,
        yaw0: f64,
        yaw1: f64,
    },
    /// Vertical from `from` to height `z1` at `rate` m/s.
    Vertical { from: Vector3<f64>, z1: f64 },
    /// Straight leg, trapezoidal horizontal speed (`v` cruise, `a` accel), height linear in time.
    Line {
        from: Vector3<f64>,
        to: Vector3<f64>,
        v: f64,
        a: f64,
    },
}

#[derive(Debug, Clone, Copy)]
struct Segment {
    motion: Motion,
    duration_s: f64,
    yaw: f64,
    leg: usize,
}

/// Position, velocity, acceleration (ENU) and heading at local time `t` of a segment.
fn state(seg: &Segment, t: f64) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>, f64, f64) {
    let d = seg.duration_s.max(1e-9);
    match seg.motion {
        Motion::Hover { at, yaw0, yaw1 } => {
            let dy = wrap_pi(yaw1 - yaw0);
            let f = (t / d).clamp(0.0, 1.0);
            (
                at,
                Vector3::zeros(),
                Vector3::zeros(),
                yaw0 + dy * f,
                dy / d,
            )
        }
        Motion::Vertical { from, z1 } => {
            let rate = (z1 - from.z) / d;
            (
                Vector3::new(from.x, from.y, from.z + rate * t),
                Vector3::new(0.0, 0.0, rate),
                Vector3::zeros(),
                seg.yaw,
                0.0,
            )
        }
        Motion::Line { from, to, v, a } => {
            let dh = (to - from).xy();
            let len = dh.norm();
            let dir = if len > 1e-9 {
                dh / len
            } else {
                nalgebra::Vector2::zeros()
            };
            let (s, sp, acc) = trapezoid(len, v, a, t);
            let vz = (to.z - from.z) / d;
            let p = Vector3::new(from.x + dir.x * s, from.y + dir.y * s, from.z + vz * t);
            (
                p,
                Vector3::new(dir.x * sp, dir.y * sp, vz),
                Vector3::new(dir.x * acc, dir.y * acc, 0.0),
                seg.yaw,
                0.0,
            )
        }
    }
}

/// Distance, speed and acceleration at time `t` of a stop-to-stop move over `len` m at
/// top speed `v` and acceleration `a`.
fn trapezoid(len: f64, v: f64, a: f64, t: f64) -> (f64, f64, f64) {
    let v_top = v.min((len * a).sqrt());
    let t_acc = v_top / a;
    let d_acc = 0.5 * a * t_acc * t_acc;
    let t_cruise = ((len - 2.0 * d_acc) / v_top.max(1e-9)).max(0.0);
    let total = 2.0 * t_acc + t_cruise;
    let t = t.clamp(0.0, total);
    if t < t_acc {
        (0.5 * a * t * t, a * t, a)
    } else if t < t_acc + t_cruise {
        (d_acc + v_top * (t - t_acc), v_top, 0.0)
    } else {
        let r = total - t;
        (len - 0.5 * a * r * r, a * r, -a)
    }
}

fn trapezoid_time(len: f64, v: f64, a: f64) -> f64 {
    if len <= 0.0 {
        return 0.0;
    }
    let v_top = v.min((len * a).sqrt());
    let t_acc = v_top / a;
    2.0 * t_acc + ((len - a * t_acc * t_acc) / v_top).max(0.0)
}

/// East/north offset of `p` from `home`, m (flat earth: fine over a mission's kilometres;
/// [`crate::features::frames::ne_offset_m`], the one conversion every part uses).
pub fn enu_of(home: &GeoPoint, lat_deg: f64, lon_deg: f64) -> (f64, f64) {
    let (n, e) = crate::features::frames::ne_offset_m(home.lat_deg, home.lon_deg, lat_deg, lon_deg);
    (e, n)
}

/// The body attitude for a heading (rad, ENU bearing of forward) and the horizontal
/// force per unit mass the thrust tilts toward, and what the features read off it.
#[derive(Debug, Clone, Copy)]
struct Attitude {
    /// The data set's quaternion (x, y, z, w; w ≥ 0).
    q_xyzw: [f32; 4],
    /// The quaternion's own yaw ψ (heading frame of the velocity features).
    sin_psi: f64,
    cos_psi: f64,
    /// Forward and right, ENU horizontal unit vectors.
    fwd: nalgebra::Vector2<f64>,
    right: nalgebra::Vector2<f64>,
}

fn attitude(heading: f64, f_h: nalgebra::Vector2<f64>) -> Attitude {
    let tilt = (f_h.norm() / G_M_S2).atan();
    let yaw_body_x = heading - std::f64::consts::FRAC_PI_2; // body y is forward
    let q_yaw = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw_body_x);
    let q = if tilt > 1e-6 {
        let axis = Vector3::z().cross(&Vector3::new(f_h.x, f_h.y, 0.0));
        UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_normalize(axis), tilt) * q_yaw
    } else {
        q_yaw
    };
    let r = q.to_rotation_matrix();
    let psi = r.matrix()[(1, 0)].atan2(r.matrix()[(0, 0)]);
    let (sin_psi, cos_psi) = psi.sin_cos();
    let fwd = nalgebra::Vector2::new(heading.cos(), heading.sin());
    let qq = q.quaternion();
    let sign = if qq.w < 0.0 { -1.0 } else { 1.0 };
    Attitude {
        q_xyzw: [
            (sign * qq.i) as f32,
            (sign * qq.j) as f32,
            (sign * qq.k) as f32,
            (sign * qq.w) as f32,
        ],
        sin_psi,
        cos_psi,
        fwd,
        right: nalgebra::Vector2::new(fwd.y, -fwd.x),
    }
}

/// The highest altitude the plan commands, m above home (the data set's `altitude`).
fn commanded_altitude(plan: &Plan) -> f64 {
    let cmd_alt = plan.items.iter().filter_map(|i| match i.kind {
        ItemKind::Takeoff { alt_m } | ItemKind::VtolTakeoff { alt_m } => Some(alt_m),
        _ => i.position.map(|p| p.alt_m),
    });
    cmd_alt.fold(0.0f64, f64::max)
}

/// Turns a rotor-borne state (position, velocity, acceleration ENU, heading, yaw rate)
/// into a sample of the 21 features; the attitude and the anemometer are remembered
/// between samples (steady cruise, climbs and holds repeat them sample after sample).
struct RotorFeatures<'a> {
    plan: &'a Plan,
    k: &'a KinematicsConfig,
    c: &'a Conditions,
    cmd_alt: f64,
    wind: Vector3<f64>,
    att: ([f64; 3], Attitude),
    anemo: ([f64; 2], f32, f32),
}

impl<'a> RotorFeatures<'a> {
    fn new(plan: &'a Plan, k: &'a KinematicsConfig, c: &'a Conditions) -> Self {
        Self {
            plan,
            k,
            c,
            cmd_alt: commanded_altitude(plan),
            wind: c.wind.velocity_enu(),
            // memo keys start as NaN: never equal, the first sample computes them
            att: ([f64::NAN; 3], attitude(0.0, nalgebra::Vector2::zeros())),
            anemo: ([f64::NAN; 2], 0.0, 0.0),
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn sample(
        &mut self,
        t: f64,
        p: Vector3<f64>,
        v: Vector3<f64>,
        a: Vector3<f64>,
        heading: f64,
        yaw_rate: f64,
        cur_speed: f64,
    ) -> Sample {
        let air = v - self.wind;
        // thrust axis: tilt toward the horizontal force per unit mass
        let f_h = a.xy() + G_M_S2 * self.k.tilt_per_airspeed2 * air.xy().norm() * air.xy();
        let key = [heading, f_h.x, f_h.y];
        if self.att.0 != key {
            self.att = (key, attitude(heading, f_h));
        }
        let air_key = [air.x, air.y];
        if self.anemo.0 != air_key {
            self.anemo = (
                air_key,
                air.xy().norm() as f32,
                air.x.atan2(air.y).to_degrees().rem_euclid(360.0) as f32,
            );
        }
        let att = &self.att.1;
        let (sn, cs) = (att.sin_psi, att.cos_psi);
        let vx = v.x * cs + v.y * sn;
        let vy = -v.x * sn + v.y * cs;
        let (fwd, right) = (att.fwd, att.right);
        let mut f = [0.0f32; N_FEATURES];
        f[idx::WIND_SPEED] = self.anemo.1;
        f[idx::WIND_ANGLE] = self.anemo.2;
        [f[idx::QX], f[idx::QY], f[idx::QZ], f[idx::QW]] = att.q_xyzw;
        f[idx::VX] = vx as f32;
        f[idx::VY] = vy as f32;
        f[idx::VZ] = v.z as f32;
        f[idx::WZ] = -yaw_rate as f32;
        f[idx::AX] = a.xy().dot(&fwd) as f32;
        f[idx::AY] = a.xy().dot(&right) as f32;
        f[idx::AZ] = -(G_M_S2 + a.z) as f32;
        f[idx::SPEED] = cur_speed as f32;
        mission_sample(self.plan, self.c, self.cmd_alt, t, p, f)
    }
}

/// A sample at `t` and ENU position `p` with the motion features `f` filled: the position,
/// the mission features and the home vector added.
fn mission_sample(
    plan: &Plan,
    c: &Conditions,
    cmd_alt: f64,
    t: f64,
    p: Vector3<f64>,
    mut f: [f32; N_FEATURES],
) -> Sample {
    let (lat, lon) =
        crate::features::frames::offset_ne(plan.home.lat_deg, plan.home.lon_deg, p.y, p.x);
    f[idx::POS_X] = lon as f32;
    f[idx::POS_Y] = lat as f32;
    f[idx::POS_Z] = (plan.home.alt_m + p.z) as f32;
    f[idx::PAYLOAD] = c.payload_g as f32;
    f[idx::ALTITUDE] = cmd_alt as f32;
    Sample {
        t_s: t,
        features: f,
        measured_w: None,
        voltage_v: None,
        home: Some(HomeVector {
            distance_m: p.xy().norm() as f32,
            height_m: p.z as f32,
        }),
        stale_mask: 0,
        battery_remaining_pct: None,
        vehicle: Default::default(),
        air: Default::default(),
    }
}

/// Leg times and sample ranges from the leg of each sample (samples are in leg order).
fn close_legs(legs: &mut [Leg], leg_of: &[u32], dt: f64) {
    let mut j = 0;
    while j < leg_of.len() {
        let li = leg_of[j] as usize;
        let a = j;
        while j < leg_of.len() && leg_of[j] as usize == li {
            j += 1;
        }
        if let Some(leg) = legs.get_mut(li) {
            leg.samples = a..j;
            leg.t_start_s = a as f64 * dt;
            leg.t_end_s = j as f64 * dt;
        }
    }
}

/// The vehicle class a plan is flown as: a multirotor (and anything without a model) as
/// [`fly`] flies it, a plane and a VTOL as [`plane::fly_plane`] does.
pub fn fly_as(
    class: crate::features::VehicleClass,
    plan: &Plan,
    k: &KinematicsConfig,
    flight: &crate::model::physics::fixed_wing::Flight,
    c: &Conditions,
) -> Trajectory {
    use crate::features::VehicleClass as V;
    match class {
        V::FixedWing => plane::fly_plane(plan, k, flight, false, c),
        V::Vtol => plane::fly_plane(plan, k, flight, true, c),
        V::Multirotor | V::Other => fly(plan, k, c),
    }
}

/// Fly `plan` on paper as a multirotor. Never fails: a plan with no motion gives no samples.
pub fn fly(plan: &Plan, k: &KinematicsConfig, c: &Conditions) -> Trajectory {
    let speed0 = c
        .speed_m_s
        .or(plan.hover_speed_m_s)
        .unwrap_or(k.default_speed_m_s);
    let mut legs = Vec::new();
    let segs = segments(plan, k, speed0, &mut legs);
    let dt = 1.0 / c.rate_hz;
    let mut feats = RotorFeatures::new(plan, k, c);
    // Commanded speed feature per segment: the speed in force (changes are rare; the
    // segment's own top speed where it has one).
    let mut cur_speed = speed0;
    let durations: Vec<f64> = segs.iter().map(|s| s.duration_s).collect();
    sampled(&durations, dt, legs, |_, t, i, local_t| {
        let seg = &segs[i];
        if let Motion::Line { v, .. } = seg.motion {
            cur_speed = v;
        }
        let (p, v, a, heading, yaw_rate) = state(seg, local_t);
        let s = feats.sample(t, p, v, a, heading, yaw_rate, cur_speed);
        (s, p, seg.leg)
    })
}

/// Sample segments of `durations` every `dt` from 0 to their end: `at(j, t, segment,
/// local time)` gives sample `j`, its ENU position and its leg; then the legs' times and
/// sample ranges.
fn sampled(
    durations: &[f64],
    dt: f64,
    mut legs: Vec<Leg>,
    mut at: impl FnMut(usize, f64, usize, f64) -> (Sample, Vector3<f64>, usize),
) -> Trajectory {
    let total: f64 = durations.iter().sum();
    let n = if durations.is_empty() {
        0
    } else {
        crate::features::units::floor_ratio(total, dt).unwrap_or(0.0) as usize + 1
    };
    let mut samples = Vec::with_capacity(n);
    let mut enu_m = Vec::with_capacity(n);
    let mut leg_of = Vec::with_capacity(n);
    let (mut seg_i, mut seg_t0) = (0usize, 0.0f64);
    for j in 0..n {
        let t = j as f64 * dt;
        while seg_i + 1 < durations.len() && t >= seg_t0 + durations[seg_i] {
            seg_t0 += durations[seg_i];
            seg_i += 1;
        }
        let (s, p, leg) = at(j, t, seg_i, t - seg_t0);
        samples.push(s);
        enu_m.push([p.x as f32, p.y as f32, p.z as f32]);
        leg_of.push(leg as u32);
    }
    close_legs(&mut legs, &leg_of, dt);
    Trajectory {
        samples,
        enu_m,
        leg_of,
        legs,
        dt_s: dt,
        given_w: Vec::new(),
    }
}

impl Trajectory {
    /// Duration from the start of the climb to touchdown, s.
    pub fn duration_s(&self) -> f64 {
        self.samples.len() as f64 * self.dt_s
    }

    /// The sample nearest (3-D) to `enu_m` among samples `from..from + horizon`: how a
    /// live re-forecast finds where on the plan the vehicle is, searching forward from
    /// where it was (or from the first sample of the leg toward the current item), so a
    /// route that crosses itself cannot send it back or far ahead.
    pub fn locate(&self, from: usize, horizon: usize, enu_m: [f32; 3]) -> usize {
        let end = (from + horizon).min(self.enu_m.len());
        let d2 = |p: &[f32; 3]| {
            (p[0] - enu_m[0]).powi(2) + (p[1] - enu_m[1]).powi(2) + (p[2] - enu_m[2]).powi(2)
        };
        let mut best = from.min(self.enu_m.len().saturating_sub(1));
        let mut best_d = f32::INFINITY;
        for (i, p) in self.enu_m.iter().enumerate().take(end).skip(from) {
            let d = d2(p);
            if d < best_d {
                best_d = d;
                best = i;
            }
        }
        best
    }

    /// First sample of the first leg that serves plan item `item` or a later one (the
    /// vehicle is flying toward `item`): where [`Trajectory::locate`] starts for a
    /// MISSION_CURRENT of `item`.
    pub fn first_sample_of_item(&self, item: usize) -> usize {
        self.legs
            .iter()
            .find(|l| l.item >= item)
            .map_or(self.samples.len(), |l| l.samples.start)
    }
}

#[cfg(test)]
mod tests;
