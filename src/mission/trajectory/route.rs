//! Building a multirotor's segments from a plan: take-off, legs with their accelerations
//! and turns, holds and loiters, the landing ([`Segment`]s and their [`Leg`]s).

use super::*;

/// Build the segments of a plan; `speed0` is the cruise speed at the start.
pub(super) fn segments(
    plan: &Plan,
    k: &KinematicsConfig,
    speed0: f64,
    legs: &mut Vec<Leg>,
) -> Vec<Segment> {
    let mut segs: Vec<Segment> = Vec::new();
    let mut pos = Vector3::zeros();
    let mut yaw = std::f64::consts::FRAC_PI_2; // facing north until the first leg
    let mut speed = speed0;
    let mut airborne = false;
    let pause =
        |segs: &mut Vec<Segment>, at: Vector3<f64>, yaw0: f64, yaw1: f64, d: f64, leg: usize| {
            if d > 0.0 {
                segs.push(Segment {
                    motion: Motion::Hover { at, yaw0, yaw1 },
                    duration_s: d,
                    yaw: yaw1,
                    leg,
                });
            }
        };
    let descend = |segs: &mut Vec<Segment>, pos: &mut Vector3<f64>, yaw: f64, leg: usize| {
        let slow = k.slow_below_m.max(0.0);
        if pos.z > slow {
            let d = (pos.z - slow) / k.descent_m_s;
            segs.push(Segment {
                motion: Motion::Vertical {
                    from: *pos,
                    z1: slow,
                },
                duration_s: d,
                yaw,
                leg,
            });
            pos.z = slow;
        }
        if pos.z > 0.0 {
            let d = pos.z / k.land_m_s;
            segs.push(Segment {
                motion: Motion::Vertical {
                    from: *pos,
                    z1: 0.0,
                },
                duration_s: d,
                yaw,
                leg,
            });
            pos.z = 0.0;
        }
    };
    // Leaving the ground: the motors spin up there first.
    let lift_off =
        |segs: &mut Vec<Segment>, pos: Vector3<f64>, yaw: f64, leg: usize, airborne: &mut bool| {
            if !*airborne && pos.z <= 0.0 {
                pause(segs, pos, yaw, yaw, k.spinup_s, leg);
            }
            *airborne = true;
        };
    let fly_to = |segs: &mut Vec<Segment>,
                  pos: &mut Vector3<f64>,
                  yaw: &mut f64,
                  to: Vector3<f64>,
                  speed: f64,
                  leg: usize|
     -> f64 {
        let dh = (to - *pos).xy();
        let len = dh.norm();
        let heading = if len > 0.5 { dh.y.atan2(dh.x) } else { *yaw };
        // turn toward the leg during the stop before it
        pause(segs, *pos, *yaw, heading, k.waypoint_pause_s, leg);
        let t_h = trapezoid_time(len, speed, k.accel_m_s2);
        let dz = to.z - pos.z;
        let t_v = if dz >= 0.0 {
            dz / k.climb_m_s
        } else {
            -dz / k.descent_m_s
        };
        let d = t_h.max(t_v);
        if d > 0.0 {
            segs.push(Segment {
                motion: Motion::Line {
                    from: *pos,
                    to,
                    v: speed,
                    a: k.accel_m_s2,
                },
                duration_s: d,
                yaw: heading,
                leg,
            });
        }
        *pos = to;
        *yaw = heading;
        len
    };
    for (i, item) in plan.items.iter().enumerate() {
        let target = item.position.map(|p| {
            let (e, n) = enu_of(&plan.home, p.lat_deg, p.lon_deg);
            Vector3::new(e, n, p.alt_m)
        });
        let leg = legs.len();
        let first = segs.len();
        let mut distance_m = 0.0;
        let label: String = match item.kind {
            ItemKind::ChangeSpeed { speed_m_s } => {
                if speed_m_s > 0.0 {
                    speed = speed_m_s;
                }
                continue;
            }
            ItemKind::VtolTransition { .. } => continue,
            ItemKind::Takeoff { alt_m } | ItemKind::VtolTakeoff { alt_m } => {
                if let Some(t) = target {
                    if !airborne {
                        pos = Vector3::new(t.x, t.y, 0.0);
                    }
                }
                lift_off(&mut segs, pos, yaw, leg, &mut airborne);
                if alt_m > pos.z {
                    let d = (alt_m - pos.z) / k.climb_m_s;
                    segs.push(Segment {
                        motion: Motion::Vertical {
                            from: pos,
                            z1: alt_m,
                        },
                        duration_s: d,
                        yaw,
                        leg,
                    });
                    pos.z = alt_m;
                }
                "takeoff".into()
            }
            ItemKind::Waypoint { hold_s } => match target {
                Some(t) => {
                    lift_off(&mut segs, pos, yaw, leg, &mut airborne);
                    distance_m = fly_to(&mut segs, &mut pos, &mut yaw, t, speed, leg);
                    pause(&mut segs, pos, yaw, yaw, hold_s, leg);
                    "waypoint".into()
                }
                None => continue,
            },
            ItemKind::LoiterTime { time_s } => {
                if let Some(t) = target {
                    lift_off(&mut segs, pos, yaw, leg, &mut airborne);
                    distance_m = fly_to(&mut segs, &mut pos, &mut yaw, t, speed, leg);
                }
                pause(&mut segs, pos, yaw, yaw, time_s, leg);
                "loiter".into()
            }
            ItemKind::Land | ItemKind::VtolLand | ItemKind::ReturnToLaunch => {
                let to = match (item.kind, target) {
                    (ItemKind::ReturnToLaunch, _) => Some(Vector3::new(0.0, 0.0, pos.z)),
                    (_, Some(t)) => Some(Vector3::new(t.x, t.y, pos.z)),
                    _ => None,
                };
                if let Some(to) = to {
                    distance_m = fly_to(&mut segs, &mut pos, &mut yaw, to, speed, leg);
                }
                pause(&mut segs, pos, yaw, yaw, k.waypoint_pause_s, leg);
                descend(&mut segs, &mut pos, yaw, leg);
                airborne = false;
                if !matches!(item.kind, ItemKind::ReturnToLaunch) {
                    "land".into()
                } else {
                    "rtl".into()
                }
            }
            // A multirotor flies a loiter of turns, or one for ever, through its position.
            ItemKind::LoiterTurns { .. } | ItemKind::LoiterUnlimited => match target {
                Some(t) => {
                    lift_off(&mut segs, pos, yaw, leg, &mut airborne);
                    distance_m = fly_to(&mut segs, &mut pos, &mut yaw, t, speed, leg);
                    "loiter (flown through)".into()
                }
                None => continue,
            },
            ItemKind::NotModelled {
                command,
                flown_through,
            } => match (flown_through, target) {
                (true, Some(t)) => {
                    lift_off(&mut segs, pos, yaw, leg, &mut airborne);
                    distance_m = fly_to(&mut segs, &mut pos, &mut yaw, t, speed, leg);
                    format!("not modelled {command}")
                }
                _ => continue,
            },
        };
        if segs.len() > first || distance_m > 0.0 {
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
    if pos.z > 0.0 {
        let leg = legs.len();
        pause(&mut segs, pos, yaw, yaw, k.waypoint_pause_s, leg);
        descend(&mut segs, &mut pos, yaw, leg);
        legs.push(Leg {
            item: plan.items.len().saturating_sub(1),
            label: "land (end of plan)".into(),
            t_start_s: 0.0,
            t_end_s: 0.0,
            distance_m: 0.0,
            samples: 0..0,
        });
    }
    segs
}
