//! Building the plane's segments: a [`Builder`] walks the plan item by item (take-off,
//! legs with their turns, loiters, transitions, the landing) into [`Seg`]s.

use super::*;

/// The flight being built: where the vehicle is, its heading and airspeed, its mode.
pub(super) struct Builder<'a> {
    pub(super) f: &'a Flight,
    pub(super) vtol: bool,
    pub(super) wind: V2,
    pub(super) segs: Vec<Seg>,
    pub(super) pos: V3,
    /// Heading of the nose, rad (ENU bearing).
    pub(super) psi: f64,
    pub(super) airspeed: f64,
    pub(super) airborne: bool,
    /// A VTOL on its rotors (before the first transition, after a back transition).
    pub(super) on_rotors: bool,
    pub(super) leg: usize,
    /// Horizontal distance of the current leg, m.
    pub(super) dist: f64,
}

impl Builder<'_> {
    /// A take-off to `alt_m` above home, at `target` when the vehicle is still on the ground,
    /// heading for `next` (the plan's next position): a VTOL climbs on its rotors, a plane
    /// climbs out at its airspeed. The leg's label.
    fn takeoff(&mut self, target: Option<V3>, next: Option<V2>, alt_m: f64) -> &'static str {
        if let (Some(t), false) = (target, self.airborne) {
            self.pos = V3::new(t.x, t.y, 0.0);
        }
        if let Some(n) = next {
            let to = n - self.pos.xy();
            if to.norm() > 0.5 {
                self.psi = to.y.atan2(to.x);
            }
        }
        let climb = (alt_m - self.pos.z).max(0.0);
        if self.vtol && self.on_rotors {
            let from = self.pos;
            self.push(
                Piece::Vertical {
                    from,
                    z1: alt_m.max(from.z),
                    heading: self.psi,
                },
                climb / self.f.vtol_climb_m_s,
            );
            self.pos.z += climb;
            self.airborne = true;
            "vtol takeoff"
        } else {
            self.airborne = true;
            let d = unit(self.psi);
            let vz = self.f.climb_m_s.min(self.airspeed * 0.9);
            let v_h = (self.airspeed * self.airspeed - vz * vz).sqrt();
            let g = v_h * d + self.wind;
            let t = climb / vz;
            self.push(
                Piece::Straight {
                    from: self.pos,
                    vel: V3::new(g.x, g.y, vz),
                    airspeed: self.airspeed,
                    heading: self.psi,
                },
                t,
            );
            self.pos += V3::new(g.x * t, g.y * t, climb);
            self.dist += g.norm() * t;
            "takeoff"
        }
    }

    pub(super) fn push(&mut self, piece: Piece, duration_s: f64) {
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
    pub(super) fn turn_toward(&mut self, target: V2) {
        if !self.airborne || self.on_rotors {
            return;
        }
        let r = self.f.turn_radius_m(self.airspeed);
        let to = target - self.pos.xy();
        let delta = super::super::wrap_pi(to.y.atan2(to.x) - self.psi);
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
    pub(super) fn straight_to(&mut self, target: V3) {
        self.straight_to_within(target, self.f.sink_m_s);
    }

    /// [`Builder::straight_to`] with its own sink limit, m/s.
    pub(super) fn straight_to_within(&mut self, target: V3, sink_m_s: f64) {
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
    pub(super) fn onto_wing(&mut self, toward: V2) {
        if self.on_rotors {
            let to = toward - self.pos.xy();
            if to.norm() > 0.5 {
                self.psi = to.y.atan2(to.x);
            }
            self.transition(true);
        }
        self.airborne = true;
    }

    pub(super) fn transition(&mut self, to_fw: bool) {
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
    pub(super) fn loiter(&mut self, c: V3, r: f64, turns: Option<f64>, time_s: f64) {
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
    pub(super) fn land(&mut self, at: Option<V2>, vtol_land: bool) {
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

impl Builder<'_> {
    /// Fly item `i` (at `target`, loitering at `radius`): its label, or None for an item
    /// that flies nothing (a speed change, a transition already made, an item not modelled).
    fn fly_item(
        &mut self,
        plan: &Plan,
        i: usize,
        target: Option<V3>,
        radius: f64,
    ) -> Option<String> {
        let item = &plan.items[i];
        let vtol = self.vtol;
        Some(match item.kind {
            ItemKind::ChangeSpeed { speed_m_s } => {
                if speed_m_s > 0.0 {
                    self.airspeed = speed_m_s;
                }
                return None;
            }
            ItemKind::Takeoff { alt_m } | ItemKind::VtolTakeoff { alt_m } => {
                self.takeoff(target, next_position(plan, i), alt_m).into()
            }
            ItemKind::Waypoint { .. }
            | ItemKind::NotModelled {
                flown_through: true,
                ..
            }
            | ItemKind::LoiterUnlimited => match target {
                Some(t) => {
                    self.onto_wing(t.xy());
                    self.turn_toward(t.xy());
                    self.straight_to(t);
                    match item.kind {
                        ItemKind::NotModelled { command, .. } => format!("not modelled {command}"),
                        ItemKind::LoiterUnlimited => "loiter unlimited (flown through)".into(),
                        _ => "waypoint".into(),
                    }
                }
                None => return None,
            },
            ItemKind::LoiterTime { time_s } => {
                let c0 = target.unwrap_or(self.pos);
                self.onto_wing(c0.xy());
                self.loiter(c0, radius, None, time_s);
                "loiter".into()
            }
            ItemKind::LoiterTurns { turns } => {
                let c0 = target.unwrap_or(self.pos);
                self.onto_wing(c0.xy());
                self.loiter(c0, radius, Some(turns), 0.0);
                "loiter turns".into()
            }
            ItemKind::VtolTransition { to_fw } => {
                if !vtol || !self.airborne || to_fw != self.on_rotors {
                    return None;
                }
                self.transition(to_fw);
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
                self.land(at, on_rotors);
                match item.kind {
                    ItemKind::ReturnToLaunch => "rtl",
                    ItemKind::VtolLand => "vtol land",
                    _ => "land",
                }
                .into()
            }
            ItemKind::NotModelled { .. } => return None,
        })
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
pub(super) fn segments(
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
        let Some(label) = b.fly_item(plan, i, target, radius) else {
            continue;
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
