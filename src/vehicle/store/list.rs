//! `dronewatt vehicles`: what the store knows, as a table or JSON.

use std::path::Path;

use anyhow::Result;

use crate::vehicle::store::dir::DB_FILE;
use crate::vehicle::store::posterior::Interval;
use crate::vehicle::store::Store;

/// `dronewatt vehicles`: the table (or JSON with `json`).
pub fn list(dir: &Path, json: bool) -> Result<String> {
    use std::fmt::Write;
    let path = dir.join(DB_FILE);
    if !path.exists() {
        return Ok(if json {
            "[]\n".into()
        } else {
            format!(
                "{}: no vehicle store yet (nothing flown with the store on)\n",
                path.display()
            )
        });
    }
    let store = Store::open(dir)?;
    let vehicles = store.vehicles()?;
    if json {
        return list_json(&vehicles);
    }
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{}: {} vehicle(s)",
        store.path().display(),
        vehicles.len()
    );
    let _ = writeln!(
        s,
        "{:<34} {:<9} {:<10} {:<22} {:<10} {:>7} {:>9} {:>9}  capacity delivered / rated, by flight",
        "vehicle", "told by", "autopilot", "type", "class", "flights", "airborne", "Wh/min"
    );
    for v in &vehicles {
        // (+ 0.0: an empty sum is −0.0.)
        let airborne: f64 = v.flights.iter().map(|f| f.summary.airborne_s).sum::<f64>() + 0.0;
        let trend = v.capacity_trend_pct();
        let trend = if trend.is_empty() {
            "—".to_string()
        } else {
            trend
                .iter()
                .map(|p| format!("{p:.0} %"))
                .collect::<Vec<_>>()
                .join(" → ")
        };
        let _ = writeln!(
            s,
            "{:<34} {:<9} {:<10} {:<22} {:<10} {:>7} {:>7.1} m {:>9}  {}",
            v.key,
            v.key_kind,
            v.autopilot,
            v.vehicle_type.trim_start_matches("MAV_TYPE_"),
            v.vehicle_class,
            v.flights.len(),
            airborne / 60.0,
            v.wh_per_min()
                .map_or("—".to_string(), |w| format!("{w:.2}")),
            trend
        );
        // Why each flight was matched to this vehicle (uid, key + pack, new), oldest first.
        let why: Vec<&str> = v
            .flights
            .iter()
            .map(|f| f.matched.as_deref().unwrap_or("not recorded (older store)"))
            .collect();
        if v.pack.is_known() || !why.is_empty() {
            let _ = writeln!(
                s,
                "{:<34} pack reported {}; flights matched by: {}",
                "",
                v.pack.describe(),
                if why.is_empty() {
                    "—".to_string()
                } else {
                    why.join("; ")
                }
            );
        }
        pack_rows(&mut s, v);
        if let Some(p) = &v.profile {
            let _ = writeln!(
                s,
                "{:<34} learned profile {} (forecast model {})",
                "",
                p.path.display(),
                p.forecast_model.as_deref().unwrap_or("not picked")
            );
        }
    }
    Ok(s)
}

/// `vehicles --json`: each vehicle with its pack's capacity and resistance and their
/// uncertainty.
fn list_json(vehicles: &[super::VehicleRecord]) -> Result<String> {
    // each vehicle with its pack's capacity and resistance and their uncertainty
    #[derive(serde::Serialize)]
    struct WithPack<'a> {
        #[serde(flatten)]
        v: &'a super::VehicleRecord,
        capacity_wh: Option<Interval>,
        internal_r_ohm: Option<Interval>,
    }
    let out: Vec<WithPack> = vehicles
        .iter()
        .map(|v| WithPack {
            v,
            capacity_wh: capacity(&v.flights),
            internal_r_ohm: resistance(&v.flights),
        })
        .collect();
    Ok(serde_json::to_string_pretty(&out)? + "\n")
}

/// One row per pack the vehicle identified (BATTERY_INFO's serial), in the order first
/// flown; the flights with no pack id heard in one row for the vehicle.
fn pack_rows(s: &mut String, v: &super::VehicleRecord) {
    use std::fmt::Write;
    let mut packs: Vec<Option<&str>> = Vec::new();
    for f in &v.flights {
        let id = f.summary.pack_id.as_deref();
        if !packs.contains(&id) {
            packs.push(id);
        }
    }
    for id in packs {
        let flights: Vec<_> = v
            .flights
            .iter()
            .filter(|f| f.summary.pack_id.as_deref() == id)
            .cloned()
            .collect();
        let mut pack = pack_trend(&flights);
        for (name, i, scale, unit) in [
            ("learned capacity", capacity(&flights), 1.0, "Wh"),
            ("learned R", resistance(&flights), 1000.0, "mΩ"),
        ] {
            if let Some(i) = i {
                let sep = if pack.is_empty() { "" } else { "; " };
                pack = format!(
                    "{pack}{sep}{name} {}",
                    super::posterior::text(&i, scale, unit)
                );
            }
        }
        let who = match id {
            Some(id) => format!("pack {id} ({} flight(s))", flights.len()),
            None => "pack (per vehicle: no pack id heard)".to_string(),
        };
        if !pack.is_empty() || id.is_some() {
            let pack = if pack.is_empty() { "—".into() } else { pack };
            let _ = writeln!(s, "{:<34} {who}, by flight: {pack}", "");
        }
    }
}

/// The capacity's posterior over the last [`super::CAPACITY_FLIGHTS`] of `flights` (oldest
/// first) that measured one: what the next flight starts from.
fn capacity(flights: &[super::FlightRecord]) -> Option<Interval> {
    let rows: Vec<(f64, Option<f64>, f64)> = flights
        .iter()
        .rev()
        .filter_map(|f| {
            let s = &f.summary;
            let c = s.effective_capacity_wh.filter(|c| *c > 0.0)?;
            Some((
                c,
                s.pct_start.zip(s.pct_end).map(|(a, b)| a - b),
                s.rated_capacity_wh,
            ))
        })
        .take(super::CAPACITY_FLIGHTS)
        .collect();
    let fl: Vec<(f64, f64)> = rows
        .iter()
        .filter_map(|(c, f, _)| Some((*c, (*f)?)))
        .collect();
    super::posterior::capacity(rows.first().map(|r| r.2), &fl).filter(|i| i.flights > 0)
}

/// The resistance's posterior over every flight that measured one.
fn resistance(flights: &[super::FlightRecord]) -> Option<Interval> {
    let r: Vec<f64> = flights
        .iter()
        .filter_map(|f| f.summary.internal_r_ohm)
        .collect();
    super::posterior::resistance(&r)
}

/// The pack's trend over flights, oldest first: health (energy delivered between the
/// resting voltages over what the OCV curve holds between them) and series resistance.
fn pack_trend(flights: &[super::FlightRecord]) -> String {
    let health: Vec<String> = flights
        .iter()
        .filter_map(|f| f.summary.pack_health_pct)
        .map(|h| format!("{h:.0} %"))
        .collect();
    let r: Vec<String> = flights
        .iter()
        .filter_map(|f| f.summary.internal_r_ohm)
        .map(|r| format!("{:.0}", 1000.0 * r))
        .collect();
    let mut parts = Vec::new();
    if !health.is_empty() {
        parts.push(format!("health {}", health.join(" → ")));
    }
    if !r.is_empty() {
        parts.push(format!("R {} mΩ", r.join(" → ")));
    }
    parts.join("; ")
}
