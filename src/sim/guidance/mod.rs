//! Waypoint guidance: a [`Route`] (take-off, waypoints, landing) flown as a sequence of
//! [`Phase`]s, each step giving the velocity a multirotor's position controller commands.
//!
//! Why here: the simulator flies it, and a mission forecast can fly the same route with
//! the same braking and holds, so the two cannot disagree on what "the mission" is.
//!
//! ## The flight
//! `PreArm` (5 s on the ground, disarmed) → `Spinup` (3 s armed, props idling) → `Climb`
//! (vertically above home to the take-off altitude at up to `climb_mps`) → for each waypoint
//! `Leg(i)` (toward it at its `speed_mps` horizontally and [`LEG_CLIMB_MPS`] vertically;
//! reached within [`ARRIVAL_M`]) and, when it has a hold time or is the last one, `Hold(i)`
//! (station-keeping for `hold_s`) → `Descent` (vertically at `descent_mps`, [`LAND_MPS`]
//! below [`FLARE_M`]) → `Landed` (3 s armed) → `Done` (3 s disarmed) → finished.
//!
//! ## Frames and units
//! Positions are NED metres relative to home (x north, y east, z down); altitudes in a
//! [`Waypoint`] are metres above home, positive up. [`Home`] converts latitude/longitude to
//! and from that frame on a local spherical-earth tangent plane (errors are millimetres
//! over a few km).
//!
//! ## The guidance law
//! [`toward`]: the desired velocity points at the target, at the commanded speed, braking
//! as `√(2·a_brake·d)` near it (and never more than `2·K_v·d`, so the velocity loop
//! settles instead of overshooting). The position controller then commands the
//! acceleration `K_v·(v_des − v)` ([`VELOCITY_GAIN_PER_S`]).

use nalgebra::Vector3;

/// Velocity-loop gain K_v, 1/s: commanded acceleration per m/s of velocity error.
pub const VELOCITY_GAIN_PER_S: f64 = 1.2;
/// Braking deceleration the desired velocity allows near a target, m/s².
pub const BRAKE_MPS2: f64 = 1.5;
/// Vertical speed limit on legs and holds, m/s.
pub const LEG_CLIMB_MPS: f64 = 2.5;
/// Distance at which a waypoint counts as reached, m.
pub const ARRIVAL_M: f64 = 1.5;
/// Height below which the descent slows to [`LAND_MPS`], m.
pub const FLARE_M: f64 = 3.0;
/// Final descent speed, m/s.
pub const LAND_MPS: f64 = 0.5;
/// Time on the ground disarmed before arming, s.
pub const PREARM_S: f64 = 5.0;
/// Time armed with props idling before the climb, s.
pub const SPINUP_S: f64 = 3.0;
/// Time armed on the ground after touch-down, s.
pub const LANDED_S: f64 = 3.0;
/// Time disarmed after the flight before the route ends, s.
pub const DONE_S: f64 = 3.0;

/// Mission phases.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// On the ground, disarmed, before take-off.
    PreArm,
    /// Armed, props spinning on the ground.
    Spinup,
    /// Vertical climb to the take-off altitude.
    Climb,
    /// Flying toward waypoint `i`.
    Leg(usize),
    /// Holding over waypoint `i`.
    Hold(usize),
    /// Descending and landing.
    Descent,
    /// Landed, about to disarm.
    Landed,
    /// Disarmed after the flight.
    Done,
}

impl Phase {
    /// Motors armed.
    pub fn armed(self) -> bool {
        !matches!(self, Phase::PreArm | Phase::Done)
    }
    /// Off the ground.
    pub fn in_air(self) -> bool {
        matches!(
            self,
            Phase::Climb | Phase::Leg(_) | Phase::Hold(_) | Phase::Descent
        )
    }
}

/// One waypoint, in metres relative to home.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Waypoint {
    /// North of home, m.
    pub north_m: f64,
    /// East of home, m.
    pub east_m: f64,
    /// Altitude above home, m (positive up).
    pub alt_m: f64,
    /// Horizontal ground speed on the leg to this waypoint, m/s.
    pub speed_mps: f64,
    /// Time to hold over it once reached, s.
    pub hold_s: f64,
}

impl Waypoint {
    /// NED position, m.
    pub fn ned(&self) -> Vector3<f64> {
        Vector3::new(self.north_m, self.east_m, -self.alt_m)
    }
}

/// Where home is: the origin of the NED frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Home {
    /// Latitude, deg.
    pub lat_deg: f64,
    /// Longitude, deg.
    pub lon_deg: f64,
    /// Altitude above mean sea level, m.
    pub alt_amsl_m: f64,
}

impl Home {
    /// NED offset from home (m) → latitude, longitude (deg), altitude above sea level (m).
    pub fn to_geodetic(&self, ned: &Vector3<f64>) -> (f64, f64, f64) {
        let (lat, lon) =
            crate::features::frames::offset_ne(self.lat_deg, self.lon_deg, ned.x, ned.y);
        (lat, lon, self.alt_amsl_m - ned.z)
    }

    /// A waypoint at a latitude/longitude (deg) and `alt_m` above home.
    pub fn waypoint(
        &self,
        lat_deg: f64,
        lon_deg: f64,
        alt_m: f64,
        speed_mps: f64,
        hold_s: f64,
    ) -> Waypoint {
        let (north_m, east_m) =
            crate::features::frames::ne_offset_m(self.lat_deg, self.lon_deg, lat_deg, lon_deg);
        Waypoint {
            north_m,
            east_m,
            alt_m,
            speed_mps,
            hold_s,
        }
    }
}

/// What to fly: take off above home, visit the waypoints in order, land below the last.
#[derive(Debug, Clone, PartialEq)]
pub struct Route {
    /// Take-off altitude above home, m.
    pub takeoff_alt_m: f64,
    /// Climb rate of the take-off, m/s.
    pub climb_mps: f64,
    /// The waypoints, at least one.
    pub waypoints: Vec<Waypoint>,
    /// Descent rate above [`FLARE_M`], m/s.
    pub descent_mps: f64,
}

/// A route option that is out of range: `key` names it, `reason` says why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{key} {reason}")]
pub struct InvalidOption {
    /// The option, as the struct names it (`speed_mps`, `waypoints[2].hold_s`).
    pub key: String,
    /// What is wrong, with the value.
    pub reason: String,
}

/// Check `lo ≤ v ≤ hi` (or `lo < v` with `open_lo`), naming `key`.
pub(crate) fn in_range(
    key: &str,
    v: f64,
    lo: f64,
    hi: f64,
    open_lo: bool,
) -> Result<(), InvalidOption> {
    use std::ops::Bound::{Excluded, Included};
    let start = if open_lo { Excluded(lo) } else { Included(lo) };
    match crate::validate::violation(v, &(start, Included(hi)), "") {
        None => Ok(()),
        Some(why) => Err(InvalidOption {
            key: key.into(),
            reason: format!("= {v}: {why}"),
        }),
    }
}

/// Speed limits every leg obeys, m/s: above a walking pace, below what small multirotors fly.
pub const SPEED_RANGE_MPS: (f64, f64) = (0.5, 20.0);
/// Altitude limits above home, m.
pub const ALT_RANGE_M: (f64, f64) = (2.0, 500.0);
/// Longest hold, s.
pub const MAX_HOLD_S: f64 = 3600.0;

/// The triangle the simulator flies by default: legs of `leg_m` north, then south-east,
/// then back home, at `altitude_m` and `speed_mps`, holding `hover_s` over home.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Triangle {
    /// Side, m.
    pub leg_m: f64,
    /// Altitude above home, m.
    pub altitude_m: f64,
    /// Ground speed on every leg, m/s.
    pub speed_mps: f64,
    /// Hold over home at the end (the delivery), s.
    pub hover_s: f64,
}

impl Triangle {
    /// Range checks; the error names the field.
    pub fn validate(&self) -> Result<(), InvalidOption> {
        in_range(
            "speed_mps",
            self.speed_mps,
            SPEED_RANGE_MPS.0,
            SPEED_RANGE_MPS.1,
            true,
        )?;
        in_range(
            "altitude_m",
            self.altitude_m,
            ALT_RANGE_M.0,
            ALT_RANGE_M.1,
            false,
        )?;
        in_range("leg_m", self.leg_m, 10.0, 5000.0, false)?;
        in_range("hover_s", self.hover_s, 0.0, MAX_HOLD_S, false)
    }

    /// The triangle as a route: climb at 2.5 m/s, descend at 1.5 m/s.
    pub fn route(&self) -> Route {
        let (l, alt, v) = (self.leg_m, self.altitude_m, self.speed_mps);
        let wp = |north_m, east_m, hold_s| Waypoint {
            north_m,
            east_m,
            alt_m: alt,
            speed_mps: v,
            hold_s,
        };
        Route {
            takeoff_alt_m: alt,
            climb_mps: 2.5,
            waypoints: vec![
                wp(l, 0.0, 0.0),
                wp(l / 2.0, l * 3f64.sqrt() / 2.0, 0.0),
                wp(0.0, 0.0, self.hover_s),
            ],
            descent_mps: 1.5,
        }
    }
}

impl Route {
    /// Range checks; the error names the field (`waypoints[i].speed_mps`).
    pub fn validate(&self) -> Result<(), InvalidOption> {
        in_range(
            "takeoff_alt_m",
            self.takeoff_alt_m,
            ALT_RANGE_M.0,
            ALT_RANGE_M.1,
            false,
        )?;
        in_range("climb_mps", self.climb_mps, 0.1, 10.0, false)?;
        in_range("descent_mps", self.descent_mps, 0.1, 10.0, false)?;
        if self.waypoints.is_empty() {
            return Err(InvalidOption {
                key: "waypoints".into(),
                reason: "is empty: a route needs at least one".into(),
            });
        }
        for (i, w) in self.waypoints.iter().enumerate() {
            let k = |f: &str| format!("waypoints[{i}].{f}");
            in_range(
                &k("speed_mps"),
                w.speed_mps,
                SPEED_RANGE_MPS.0,
                SPEED_RANGE_MPS.1,
                true,
            )?;
            in_range(&k("alt_m"), w.alt_m, ALT_RANGE_M.0, ALT_RANGE_M.1, false)?;
            in_range(&k("hold_s"), w.hold_s, 0.0, MAX_HOLD_S, false)?;
            in_range(&k("north_m"), w.north_m, -1e5, 1e5, false)?;
            in_range(&k("east_m"), w.east_m, -1e5, 1e5, false)?;
        }
        Ok(())
    }

    /// The commanded ground speed (m/s) and altitude above home (m) in `phase`: the
    /// current leg's, the first leg's before it, the last leg's after.
    pub fn commanded(&self, phase: Phase) -> (f64, f64) {
        let last = self.waypoints.len().saturating_sub(1);
        let i = match phase {
            Phase::Leg(i) | Phase::Hold(i) => i.min(last),
            Phase::PreArm | Phase::Spinup | Phase::Climb => 0,
            Phase::Descent | Phase::Landed | Phase::Done => last,
        };
        let w = &self.waypoints[i];
        let alt = if matches!(phase, Phase::PreArm | Phase::Spinup | Phase::Climb) {
            self.takeoff_alt_m
        } else {
            w.alt_m
        };
        (w.speed_mps, alt)
    }
}

/// A [`Route`] flown from a mission plan, and which plan item each waypoint serves.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanRoute {
    pub route: Route,
    /// Plan item index per waypoint.
    pub waypoint_items: Vec<usize>,
    /// Plan item of the take-off (the first item before the first waypoint's).
    pub takeoff_item: usize,
    /// Plan item that ends the flight (LAND, RETURN_TO_LAUNCH, else the last).
    pub end_item: usize,
}

impl Route {
    /// A plan as the simulator flies it: take-off to the TAKEOFF item's altitude (else the
    /// first waypoint's), every positioned item (waypoints, loiters, NAV commands it does
    /// not model) as a waypoint at the speed then in force (`speed_mps` until a
    /// DO_CHANGE_SPEED; the plan's `hoverSpeed` wins over it), hold and loiter times as
    /// holds; LAND lands at its position (or where it is), RETURN_TO_LAUNCH flies home at
    /// the altitude it is at and lands. Positions are NED from the plan's home.
    pub fn from_plan(
        plan: &crate::mission::plan::Plan,
        speed_mps: f64,
    ) -> Result<PlanRoute, InvalidOption> {
        use crate::mission::plan::ItemKind as K;
        let mut speed = plan.hover_speed_m_s.unwrap_or(speed_mps);
        let mut waypoints: Vec<Waypoint> = Vec::new();
        let mut waypoint_items = Vec::new();
        let mut takeoff: Option<(usize, f64)> = None;
        let mut end_item = plan.items.len().saturating_sub(1);
        let ned = |p: &crate::mission::plan::GeoPoint| {
            crate::mission::trajectory::enu_of(&plan.home, p.lat_deg, p.lon_deg)
        };
        for it in &plan.items {
            let hold_s = match it.kind {
                K::ChangeSpeed { speed_m_s } => {
                    if speed_m_s > 0.0 {
                        speed = speed_m_s;
                    }
                    continue;
                }
                K::Takeoff { alt_m } | K::VtolTakeoff { alt_m } => {
                    takeoff.get_or_insert((it.index, alt_m));
                    continue;
                }
                K::Waypoint { hold_s } => hold_s,
                K::LoiterTime { time_s } => time_s,
                K::LoiterTurns { .. } | K::LoiterUnlimited => 0.0,
                K::NotModelled { flown_through, .. } if flown_through => 0.0,
                K::NotModelled { .. } | K::VtolTransition { .. } => continue,
                K::Land | K::VtolLand | K::ReturnToLaunch => {
                    // The flight ends here: LAND at its position (or where it is), RETURN_TO_LAUNCH
                    // over home at the altitude it is at.
                    let last_alt = waypoints.last().map(|w| w.alt_m);
                    let end = match (matches!(it.kind, K::Land | K::VtolLand), &it.position) {
                        (true, Some(p)) => {
                            let (e, n) = ned(p);
                            Some((n, e, last_alt.unwrap_or(p.alt_m)))
                        }
                        (true, None) => None,
                        (false, _) => Some((
                            0.0,
                            0.0,
                            last_alt.unwrap_or(takeoff.map_or(ALT_RANGE_M.0, |t| t.1)),
                        )),
                    };
                    if let Some((north_m, east_m, alt_m)) = end {
                        waypoints.push(Waypoint {
                            north_m,
                            east_m,
                            alt_m,
                            speed_mps: speed,
                            hold_s: 0.0,
                        });
                        waypoint_items.push(it.index);
                    }
                    end_item = it.index;
                    break;
                }
            };
            let Some(p) = &it.position else { continue };
            let (e, n) = ned(p);
            waypoints.push(Waypoint {
                north_m: n,
                east_m: e,
                alt_m: p.alt_m,
                speed_mps: speed,
                hold_s,
            });
            waypoint_items.push(it.index);
        }
        let first_alt = waypoints.first().map_or(ALT_RANGE_M.0, |w| w.alt_m);
        let route = Route {
            takeoff_alt_m: takeoff.map_or(first_alt, |t| t.1),
            climb_mps: 2.5,
            waypoints,
            descent_mps: 1.5,
        };
        route.validate()?;
        Ok(PlanRoute {
            route,
            takeoff_item: takeoff.map_or(0, |t| t.0),
            waypoint_items,
            end_item,
        })
    }
}

/// What the guidance asks for in one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Command {
    /// The phase after this step's transition.
    pub phase: Phase,
    /// Desired velocity, NED m/s (in the air), computed in the phase the step began in.
    pub velocity_ned: Option<Vector3<f64>>,
    /// The vehicle touched down this step: set its height to zero.
    pub touchdown: bool,
    /// The route is over.
    pub finished: bool,
}

/// Flies a [`Route`] step by step.
#[derive(Debug, Clone)]
pub struct Guidance {
    route: Route,
    phase: Phase,
    phase_t_s: f64,
}

impl Guidance {
    /// Start on the ground, disarmed. The route should have passed [`Route::validate`].
    pub fn new(route: Route) -> Self {
        Self {
            route,
            phase: Phase::PreArm,
            phase_t_s: 0.0,
        }
    }

    /// The route flown.
    pub fn route(&self) -> &Route {
        &self.route
    }

    /// The current phase.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// Advance by `dt_s` from position `pos` and velocity `vel` (NED, m and m/s).
    pub fn step(&mut self, pos: &Vector3<f64>, vel: &Vector3<f64>, dt_s: f64) -> Command {
        let r = &self.route;
        let t = self.phase_t_s;
        let last = r.waypoints.len() - 1;
        let stops_at = |i: usize| r.waypoints[i].hold_s > 0.0 || i == last;
        let mut v_des = None;
        let mut next = None;
        let mut touchdown = false;
        match self.phase {
            Phase::PreArm if t >= PREARM_S => next = Some(Phase::Spinup),
            Phase::Spinup if t >= SPINUP_S => next = Some(Phase::Climb),
            Phase::Climb => {
                let h = -r.takeoff_alt_m;
                v_des = Some(toward(
                    pos,
                    &Vector3::new(0.0, 0.0, h),
                    r.waypoints[0].speed_mps,
                    r.climb_mps,
                ));
                if (pos.z - h).abs() < 0.3 && vel.norm() < 0.3 {
                    next = Some(Phase::Leg(0));
                }
            }
            Phase::Leg(i) => {
                let w = &r.waypoints[i];
                let target = w.ned();
                v_des = Some(toward(pos, &target, w.speed_mps, LEG_CLIMB_MPS));
                if (target - pos).norm() < ARRIVAL_M {
                    next = Some(if stops_at(i) {
                        Phase::Hold(i)
                    } else {
                        Phase::Leg(i + 1)
                    });
                }
            }
            Phase::Hold(i) => {
                let w = &r.waypoints[i];
                v_des = Some(toward(pos, &w.ned(), w.speed_mps, LEG_CLIMB_MPS));
                if t >= w.hold_s {
                    next = Some(if i < last {
                        Phase::Leg(i + 1)
                    } else {
                        Phase::Descent
                    });
                }
            }
            Phase::Descent => {
                let w = &r.waypoints[last];
                let height = -pos.z;
                // Below the flare height, aim 1 m under the ground so touch-down happens at LAND_MPS.
                let (rate, z) = if height > FLARE_M {
                    (r.descent_mps, 0.0)
                } else {
                    (LAND_MPS, 1.0)
                };
                v_des = Some(toward(
                    pos,
                    &Vector3::new(w.north_m, w.east_m, z),
                    w.speed_mps,
                    rate,
                ));
                if height <= 0.02 {
                    touchdown = true;
                    next = Some(Phase::Landed);
                }
            }
            Phase::Landed if t >= LANDED_S => next = Some(Phase::Done),
            Phase::Done if t >= DONE_S => {
                return Command {
                    phase: Phase::Done,
                    velocity_ned: None,
                    touchdown: false,
                    finished: true,
                };
            }
            _ => {}
        }
        if let Some(p) = next {
            self.phase = p;
            self.phase_t_s = 0.0;
        }
        self.phase_t_s += dt_s;
        Command {
            phase: self.phase,
            velocity_ned: v_des,
            touchdown,
            finished: false,
        }
    }
}

/// Desired velocity toward `target`: horizontal speed up to `speed`, vertical up to
/// `vz_max`, each braking as √(2·a_brake·d) near the target.
pub fn toward(pos: &Vector3<f64>, target: &Vector3<f64>, speed: f64, vz_max: f64) -> Vector3<f64> {
    let d = target - pos;
    let dh = (d.x * d.x + d.y * d.y).sqrt();
    let mut v = Vector3::zeros();
    if dh > 1e-6 {
        let s = speed
            .min((2.0 * BRAKE_MPS2 * dh).sqrt())
            .min(dh * VELOCITY_GAIN_PER_S * 2.0);
        v.x = d.x / dh * s;
        v.y = d.y / dh * s;
    }
    let vz = vz_max
        .min((2.0 * BRAKE_MPS2 * d.z.abs()).sqrt())
        .min(d.z.abs() * 2.0);
    v.z = vz * d.z.signum();
    v
}

#[cfg(test)]
mod tests;
