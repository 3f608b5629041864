//! The plan model and its readers: QGroundControl `.plan` JSON and `QGC WPL 110`
//! `.waypoints` text.
//!
//! A [`Plan`] is a home position and a list of [`Item`]s in mission order. Every item read
//! is kept, the ones the trajectory model does not model too ([`ItemKind::NotModelled`],
//! listed by [`Plan::not_modelled`]), so nothing is silently dropped.
//!
//! ## Items and what is done with them
//!
//! | MAV_CMD | kind | parameters used |
//! |---|---|---|
//! | 22 NAV_TAKEOFF | [`ItemKind::Takeoff`] | altitude (climbed to vertically; latitude/longitude 0 = here) |
//! | 16 NAV_WAYPOINT, 82 NAV_SPLINE_WAYPOINT | [`ItemKind::Waypoint`] | p1 hold time (s); position (a spline is flown straight) |
//! | 19 NAV_LOITER_TIME | [`ItemKind::LoiterTime`] | p1 time (s), hovered at the position (a plane circles; p3 radius) |
//! | 18 NAV_LOITER_TURNS | [`ItemKind::LoiterTurns`] | p1 turns, p3 radius (m; a plane circles, a multirotor flies through) |
//! | 17 NAV_LOITER_UNLIM | [`ItemKind::LoiterUnlimited`] | position (flown through: no forecast for "forever") |
//! | 84 NAV_VTOL_TAKEOFF | [`ItemKind::VtolTakeoff`] | altitude (a VTOL climbs on its rotors; a multirotor as TAKEOFF) |
//! | 85 NAV_VTOL_LAND | [`ItemKind::VtolLand`] | position (a VTOL lands on its rotors; a multirotor as LAND) |
//! | 3000 DO_VTOL_TRANSITION | [`ItemKind::VtolTransition`] | p1 state (3 MC, 4 FW) |
//! | 178 DO_CHANGE_SPEED | [`ItemKind::ChangeSpeed`] | p2 speed (m/s; −1 or 0 = no change) |
//! | 21 NAV_LAND | [`ItemKind::Land`] | position (fly there, then descend to the ground) |
//! | 20 NAV_RETURN_TO_LAUNCH | [`ItemKind::ReturnToLaunch`] | fly home at the current altitude, then land |
//! | any other MAV_CMD | [`ItemKind::NotModelled`] | a NAV command (id < 100) with a position is flown through as a plain waypoint; others fly nothing |
//!
//! A number that is no MAV_CMD of the ArduPilot dialect at all is an error.
//!
//! ## Altitude frames
//!
//! Altitudes are kept as the trajectory needs them: metres above home.
//! - relative (MAV_FRAME 3 GLOBAL_RELATIVE_ALT, 6 GLOBAL_RELATIVE_ALT_INT): as is;
//! - absolute (0 GLOBAL, 5 GLOBAL_INT, metres above mean sea level): minus the home's AMSL
//!   altitude (a plan without a home altitude cannot use this frame: an error);
//! - terrain (10 GLOBAL_TERRAIN_ALT, 11 GLOBAL_TERRAIN_ALT_INT): read as above home, i.e.
//!   flat terrain at the home's height (there is no terrain model); the item says so in
//!   [`Item::frame`] and the `plan` command lists it;
//! - mission (2): the item has no position (DO_ and CONDITION_ commands).
//!
//! ## Errors
//!
//! A bad plan is a [`PlanError`] naming the file, the item (index, and the line or JSON
//! path) and why: malformed JSON, a missing field, an unknown command, latitude or
//! longitude out of range, a non-finite number, no items at all.
mod formats;

use formats::{build_item, RawItem};
pub use formats::{parse_qgc_plan, parse_waypoints};

use std::path::Path;

/// Where an item came from in its file, for messages: `line 4` or `mission.items[2]`.
pub type ItemOrigin = String;

/// A position: WGS-84 latitude/longitude (deg) and altitude.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct GeoPoint {
    /// Latitude, deg, −90..90.
    pub lat_deg: f64,
    /// Longitude, deg, −180..180.
    pub lon_deg: f64,
    /// Altitude, m: above mean sea level for the home, above home for items.
    pub alt_m: f64,
}

impl GeoPoint {
    /// The point `north_m`, `east_m` from this one, at `alt_m` (flat earth: the crate's one
    /// conversion, [`crate::features::frames::offset_ne`]).
    pub fn offset(&self, north_m: f64, east_m: f64, alt_m: f64) -> GeoPoint {
        use crate::features::frames::offset_ne;
        let (lat_deg, lon_deg) = offset_ne(self.lat_deg, self.lon_deg, north_m, east_m);
        GeoPoint {
            lat_deg,
            lon_deg,
            alt_m,
        }
    }
}

/// How an item's altitude was given (see the module docs for what is done with each).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AltFrame {
    /// Above home.
    Relative,
    /// Above mean sea level (converted to above home on reading).
    Absolute,
    /// Above terrain, read as above home (flat terrain assumed).
    Terrain,
    /// No position (DO_/CONDITION_ commands).
    None,
}

/// What an item makes the vehicle do, as far as energy goes.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum ItemKind {
    /// Climb vertically over the current position (or `position`, when given) to
    /// `alt_m` above home.
    Takeoff { alt_m: f64 },
    /// Fly to `position`, then hover `hold_s`.
    Waypoint { hold_s: f64 },
    /// Fly to `position`, then hover `time_s` (a plane circles).
    LoiterTime { time_s: f64 },
    /// Fly to `position`, then circle `turns` times (a plane; a multirotor flies through).
    LoiterTurns { turns: f64 },
    /// Fly to `position` and circle for ever: flown through (a forecast cannot hold "for ever").
    LoiterUnlimited,
    /// VTOL: climb on the lift rotors to `alt_m` above home (a multirotor: as TAKEOFF).
    VtolTakeoff { alt_m: f64 },
    /// VTOL: fly to `position` (when given), change to hover and land on the rotors (a
    /// multirotor: as LAND).
    VtolLand,
    /// VTOL: change to forward flight (`to_fw`) or to hover.
    VtolTransition { to_fw: bool },
    /// Cruise ground speed from here on, m/s.
    ChangeSpeed { speed_m_s: f64 },
    /// Fly to `position` (when given), descend and land.
    Land,
    /// Fly home at the current altitude, descend and land.
    ReturnToLaunch,
    /// A command the trajectory model does not model; kept and listed. `flown_through`:
    /// its position is flown to like a waypoint's.
    NotModelled { command: u16, flown_through: bool },
}

/// One mission item.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Item {
    /// Index in the plan's item list (0-based, after expanding complex items).
    pub index: usize,
    /// Where it was read: `line N` or a JSON path.
    pub origin: ItemOrigin,
    /// The MAV_CMD number.
    pub command: u16,
    /// What it does.
    #[serde(flatten)]
    pub kind: ItemKind,
    /// Target position, altitude above home (m), when the item has one.
    pub position: Option<GeoPoint>,
    /// How the altitude was given.
    pub frame: AltFrame,
    /// A loiter's radius (NAV_LOITER_* param3, m, unsigned), when it gives one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub loiter_radius_m: Option<f64>,
}

/// A mission plan: home, items, default speeds.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Plan {
    /// Where it was read from (for messages).
    pub source: String,
    /// Home (take-off and return point), altitude above mean sea level (m; 0 when the
    /// file gives none).
    pub home: GeoPoint,
    /// Items in mission order.
    pub items: Vec<Item>,
    /// Default cruise ground speed for multirotors, m/s (QGC `hoverSpeed`), when given.
    pub hover_speed_m_s: Option<f64>,
    /// Default cruise speed for fixed-wing (QGC `cruiseSpeed`), m/s, when given; kept for
    /// the record, a multirotor flies `hover_speed_m_s`.
    pub cruise_speed_m_s: Option<f64>,
}

/// A plan that cannot be read: the file, the item and why.
#[derive(Debug, thiserror::Error)]
#[error("{file}: {at}: {why}")]
pub struct PlanError {
    /// The file.
    pub file: String,
    /// The item: `item 3 (line 5)`, `mission.items[2]`, or `file` for the whole.
    pub at: String,
    /// Why.
    pub why: String,
}

impl Plan {
    /// Read a plan file, by content: `QGC WPL 110` text, else QGroundControl JSON.
    pub fn load(path: &Path) -> Result<Plan, PlanError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| PlanError {
            file: file.clone(),
            at: "file".into(),
            why: format!("cannot read: {e}"),
        })?;
        if text.trim_start().starts_with("QGC WPL") {
            parse_waypoints(&text, &file)
        } else {
            parse_qgc_plan(&text, &file)
        }
    }

    /// Items the trajectory model does not model, for listing.
    pub fn not_modelled(&self) -> Vec<&Item> {
        self.items
            .iter()
            .filter(|i| matches!(i.kind, ItemKind::NotModelled { .. }))
            .collect()
    }

    /// Items whose altitude was given above terrain (flown as above home).
    pub fn terrain_items(&self) -> Vec<&Item> {
        self.items
            .iter()
            .filter(|i| i.frame == AltFrame::Terrain)
            .collect()
    }

    /// A plan from a home and waypoints (altitudes above home), flown at `speed_m_s`:
    /// take-off to the first waypoint's altitude, the waypoints, return to launch. What
    /// the evaluation builds from the data set's routes, and what tests and benches fly.
    pub fn from_waypoints(
        source: &str,
        home: GeoPoint,
        waypoints: &[GeoPoint],
        speed_m_s: f64,
    ) -> Plan {
        let mut items = Vec::with_capacity(waypoints.len() + 3);
        let mut push = |command: u16, kind: ItemKind, position: Option<GeoPoint>| {
            let index = items.len();
            let frame = if position.is_some() {
                AltFrame::Relative
            } else {
                AltFrame::None
            };
            items.push(Item {
                index,
                origin: format!("waypoint {index}"),
                command,
                kind,
                position,
                frame,
                loiter_radius_m: None,
            });
        };
        push(178, ItemKind::ChangeSpeed { speed_m_s }, None);
        let first_alt = waypoints.first().map_or(25.0, |w| w.alt_m);
        push(22, ItemKind::Takeoff { alt_m: first_alt }, None);
        for w in waypoints {
            push(16, ItemKind::Waypoint { hold_s: 0.0 }, Some(*w));
        }
        push(20, ItemKind::ReturnToLaunch, None);
        Plan {
            source: source.to_string(),
            home,
            items,
            hover_speed_m_s: Some(speed_m_s),
            cruise_speed_m_s: None,
        }
    }
}

impl Plan {
    /// A plan from a mission list the protocol carried ([`super::protocol`]). ArduPilot's
    /// item 0 is home (its altitude AMSL, which absolute frames are taken against); else
    /// `home` (HOME_POSITION, or where the vehicle was first heard) is home, and absolute
    /// altitudes need its AMSL altitude. A mission that does not end by landing (its last
    /// NAV item no LAND or RETURN_TO_LAUNCH) gets a RETURN_TO_LAUNCH appended (origin
    /// `added: return and land`): the forecast is of the mission *and* the way home.
    /// Plan item `i` is mission `seq` `i + seq_offset` (1 with a home item, else 0).
    pub fn from_mission(
        source: &str,
        m: &super::protocol::Mission,
        home: Option<GeoPoint>,
    ) -> Result<(Plan, u16), PlanError> {
        let err = |at: String, why: String| PlanError {
            file: source.to_string(),
            at,
            why,
        };
        let (home, rest, seq_offset) = match (m.home_is_item0, m.items.split_first()) {
            (true, Some((h, rest))) => {
                if !h.lat_deg.is_finite()
                    || !h.lon_deg.is_finite()
                    || !h.alt_m.is_finite()
                    || !(-90.0..=90.0).contains(&h.lat_deg)
                    || !(-180.0..=180.0).contains(&h.lon_deg)
                {
                    return Err(err(
                        "item 0 (seq 0, home)".into(),
                        format!(
                            "home position ({}, {}, {}) is not a valid position",
                            h.lat_deg, h.lon_deg, h.alt_m
                        ),
                    ));
                }
                (
                    GeoPoint {
                        lat_deg: h.lat_deg,
                        lon_deg: h.lon_deg,
                        alt_m: h.alt_m,
                    },
                    rest,
                    1u16,
                )
            }
            _ => (
                home.ok_or_else(|| {
                    err(
                        "file".into(),
                        "no home: no home item, HOME_POSITION or vehicle position heard".into(),
                    )
                })?,
                &m.items[..],
                0u16,
            ),
        };
        let mut items = Vec::with_capacity(rest.len() + 1);
        for it in rest {
            let raw = RawItem {
                command: it.command,
                frame: it.frame,
                params: it.params,
                lat: it.lat_deg,
                lon: it.lon_deg,
                alt: it.alt_m,
            };
            let origin = format!("seq {}", it.seq);
            let built = build_item(&raw, items.len(), origin.clone(), Some(home.alt_m))
                .map_err(|why| err(format!("item {} ({origin})", items.len()), why))?;
            items.push(built);
        }
        if items.is_empty() {
            return Err(err("file".into(), "the mission has no items".into()));
        }
        let lands = items
            .iter()
            .rev()
            .find(|i| i.command < 100)
            .is_some_and(|i| matches!(i.kind, ItemKind::Land | ItemKind::ReturnToLaunch));
        if !lands {
            let index = items.len();
            items.push(Item {
                index,
                origin: "added: return and land".into(),
                command: 20,
                kind: ItemKind::ReturnToLaunch,
                position: None,
                frame: AltFrame::None,
                loiter_radius_m: None,
            });
        }
        Ok((
            Plan {
                source: source.to_string(),
                home,
                items,
                hover_speed_m_s: None,
                cruise_speed_m_s: None,
            },
            seq_offset,
        ))
    }
}

impl Plan {
    /// The plan as ArduPilot holds it, for the protocol (what the simulator logs): item 0
    /// home (absolute altitude, frame 0), then every item in the relative frame (3) with
    /// the parameters the trajectory reads (hold/loiter time p1, speed p2, take-off
    /// altitude); items with no position in the mission frame (2).
    pub fn to_mission_items(&self) -> Vec<super::protocol::MissionItem> {
        use super::protocol::MissionItem;
        let mut out = vec![MissionItem {
            seq: 0,
            frame: 0,
            command: 16,
            params: [0.0; 4],
            lat_deg: self.home.lat_deg,
            lon_deg: self.home.lon_deg,
            alt_m: self.home.alt_m,
        }];
        for it in &self.items {
            let mut params = [0.0; 4];
            let mut alt = it.position.map_or(0.0, |p| p.alt_m);
            match it.kind {
                ItemKind::Waypoint { hold_s } => params[0] = hold_s,
                ItemKind::LoiterTime { time_s } => params[0] = time_s,
                ItemKind::LoiterTurns { turns } => params[0] = turns,
                ItemKind::ChangeSpeed { speed_m_s } => params[1] = speed_m_s,
                ItemKind::Takeoff { alt_m } | ItemKind::VtolTakeoff { alt_m } => alt = alt_m,
                ItemKind::VtolTransition { to_fw } => params[0] = if to_fw { 4.0 } else { 3.0 },
                _ => {}
            }
            params[2] = it.loiter_radius_m.unwrap_or(params[2]);
            let positioned = it.command < 100 && it.command != 20;
            let (lat, lon) = it.position.map_or((0.0, 0.0), |p| (p.lat_deg, p.lon_deg));
            out.push(MissionItem {
                seq: u16::try_from(out.len()).unwrap_or(u16::MAX),
                frame: if positioned { 3 } else { 2 },
                command: u32::from(it.command),
                params,
                lat_deg: lat,
                lon_deg: lon,
                alt_m: alt,
            });
        }
        out
    }

    /// The same plan moved to another home: every position keeps its east/north offset
    /// from home (flat earth, as the trajectory flies it).
    pub fn relocated(&self, home: GeoPoint) -> Plan {
        use crate::features::frames::ne_offset_m;
        let mut p = self.clone();
        for it in &mut p.items {
            if let Some(pos) = &mut it.position {
                let (n, e) = ne_offset_m(
                    self.home.lat_deg,
                    self.home.lon_deg,
                    pos.lat_deg,
                    pos.lon_deg,
                );
                *pos = home.offset(n, e, pos.alt_m);
            }
        }
        p.home = home;
        p
    }
}

#[cfg(test)]
mod tests;
