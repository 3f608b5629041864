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
const G: f64 = 9.80665;
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

/// The flight being built: where the vehicle is, its heading and airspeed, its mode.
struct Builder<'a> {
    f: &'a Flight,
    vtol: bool,
    wind: V2,
    segs: Vec<Seg>,
    pos: V3,
    /// Heading of the nose, rad (ENU bearing).
    psi: f64,
    airspeed: f64,
    airborne: bool,
    /// A VTOL on its rotors (before the first transition, after a back transition).
    on_rotors: bool,
    leg: usize,
    /// Horizontal distance of the current leg, m.
    dist: f64,
}

impl Builder<'_> {
    fn push(&mut self, piece: Piece, duration_s: f64) {
        if duration_s > 0.0 && duration_s.is_finite() {
            self.segs.push(Seg {
                piece,
                duration_s,
                leg: self.leg,
            });
        }
    }

    /// Turn (at the bank limit) from the current heading onto the tangent that leads to
    /// `target`, when airborne on the wing.
    fn turn_toward(&mut self, target: V2) {
        if !self.airborne || self.on_rotors {
            return;
        }
        let r = self.f.turn_radius_m(self.airspeed);
        let to = target - self.pos.xy();
        let delta = super::wrap_pi(to.y.atan2(to.x) - self.psi);
        if delta.abs() < 1e-3 || to.norm() < 1.0 {
            return;
        }
        let side = if delta > 0.0 { 1.0 } else { -1.0 };
        for s in [side, -side] {
            let c = self.pos.xy() - s * r * V2::new(self.psi.sin(), -self.psi.cos());
            let d = target - c;
            if d.norm() <= r * 1.001 {
                continue; // the target is inside this turn's circle
            }
            let psi_e = d.y.atan2(d.x) + (s * r / d.norm()).asin();
            let sweep = (s * (psi_e - self.psi)).rem_euclid(std::f64::consts::TAU);
            let t = sweep * r / self.airspeed;
            self.push(
                Piece::Turn {
                    c,
                    r,
                    psi0: self.psi,
                    s,
                    airspeed: self.airspeed,
                    drift: self.wind,
                    z: self.pos.z,
                },
                t,
            );
            let p = c + s * r * V2::new(psi_e.sin(), -psi_e.cos()) + self.wind * t;
            self.pos = V3::new(p.x, p.y, self.pos.z);
            self.psi = psi_e;
            self.dist += sweep * r;
            return;
        }
    }

    /// Straight to `target` over the ground, height toward its height within the climb
    /// and sink limits (what is not reached is carried on).
    fn straight_to(&mut self, target: V3) {
        self.straight_to_within(target, self.f.sink_m_s);
    }

    /// [`Builder::straight_to`] with its own sink limit, m/s.
    fn straight_to_within(&mut self, target: V3, sink_m_s: f64) {
        let dh = target.xy() - self.pos.xy();
        let len = dh.norm();
        if len < 0.5 {
            return;
        }
        let d = dh / len;
        let v = self.airspeed;
        let dz = target.z - self.pos.z;
        let mut t = len / ground_speed(d, v, self.wind);
        let mut vz = (dz / t).clamp(-sink_m_s, self.f.climb_m_s);
        let v_h = (v * v - vz * vz).max(0.0).sqrt();
        let g = ground_speed(d, v_h, self.wind);
        t = len / g;
        vz = (dz / t).clamp(-sink_m_s, self.f.climb_m_s);
        let air = g * d - self.wind;
        let heading = air.y.atan2(air.x);
        self.push(
            Piece::Straight {
                from: self.pos,
                vel: V3::new(g * d.x, g * d.y, vz),
                airspeed: v,
                heading,
            },
            t,
        );
        self.pos = V3::new(target.x, target.y, self.pos.z + vz * t);
        self.psi = heading;
        self.dist += len;
    }

    /// A VTOL on its rotors changes to forward flight (facing `toward`); a plane on the
    /// ground is taken to be airborne (it was launched).
    fn onto_wing(&mut self, toward: V2) {
        if self.on_rotors {
            let to = toward - self.pos.xy();
            if to.norm() > 0.5 {
                self.psi = to.y.atan2(to.x);
            }
            self.transition(true);
        }
        self.airborne = true;
    }

    fn transition(&mut self, to_fw: bool) {
        let (v0, v1, d) = if to_fw {
            (0.0, self.airspeed, self.f.transition_fw_s)
        } else {
            (self.airspeed, 0.0, self.f.transition_mc_s)
        };
        self.push(
            Piece::Transition {
                from: self.pos,
                heading: self.psi,
                v0,
                v1,
                to_fw,
            },
            d,
        );
        let s = 0.5 * (v0 + v1) * d;
        self.pos += V3::new(self.psi.cos() * s, self.psi.sin() * s, 0.0);
        self.dist += s;
        self.on_rotors = !to_fw;
    }

    /// Join a clockwise circle of radius `r` round `c` and fly it for `turns` turns or
    /// `time_s` seconds (whichever is given).
    fn loiter(&mut self, c: V3, r: f64, turns: Option<f64>, time_s: f64) {
        let r = r.max(self.f.turn_radius_m(self.airspeed));
        // arrive tangent to the circle, heading along it (clockwise: centre on the right)
        let to = c.xy() - self.pos.xy();
        let h = if to.norm() > 0.5 {
            to.y.atan2(to.x)
        } else {
            self.psi
        };
        let entry = c.xy() - r * V2::new(h.sin(), -h.cos());
        self.turn_toward(entry);
        self.straight_to(V3::new(entry.x, entry.y, c.z));
        let turn_s = loiter_turn_s(r, self.airspeed, self.wind);
        let duration = turns.map_or(time_s, |n| n * turn_s);
        let off = self.pos.xy() - c.xy();
        let a0 = off.y.atan2(off.x);
        let rate = std::f64::consts::TAU / turn_s;
        self.push(
            Piece::Loiter {
                c: c.xy(),
                r,
                a0,
                s: -1.0,
                rate,
                z: self.pos.z,
                airspeed: self.airspeed,
            },
            duration,
        );
        let a = a0 - rate * duration;
        let p = c.xy() + r * unit(a);
        self.pos = V3::new(p.x, p.y, self.pos.z);
        self.psi = a - std::f64::consts::FRAC_PI_2;
        self.dist += r * rate * duration;
    }

    /// Land at `at` (horizontal; `None`: straight ahead): a VTOL flies there, changes to
    /// hover and descends on its rotors; a plane glides in at the glide slope.
    fn land(&mut self, at: Option<V2>, vtol_land: bool) {
        let h = self.pos.z;
        if self.vtol && vtol_land {
            if let Some(p) = at {
                self.onto_wing(p);
                self.turn_toward(p);
                self.straight_to(V3::new(p.x, p.y, h));
            }
            if !self.on_rotors && self.airborne {
                self.transition(false);
            }
            let fin = self.f.vtol_land_final_m.min(self.pos.z).max(0.0);
            let from = self.pos;
            self.push(
                Piece::Vertical {
                    from,
                    z1: fin,
                    heading: self.psi,
                },
                (from.z - fin) / self.f.vtol_descent_m_s,
            );
            self.push(
                Piece::Vertical {
                    from: V3::new(from.x, from.y, fin),
                    z1: 0.0,
                    heading: self.psi,
                },
                fin / self.f.vtol_land_m_s,
            );
            self.pos.z = 0.0;
            self.airborne = false;
            return;
        }
        let glide = h / self.f.land_glide_deg.to_radians().tan();
        let p = at.unwrap_or_else(|| self.pos.xy() + glide * unit(self.psi));
        self.onto_wing(p);
        if self.f.land_into_wind && self.wind.norm() > 1.0 {
            // over the point, out downwind, and back into the wind down the glide
            self.turn_toward(p);
            self.straight_to(V3::new(p.x, p.y, h));
            let u = -self.wind / self.wind.norm();
            let start = p - u * (glide + self.f.land_straight_m);
            self.turn_toward(start);
            self.straight_to(V3::new(start.x, start.y, h));
            let straight = p - u * glide;
            self.turn_toward(straight);
            self.straight_to(V3::new(straight.x, straight.y, h));
        } else {
            self.turn_toward(p);
            let to = p - self.pos.xy();
            if to.norm() > glide {
                let start = p - to.normalize() * glide;
                self.straight_to(V3::new(start.x, start.y, h));
            }
        }
        let cruise = self.airspeed;
        if let Some(v) = self.f.land_airspeed_m_s {
            self.airspeed = v;
        }
        // the glide, whatever its slope, down to the ground at the point
        self.straight_to_within(V3::new(p.x, p.y, 0.0), f64::INFINITY);
        self.pos.z = 0.0;
        self.airborne = false;
        self.airspeed = cruise;
    }
}

/// The next position after item `i` (for the take-off's heading).
fn next_position(plan: &Plan, i: usize) -> Option<V2> {
    plan.items[i + 1..].iter().find_map(|it| {
        it.position.map(|p| {
            let (e, n) = enu_of(&plan.home, p.lat_deg, p.lon_deg);
            V2::new(e, n)
        })
    })
}

/// The pieces of a plan flown as a plane (`vtol`: a VTOL), and its legs.
fn segments(
    plan: &Plan,
    f: &Flight,
    vtol: bool,
    c: &Conditions,
    speed0: f64,
) -> (Vec<Seg>, Vec<Leg>) {
    let w = c.wind.velocity_enu();
    let mut b = Builder {
        f,
        vtol,
        wind: V2::new(w.x, w.y),
        segs: Vec::new(),
        pos: V3::zeros(),
        psi: std::f64::consts::FRAC_PI_2,
        airspeed: speed0,
        airborne: false,
        on_rotors: vtol,
        leg: 0,
        dist: 0.0,
    };
    let mut legs: Vec<Leg> = Vec::new();
    for (i, item) in plan.items.iter().enumerate() {
        let target = item.position.map(|p| {
            let (e, n) = enu_of(&plan.home, p.lat_deg, p.lon_deg);
            V3::new(e, n, p.alt_m)
        });
        b.leg = legs.len();
        b.dist = 0.0;
        let first = b.segs.len();
        let radius = item.loiter_radius_m.unwrap_or(f.loiter_radius_m);
        let label: String = match item.kind {
            ItemKind::ChangeSpeed { speed_m_s } => {
                if speed_m_s > 0.0 {
                    b.airspeed = speed_m_s;
                }
                continue;
            }
            ItemKind::Takeoff { alt_m } | ItemKind::VtolTakeoff { alt_m } => {
                if let (Some(t), false) = (target, b.airborne) {
                    b.pos = V3::new(t.x, t.y, 0.0);
                }
                if let Some(n) = next_position(plan, i) {
                    let to = n - b.pos.xy();
                    if to.norm() > 0.5 {
                        b.psi = to.y.atan2(to.x);
                    }
                }
                let climb = (alt_m - b.pos.z).max(0.0);
                if vtol && b.on_rotors {
                    let from = b.pos;
                    b.push(
                        Piece::Vertical {
                            from,
                            z1: alt_m.max(from.z),
                            heading: b.psi,
                        },
                        climb / f.vtol_climb_m_s,
                    );
                    b.pos.z += climb;
                    b.airborne = true;
                    "vtol takeoff".into()
                } else {
                    b.airborne = true;
                    let d = unit(b.psi);
                    let vz = f.climb_m_s.min(b.airspeed * 0.9);
                    let v_h = (b.airspeed * b.airspeed - vz * vz).sqrt();
                    let g = v_h * d + b.wind;
                    let t = climb / vz;
                    b.push(
                        Piece::Straight {
                            from: b.pos,
                            vel: V3::new(g.x, g.y, vz),
                            airspeed: b.airspeed,
                            heading: b.psi,
                        },
                        t,
                    );
                    b.pos += V3::new(g.x * t, g.y * t, climb);
                    b.dist += g.norm() * t;
                    "takeoff".into()
                }
            }
            ItemKind::Waypoint { .. }
            | ItemKind::NotModelled {
                flown_through: true,
                ..
            }
            | ItemKind::LoiterUnlimited => match target {
                Some(t) => {
                    b.onto_wing(t.xy());
                    b.turn_toward(t.xy());
                    b.straight_to(t);
                    match item.kind {
                        ItemKind::NotModelled { command, .. } => format!("not modelled {command}"),
                        ItemKind::LoiterUnlimited => "loiter unlimited (flown through)".into(),
                        _ => "waypoint".into(),
                    }
                }
                None => continue,
            },
            ItemKind::LoiterTime { time_s } => {
                let c0 = target.unwrap_or(b.pos);
                b.onto_wing(c0.xy());
                b.loiter(c0, radius, None, time_s);
                "loiter".into()
            }
            ItemKind::LoiterTurns { turns } => {
                let c0 = target.unwrap_or(b.pos);
                b.onto_wing(c0.xy());
                b.loiter(c0, radius, Some(turns), 0.0);
                "loiter turns".into()
            }
            ItemKind::VtolTransition { to_fw } => {
                if !vtol || !b.airborne || to_fw != b.on_rotors {
                    continue;
                }
                b.transition(to_fw);
                if to_fw {
                    "transition to fw"
                } else {
                    "transition to mc"
                }
                .into()
            }
            ItemKind::Land | ItemKind::VtolLand | ItemKind::ReturnToLaunch => {
                let at = match item.kind {
                    ItemKind::ReturnToLaunch => Some(V2::zeros()),
                    _ => target.map(|t| t.xy()),
                };
                // a VTOL lands on its rotors after VTOL_LAND and RTL (ArduPlane's
                // Q_RTL_MODE), a plane glides in
                let on_rotors = !matches!(item.kind, ItemKind::Land);
                b.land(at, on_rotors);
                match item.kind {
                    ItemKind::ReturnToLaunch => "rtl",
                    ItemKind::VtolLand => "vtol land",
                    _ => "land",
                }
                .into()
            }
            ItemKind::NotModelled { .. } => continue,
        };
        if b.segs.len() > first || b.dist > 0.0 {
            legs.push(Leg {
                item: i,
                label,
                t_start_s: 0.0,
                t_end_s: 0.0,
                distance_m: b.dist,
                samples: 0..0,
            });
        }
    }
    // A plan that ends in the air lands where it is (straight ahead).
    if b.pos.z > 0.0 {
        b.leg = legs.len();
        b.dist = 0.0;
        b.land(None, true);
        legs.push(Leg {
            item: plan.items.len().saturating_sub(1),
            label: "land (end of plan)".into(),
            t_start_s: 0.0,
            t_end_s: 0.0,
            distance_m: b.dist,
            samples: 0..0,
        });
    }
    (b.segs, legs)
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

#[cfg(test)]
mod tests;
