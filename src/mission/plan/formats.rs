//! The two plan files read: QGroundControl's `.plan` (JSON) and `QGC WPL 110` text, each
//! item checked as it is turned into an [`Item`].

use crate::mission::plan::AltFrame;
use crate::mission::plan::GeoPoint;
use crate::mission::plan::Item;
use crate::mission::plan::ItemKind;
use crate::mission::plan::ItemOrigin;
use crate::mission::plan::Plan;
use crate::mission::plan::PlanError;

/// Is `command` a MAV_CMD of the ArduPilot dialect (which includes common)?
fn is_mav_cmd(command: u32) -> bool {
    <crate::dialect::MavCmd as num_traits::FromPrimitive>::from_u32(command).is_some()
}

/// One raw item as both formats give it: command, frame, p1..p4, lat, lon, alt.
pub(crate) struct RawItem {
    pub(super) command: u32,
    pub(super) frame: u32,
    pub(super) params: [f64; 4],
    pub(super) lat: f64,
    pub(super) lon: f64,
    pub(super) alt: f64,
}

/// Turn a raw item into an [`Item`], checking it. `home_amsl` converts absolute altitudes.
pub(crate) fn build_item(
    raw: &RawItem,
    index: usize,
    origin: ItemOrigin,
    home_amsl: Option<f64>,
) -> Result<Item, String> {
    if !is_mav_cmd(raw.command) {
        return Err(format!("command {} is not a MAV_CMD", raw.command));
    }
    let command = u16::try_from(raw.command)
        .map_err(|_| format!("command {} is out of range", raw.command))?;
    let p = raw.params;
    let mut kind = item_kind(command, &p)?;
    // Does this item carry a position? NAV commands (< 100) do, except RTL. TAKEOFF and
    // LAND may leave latitude/longitude 0 or unset: "here".
    let nav = command < 100 && command != 20;
    let here_ok = matches!(
        kind,
        ItemKind::Takeoff { .. }
            | ItemKind::Land
            | ItemKind::VtolTakeoff { .. }
            | ItemKind::VtolLand
    );
    // A loiter's radius (param3; its sign is the direction), when it gives one.
    let loiter_radius_m = match command {
        17..=19 if p[2].is_finite() && p[2] != 0.0 => Some(p[2].abs()),
        _ => None,
    };
    let mut frame = AltFrame::None;
    let mut position = None;
    if nav {
        let alt_above_home;
        (frame, alt_above_home) = altitude(raw, home_amsl)?;
        position = item_position(raw, here_ok, alt_above_home)?;
        match kind {
            ItemKind::Takeoff { .. } => {
                kind = ItemKind::Takeoff {
                    alt_m: alt_above_home,
                }
            }
            ItemKind::VtolTakeoff { .. } => {
                kind = ItemKind::VtolTakeoff {
                    alt_m: alt_above_home,
                }
            }
            _ => {}
        }
    }
    if let ItemKind::NotModelled { command, .. } = kind {
        kind = ItemKind::NotModelled {
            command,
            flown_through: position.is_some(),
        };
    }
    Ok(Item {
        index,
        origin,
        command,
        kind,
        position,
        frame,
        loiter_radius_m,
    })
}

/// What a MAV_CMD does, from its parameters p1..p4, checked (a take-off's altitude is
/// filled in from its position later).
fn item_kind(command: u16, p: &[f64; 4]) -> Result<ItemKind, String> {
    let nonneg = |name: &str, v: f64| -> Result<f64, String> {
        if v.is_nan() {
            return Ok(0.0); // QGC writes null (NaN) for "unused"
        }
        if !v.is_finite() || v < 0.0 {
            return Err(format!("{name} = {v}: must be a finite number ≥ 0"));
        }
        Ok(v)
    };
    Ok(match command {
        22 => ItemKind::Takeoff { alt_m: 0.0 },
        16 | 82 => ItemKind::Waypoint {
            hold_s: nonneg("hold time (param1)", p[0])?,
        },
        19 => ItemKind::LoiterTime {
            time_s: nonneg("loiter time (param1)", p[0])?,
        },
        18 => ItemKind::LoiterTurns {
            turns: nonneg("turns (param1)", p[0])?,
        },
        17 => ItemKind::LoiterUnlimited,
        84 => ItemKind::VtolTakeoff { alt_m: 0.0 },
        85 => ItemKind::VtolLand,
        3000 => ItemKind::VtolTransition {
            to_fw: match p[0] {
                4.0 => true,
                3.0 => false,
                s => {
                    return Err(format!(
                    "state (param1) = {s}: must be 3 (MAV_VTOL_STATE_MC) or 4 (MAV_VTOL_STATE_FW)"
                ))
                }
            },
        },
        178 => {
            if !p[1].is_finite() {
                return Err(format!("speed (param2) = {}: must be a number", p[1]));
            }
            ItemKind::ChangeSpeed { speed_m_s: p[1] }
        }
        21 => ItemKind::Land,
        20 => ItemKind::ReturnToLaunch,
        c => ItemKind::NotModelled {
            command: c,
            flown_through: false,
        },
    })
}

/// A NAV item's altitude frame and its altitude above home (an absolute one converted with
/// `home_amsl`).
fn altitude(raw: &RawItem, home_amsl: Option<f64>) -> Result<(AltFrame, f64), String> {
    if !raw.alt.is_finite() {
        return Err(format!("altitude {} is not finite", raw.alt));
    }
    match raw.frame {
        3 | 6 => Ok((AltFrame::Relative, raw.alt)),
        0 | 5 => {
            let h = home_amsl.ok_or(
                "an absolute (AMSL) altitude needs a home altitude, and the plan gives none",
            )?;
            Ok((AltFrame::Absolute, raw.alt - h))
        }
        10 | 11 => Ok((AltFrame::Terrain, raw.alt)),
        f => Err(format!(
            "frame {f} is not a global frame (0, 3, 5, 6, 10, 11)"
        )),
    }
}

/// A NAV item's position, checked; none for a take-off or landing "here" (latitude and
/// longitude 0 or unset) when `here_ok`.
fn item_position(raw: &RawItem, here_ok: bool, alt_m: f64) -> Result<Option<GeoPoint>, String> {
    let here = (raw.lat == 0.0 && raw.lon == 0.0) || (raw.lat.is_nan() && raw.lon.is_nan());
    if here && here_ok {
        return Ok(None);
    }
    if !raw.lat.is_finite() || !raw.lon.is_finite() {
        return Err(format!("position ({}, {}) is not finite", raw.lat, raw.lon));
    }
    if here {
        return Err("latitude and longitude are both 0: no position".to_string());
    }
    if !(-90.0..=90.0).contains(&raw.lat) {
        return Err(format!("latitude {} is out of range [-90, 90]", raw.lat));
    }
    if !(-180.0..=180.0).contains(&raw.lon) {
        return Err(format!("longitude {} is out of range [-180, 180]", raw.lon));
    }
    Ok(Some(GeoPoint {
        lat_deg: raw.lat,
        lon_deg: raw.lon,
        alt_m,
    }))
}

/// Parse `QGC WPL 110` text: a header line, then one tab-separated row per item: index,
/// current, frame, command, p1, p2, p3, p4, lat, lon, alt, autocontinue. Row 0 is home
/// (ArduPilot's convention; its altitude is AMSL).
pub fn parse_waypoints(text: &str, file: &str) -> Result<Plan, PlanError> {
    let err = |at: String, why: String| PlanError {
        file: file.to_string(),
        at,
        why,
    };
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    match lines.next() {
        Some((_, h)) if h.trim().starts_with("QGC WPL 110") => {}
        Some((_, h)) => {
            return Err(err(
                "line 1".into(),
                format!("header {:?}: expected \"QGC WPL 110\"", h.trim()),
            ))
        }
        None => {
            return Err(err(
                "file".into(),
                "empty file: no header and no items".into(),
            ))
        }
    }
    let mut rows = Vec::new();
    for (n, line) in lines {
        let lineno = n + 1;
        let cols: Vec<&str> = line.split('\t').map(str::trim).collect();
        if cols.len() < 12 {
            return Err(err(format!("line {lineno}"), format!("{} tab-separated columns: expected 12 (index, current, frame, command, p1..p4, lat, lon, alt, autocontinue)", cols.len())));
        }
        let num = |i: usize, name: &str| -> Result<f64, PlanError> {
            cols[i].parse::<f64>().map_err(|_| {
                err(
                    format!("line {lineno}"),
                    format!("{name} {:?} is not a number", cols[i]),
                )
            })
        };
        let int = |i: usize, name: &str| -> Result<u32, PlanError> {
            cols[i].parse::<u32>().map_err(|_| {
                err(
                    format!("line {lineno}"),
                    format!("{name} {:?} is not a non-negative integer", cols[i]),
                )
            })
        };
        let raw = RawItem {
            command: int(3, "command")?,
            frame: int(2, "frame")?,
            params: [
                num(4, "param1")?,
                num(5, "param2")?,
                num(6, "param3")?,
                num(7, "param4")?,
            ],
            lat: num(8, "latitude")?,
            lon: num(9, "longitude")?,
            alt: num(10, "altitude")?,
        };
        rows.push((lineno, int(0, "index")?, raw));
    }
    let Some((home_line, _, home_raw)) = rows.first() else {
        return Err(err(
            "file".into(),
            "no items: a .waypoints file needs at least the home row and one item".into(),
        ));
    };
    if !home_raw.lat.is_finite()
        || !home_raw.lon.is_finite()
        || !home_raw.alt.is_finite()
        || !(-90.0..=90.0).contains(&home_raw.lat)
        || !(-180.0..=180.0).contains(&home_raw.lon)
    {
        return Err(err(
            format!("item 0 (line {home_line}, home)"),
            format!(
                "home position ({}, {}, {}) is not a valid position",
                home_raw.lat, home_raw.lon, home_raw.alt
            ),
        ));
    }
    let home = GeoPoint {
        lat_deg: home_raw.lat,
        lon_deg: home_raw.lon,
        alt_m: home_raw.alt,
    };
    let mut items = Vec::new();
    for (lineno, idx, raw) in rows.iter().skip(1) {
        let at = format!("item {idx} (line {lineno})");
        let it = build_item(raw, items.len(), format!("line {lineno}"), Some(home.alt_m))
            .map_err(|why| err(at, why))?;
        items.push(it);
    }
    if items.is_empty() {
        return Err(err(
            "file".into(),
            "no mission items after the home row".into(),
        ));
    }
    Ok(Plan {
        source: file.to_string(),
        home,
        items,
        hover_speed_m_s: None,
        cruise_speed_m_s: None,
    })
}

/// Parse a QGroundControl `.plan` (JSON, `fileType` "Plan"): `mission.items` of
/// `SimpleItem`s (`command`, `frame`, `params` [p1..p7] with p5..p7 = lat, lon, alt;
/// `null` = unused) and `ComplexItem`s (survey, corridor scan, structure scan), whose
/// flown items are `TransectStyleComplexItem.Items` (SimpleItems as above) or, when a file
/// has only the drawing, `TransectStyleComplexItem.VisualTransectPoints` ([lat, lon]
/// pairs, flown at the item's `Altitude`, else `CameraCalc.DistanceToSurface`, relative);
/// `mission.plannedHomePosition` [lat, lon, alt AMSL]; `mission.hoverSpeed` and
/// `mission.cruiseSpeed`, m/s.
pub fn parse_qgc_plan(text: &str, file: &str) -> Result<Plan, PlanError> {
    use serde_json::Value;
    let err = |at: &str, why: String| PlanError {
        file: file.to_string(),
        at: at.to_string(),
        why,
    };
    let doc: Value =
        serde_json::from_str(text).map_err(|e| err("file", format!("malformed JSON: {e}")))?;
    if doc.get("fileType").and_then(Value::as_str) != Some("Plan") {
        return Err(err(
            "fileType",
            "expected \"Plan\" (a QGroundControl plan file)".into(),
        ));
    }
    let mission = doc
        .get("mission")
        .ok_or_else(|| err("mission", "missing".into()))?;
    let speed = |key: &str| -> Result<Option<f64>, PlanError> {
        match mission.get(key) {
            None | Some(Value::Null) => Ok(None),
            Some(v) => match v.as_f64() {
                Some(s) if s.is_finite() && s > 0.0 => Ok(Some(s)),
                _ => Err(err(
                    &format!("mission.{key}"),
                    format!("{v}: must be a speed > 0, m/s"),
                )),
            },
        }
    };
    let hover_speed_m_s = speed("hoverSpeed")?;
    let cruise_speed_m_s = speed("cruiseSpeed")?;
    let home = planned_home(mission).map_err(|why| err("mission.plannedHomePosition", why))?;
    let list = mission
        .get("items")
        .and_then(Value::as_array)
        .ok_or_else(|| err("mission.items", "missing or not a list".into()))?;
    let mut items = Vec::new();
    let home_amsl = home.map(|h| h.alt_m);
    for (i, v) in list.iter().enumerate() {
        let path = format!("mission.items[{i}]");
        match v.get("type").and_then(Value::as_str) {
            Some("SimpleItem") => {
                let raw = simple_item(v).map_err(|why| err(&path, why))?;
                let it = build_item(&raw, items.len(), path.clone(), home_amsl)
                    .map_err(|why| err(&format!("item {} ({path})", items.len()), why))?;
                items.push(it);
            }
            Some("ComplexItem") => {
                complex_item(v, &path, home_amsl, &mut items).map_err(|(at, why)| err(&at, why))?
            }
            other => {
                return Err(err(
                    &path,
                    format!("type {other:?}: expected \"SimpleItem\" or \"ComplexItem\""),
                ))
            }
        }
    }
    if items.is_empty() {
        return Err(err("mission.items", "the plan has no mission items".into()));
    }
    // Without a planned home, the first positioned item's point is home (at 0 m AMSL).
    let home = match home {
        Some(h) => h,
        None => {
            let first = items.iter().find_map(|i| i.position);
            let p = first.ok_or_else(|| {
                err(
                    "mission.plannedHomePosition",
                    "missing, and no item has a position to start from".into(),
                )
            })?;
            GeoPoint {
                lat_deg: p.lat_deg,
                lon_deg: p.lon_deg,
                alt_m: 0.0,
            }
        }
    };
    Ok(Plan {
        source: file.to_string(),
        home,
        items,
        hover_speed_m_s,
        cruise_speed_m_s,
    })
}

/// A `.plan`'s `mission.plannedHomePosition`: none when absent or null, else checked.
fn planned_home(mission: &serde_json::Value) -> Result<Option<GeoPoint>, String> {
    use serde_json::Value;
    match mission.get("plannedHomePosition") {
        Some(Value::Array(a)) if a.len() >= 2 => {
            let n = |i: usize| a.get(i).and_then(Value::as_f64);
            let (lat, lon) = (n(0).unwrap_or(f64::NAN), n(1).unwrap_or(f64::NAN));
            if !lat.is_finite()
                || !lon.is_finite()
                || !(-90.0..=90.0).contains(&lat)
                || !(-180.0..=180.0).contains(&lon)
            {
                return Err(format!("({lat}, {lon}) is not a valid latitude/longitude"));
            }
            Ok(Some(GeoPoint {
                lat_deg: lat,
                lon_deg: lon,
                alt_m: n(2).filter(|v| v.is_finite()).unwrap_or(0.0),
            }))
        }
        None | Some(Value::Null) => Ok(None),
        Some(v) => Err(format!("{v}: expected [lat, lon, alt]")),
    }
}

/// A `.plan`'s ComplexItem at `path` (a survey, corridor or structure scan), expanded into
/// `items`: its own `Items` when QGC wrote them, else its `VisualTransectPoints` flown at its
/// altitude. An error is (where, why).
fn complex_item(
    v: &serde_json::Value,
    path: &str,
    home_amsl: Option<f64>,
    items: &mut Vec<Item>,
) -> Result<(), (String, String)> {
    use serde_json::Value;
    let at = |p: &str, why: String| (p.to_string(), why);
    let mut push = |raw: RawItem, sp: String| -> Result<(), (String, String)> {
        let it = build_item(&raw, items.len(), sp.clone(), home_amsl)
            .map_err(|why| (format!("item {} ({sp})", items.len()), why))?;
        items.push(it);
        Ok(())
    };
    let kind = v
        .get("complexItemType")
        .and_then(Value::as_str)
        .unwrap_or("?");
    let tsc = v.get("TransectStyleComplexItem").ok_or_else(|| at(path, format!("complex item {kind:?} without TransectStyleComplexItem: cannot expand its waypoints")))?;
    if let Some(sub) = tsc
        .get("Items")
        .and_then(Value::as_array)
        .filter(|s| !s.is_empty())
    {
        for (j, s) in sub.iter().enumerate() {
            let sp = format!("{path}.TransectStyleComplexItem.Items[{j}]");
            let raw = simple_item(s).map_err(|why| at(&sp, why))?;
            push(raw, sp)?;
        }
    } else if let Some(pts) = tsc.get("VisualTransectPoints").and_then(Value::as_array) {
        let alt = v
            .get("Altitude")
            .and_then(Value::as_f64)
            .or_else(|| tsc.get("CameraCalc").and_then(|c| c.get("DistanceToSurface")).and_then(Value::as_f64))
            .ok_or_else(|| at(path, "VisualTransectPoints without Altitude or CameraCalc.DistanceToSurface: no altitude to fly them at".into()))?;
        for (j, p) in pts.iter().enumerate() {
            let sp = format!("{path}.TransectStyleComplexItem.VisualTransectPoints[{j}]");
            let ll = p
                .as_array()
                .filter(|a| a.len() >= 2)
                .ok_or_else(|| at(&sp, "expected [lat, lon]".into()))?;
            let raw = RawItem {
                command: 16,
                frame: 3,
                params: [0.0; 4],
                lat: ll[0].as_f64().unwrap_or(f64::NAN),
                lon: ll[1].as_f64().unwrap_or(f64::NAN),
                alt,
            };
            push(raw, sp)?;
        }
    } else {
        return Err(at(path, format!("complex item {kind:?} has neither TransectStyleComplexItem.Items nor VisualTransectPoints")));
    }
    Ok(())
}

/// A `SimpleItem`'s command, frame and seven params (`null` → NaN, "unused").
fn simple_item(v: &serde_json::Value) -> Result<RawItem, String> {
    use serde_json::Value;
    let command = v
        .get("command")
        .and_then(Value::as_u64)
        .ok_or("missing or non-integer \"command\"")?;
    let frame = v
        .get("frame")
        .and_then(Value::as_u64)
        .ok_or("missing or non-integer \"frame\"")?;
    let params = v
        .get("params")
        .and_then(Value::as_array)
        .ok_or("missing \"params\" list")?;
    if params.len() != 7 {
        return Err(format!(
            "\"params\" has {} values: expected 7",
            params.len()
        ));
    }
    let mut p = [0.0f64; 7];
    for (k, x) in params.iter().enumerate() {
        p[k] = match x {
            Value::Null => f64::NAN,
            x => x
                .as_f64()
                .ok_or_else(|| format!("params[{k}] = {x}: not a number"))?,
        };
    }
    let command =
        u32::try_from(command).map_err(|_| format!("command {command} is out of range"))?;
    let frame = u32::try_from(frame).map_err(|_| format!("frame {frame} is out of range"))?;
    Ok(RawItem {
        command,
        frame,
        params: [p[0], p[1], p[2], p[3]],
        lat: p[4],
        lon: p[5],
        alt: p[6],
    })
}
