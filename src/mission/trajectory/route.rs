//! Building a multirotor's segments from a plan: take-off, legs with their accelerations
//! and turns, holds and loiters, the landing ([`Segment`]s and their [`Leg`]s).

use super::*;

/// A multirotor flying a plan on paper: where it is, which way it faces, its cruise
/// speed, whether it is airborne, and the segments flown so far.
struct Flier<'k> {
    k: &'k KinematicsConfig,
    segs: Vec<Segment>,
    pos: Vector3<f64>,
    yaw: f64,
    speed: f64,
    airborne: bool,
}

impl Flier<'_> {
    /// Hover at `at` for `d` s, turning from `yaw0` to `yaw1`.
    fn pause(&mut self, at: Vector3<f64>, yaw0: f64, yaw1: f64, d: f64, leg: usize) {
        if d > 0.0 {
            self.segs.push(Segment {
                motion: Motion::Hover { at, yaw0, yaw1 },
                duration_s: d,
                yaw: yaw1,
                leg,
            });
        }
    }

    /// Hover where it is, facing where it faces, for `d` s.
    fn hold(&mut self, d: f64, leg: usize) {
        self.pause(self.pos, self.yaw, self.yaw, d, leg);
    }

    /// Down at the descent rate to the slow height, then at the landing rate to the ground.
    fn descend(&mut self, leg: usize) {
        let k = self.k;
        let slow = k.slow_below_m.max(0.0);
        for (z1, rate) in [(slow, k.descent_m_s), (0.0, k.land_m_s)] {
            if self.pos.z > z1 {
                let d = (self.pos.z - z1) / rate;
                self.segs.push(Segment {
                    motion: Motion::Vertical { from: self.pos, z1 },
                    duration_s: d,
                    yaw: self.yaw,
                    leg,
                });
                self.pos.z = z1;
            }
        }
    }

    /// Leaving the ground: the motors spin up there first.
    fn lift_off(&mut self, leg: usize) {
        if !self.airborne && self.pos.z <= 0.0 {
            self.hold(self.k.spinup_s, leg);
        }
        self.airborne = true;
    }

    /// Stop, turn toward `to`, fly there (a trapezoid horizontally, the climb or descent
    /// rate vertically, whichever is longer); returns the horizontal distance, m.
    fn fly_to(&mut self, to: Vector3<f64>, leg: usize) -> f64 {
        let k = self.k;
        let dh = (to - self.pos).xy();
        let len = dh.norm();
        let heading = if len > 0.5 {
            dh.y.atan2(dh.x)
        } else {
            self.yaw
        };
        // turn toward the leg during the stop before it
        self.pause(self.pos, self.yaw, heading, k.waypoint_pause_s, leg);
        let t_h = trapezoid_time(len, self.speed, k.accel_m_s2);
        let dz = to.z - self.pos.z;
        let t_v = if dz >= 0.0 {
            dz / k.climb_m_s
        } else {
            -dz / k.descent_m_s
        };
        let d = t_h.max(t_v);
        if d > 0.0 {
            self.segs.push(Segment {
                motion: Motion::Line {
                    from: self.pos,
                    to,
                    v: self.speed,
                    a: k.accel_m_s2,
                },
                duration_s: d,
                yaw: heading,
                leg,
            });
        }
        self.pos = to;
        self.yaw = heading;
        len
    }

    /// Lift off if need be and fly to `t`; returns the distance, m.
    fn fly_through(&mut self, t: Vector3<f64>, leg: usize) -> f64 {
        self.lift_off(leg);
        self.fly_to(t, leg)
    }

    /// Fly one item (as leg `leg`, toward `target` where it has a position); its label and
    /// horizontal distance, or `None` for an item that is not a leg of its own.
    fn item(
        &mut self,
        kind: ItemKind,
        target: Option<Vector3<f64>>,
        leg: usize,
    ) -> Option<(String, f64)> {
        let k = self.k;
        let mut distance_m = 0.0;
        let label: String = match kind {
            ItemKind::ChangeSpeed { speed_m_s } => {
                if speed_m_s > 0.0 {
                    self.speed = speed_m_s;
                }
                return None;
            }
            ItemKind::VtolTransition { .. } => return None,
            ItemKind::Takeoff { alt_m } | ItemKind::VtolTakeoff { alt_m } => {
                if let Some(t) = target {
                    if !self.airborne {
                        self.pos = Vector3::new(t.x, t.y, 0.0);
                    }
                }
                self.lift_off(leg);
                if alt_m > self.pos.z {
                    let d = (alt_m - self.pos.z) / k.climb_m_s;
                    self.segs.push(Segment {
                        motion: Motion::Vertical {
                            from: self.pos,
                            z1: alt_m,
                        },
                        duration_s: d,
                        yaw: self.yaw,
                        leg,
                    });
                    self.pos.z = alt_m;
                }
                "takeoff".into()
            }
            ItemKind::Waypoint { hold_s } => {
                distance_m = self.fly_through(target?, leg);
                self.hold(hold_s, leg);
                "waypoint".into()
            }
            ItemKind::LoiterTime { time_s } => {
                if let Some(t) = target {
                    distance_m = self.fly_through(t, leg);
                }
                self.hold(time_s, leg);
                "loiter".into()
            }
            ItemKind::Land | ItemKind::VtolLand | ItemKind::ReturnToLaunch => {
                let to = match (kind, target) {
                    (ItemKind::ReturnToLaunch, _) => Some(Vector3::new(0.0, 0.0, self.pos.z)),
                    (_, Some(t)) => Some(Vector3::new(t.x, t.y, self.pos.z)),
                    _ => None,
                };
                if let Some(to) = to {
                    distance_m = self.fly_to(to, leg);
                }
                self.hold(k.waypoint_pause_s, leg);
                self.descend(leg);
                self.airborne = false;
                if !matches!(kind, ItemKind::ReturnToLaunch) {
                    "land".into()
                } else {
                    "rtl".into()
                }
            }
            // A multirotor flies a loiter of turns, or one for ever, through its position.
            ItemKind::LoiterTurns { .. } | ItemKind::LoiterUnlimited => {
                distance_m = self.fly_through(target?, leg);
                "loiter (flown through)".into()
            }
            ItemKind::NotModelled {
                command,
                flown_through,
            } => match (flown_through, target) {
                (true, Some(t)) => {
                    distance_m = self.fly_through(t, leg);
                    format!("not modelled {command}")
                }
                _ => return None,
            },
        };
        Some((label, distance_m))
    }
}

/// Build the segments of a plan; `speed0` is the cruise speed at the start.
pub(super) fn segments(
    plan: &Plan,
    k: &KinematicsConfig,
    speed0: f64,
    legs: &mut Vec<Leg>,
) -> Vec<Segment> {
    let mut f = Flier {
        k,
        segs: Vec::new(),
        pos: Vector3::zeros(),
        yaw: std::f64::consts::FRAC_PI_2, // facing north until the first leg
        speed: speed0,
        airborne: false,
    };
    for (i, item) in plan.items.iter().enumerate() {
        let target = item.position.map(|p| {
            let (e, n) = enu_of(&plan.home, p.lat_deg, p.lon_deg);
            Vector3::new(e, n, p.alt_m)
        });
        let leg = legs.len();
        let first = f.segs.len();
        let Some((label, distance_m)) = f.item(item.kind, target, leg) else {
            continue;
        };
        if f.segs.len() > first || distance_m > 0.0 {
            legs.push(Leg {
                item: i,
                label,
                t_start_s: 0.0,
                t_end_s: 0.0,
                distance_m,
                samples: 0..0,
            });
        }
    }
    // A plan that ends in the air lands where it is.
    if f.pos.z > 0.0 {
        let leg = legs.len();
        f.hold(k.waypoint_pause_s, leg);
        f.descend(leg);
        legs.push(Leg {
            item: plan.items.len().saturating_sub(1),
            label: "land (end of plan)".into(),
            t_start_s: 0.0,
            t_end_s: 0.0,
            distance_m: 0.0,
            samples: 0..0,
        });
    }
    f.segs
}
