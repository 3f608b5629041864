//! The properties of the file readers that are not MAVLink: the M100 CSV, the TOML
//! configuration, mission plans and LightGBM's text model (the table in [`super`]).

use super::CSV_ENCODE_MAX_ROWS;
use crate::report::status::IngestStats;

/// The M100 CSV reader (bytes as the file would hold them, after gunzip).
pub fn check_csv(data: &[u8]) -> Result<(), String> {
    let Ok(ds) = crate::source::logs::dataset::parse_flights(data, "fuzz.csv", None) else {
        return Ok(()); // not UTF-8, or a header without the data set's columns: an error, fine
    };
    let Ok(text) = std::str::from_utf8(data) else {
        return Err("parse_flights accepted bytes that are not UTF-8".into());
    };
    let lines = text
        .split('\n')
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .count();
    let rows: usize = ds.flights.iter().map(|f| f.rows.len()).sum();
    if rows + ds.skipped.len() != lines {
        return Err(format!(
            "{lines} data lines but {rows} rows kept + {} skipped",
            ds.skipped.len()
        ));
    }
    if ds.skipped.windows(2).any(|w| w[0].line >= w[1].line)
        || ds.skipped.iter().any(|s| s.line < 2 || s.reason.is_empty())
    {
        return Err(format!(
            "skipped rows out of order or unnamed: {:?}",
            ds.skipped
        ));
    }
    if ds.all_flights.windows(2).any(|w| w[0] >= w[1]) {
        return Err(format!("all_flights not increasing: {:?}", ds.all_flights));
    }
    for f in &ds.flights {
        if !ds.all_flights.contains(&f.flight) {
            return Err(format!("flight {} read but not in all_flights", f.flight));
        }
        if ![f.speed_m_s, f.payload_g, f.altitude_m]
            .iter()
            .all(|x| x.is_finite())
        {
            return Err(format!(
                "flight {}: a non-finite speed, payload or altitude",
                f.flight
            ));
        }
        if f.rows.windows(2).any(|w| w[0].time_s >= w[1].time_s)
            || f.rows.iter().any(|r| !r.time_s.is_finite())
        {
            return Err(format!("flight {}: time does not increase", f.flight));
        }
    }
    if rows <= CSV_ENCODE_MAX_ROWS {
        for f in ds.flights.iter().filter(|f| !f.rows.is_empty()) {
            let bytes = crate::source::logs::dataset::encode_flight(f);
            let stats = IngestStats::default();
            let msgs = crate::source::logs::tlog::decode_tlog(&bytes, &stats);
            let s = stats.snapshot();
            if s.frames_bad != 0 || s.unknown != 0 || s.junk_bytes != 0 || msgs.is_empty() {
                return Err(format!(
                    "flight {}: its own encoding decodes with {s:?}",
                    f.flight
                ));
            }
        }
    }
    Ok(())
}

/// The TOML configuration: parse, then validate.
pub fn check_config(data: &[u8]) -> Result<(), String> {
    let Ok(text) = std::str::from_utf8(data) else {
        return Ok(());
    };
    let Ok(cfg) = toml::from_str::<crate::config::Config>(text) else {
        return Ok(());
    };
    let errors = cfg.errors();
    if errors != cfg.errors() {
        return Err("validate() is not deterministic".into());
    }
    const KEYS: [&str; 5] = ["telemetry.", "energy.", "alerts[", "sinks.", "mission."];
    if let Some(e) = errors
        .iter()
        .find(|e| !KEYS.iter().any(|k| e.starts_with(k)))
    {
        return Err(format!("a validation message names no key: {e:?}"));
    }
    if cfg.validate().is_ok() != errors.is_empty() {
        return Err("validate() and errors() disagree".into());
    }
    if errors.is_empty() {
        if cfg.vehicle.is_none() {
            crate::energy::EnergyTracker::new(&cfg.energy, cfg.mission.speed_m_s)
                .map_err(|e| format!("validated, but the energy tracker refuses it: {e}"))?;
        }
        crate::alert::AlertEngine::new(&cfg.alerts)
            .map_err(|e| format!("validated, but the alert engine refuses it: {e}"))?;
        let _ = crate::telemetry::Telemetry::new(&cfg.telemetry, &cfg.mission);
        if let Some(r) = cfg
            .alerts
            .iter()
            .find(|r| r.describe().ends_with(": invalid"))
        {
            return Err(format!(
                "validated, but rule '{}' describes itself as invalid",
                r.name
            ));
        }
    }
    Ok(())
}

/// A mission plan, read as both formats the `plan` command takes: QGroundControl `.plan`
/// JSON and `QGC WPL 110` `.waypoints` text. A plan that reads has items, a home and
/// positions in range with finite numbers, and every item once, in order; one that does not
/// names the file, the item or the whole file, and why. Reading is deterministic.
pub fn check_plan(data: &[u8]) -> Result<(), String> {
    use crate::mission::plan::{parse_qgc_plan, parse_waypoints, Plan, PlanError};
    let Ok(text) = std::str::from_utf8(data) else {
        return Ok(());
    };
    type Reader = fn(&str, &str) -> Result<Plan, PlanError>;
    let readers: [(&str, Reader); 2] = [
        ("fuzz.plan", parse_qgc_plan),
        ("fuzz.waypoints", parse_waypoints),
    ];
    for (file, read) in readers {
        let first = read(text, file);
        let again = read(text, file);
        match (&first, &again) {
            (Err(a), Err(b)) if a.to_string() == b.to_string() => {
                if a.file != file || a.at.is_empty() || a.why.is_empty() {
                    return Err(format!(
                        "{file}: an error that does not say where and why: {a:?}"
                    ));
                }
            }
            (Ok(a), Ok(b)) if a.items.len() == b.items.len() => {
                if a.items.is_empty() {
                    return Err(format!("{file}: read with no items"));
                }
                let in_range = |p: &crate::mission::plan::GeoPoint| {
                    p.lat_deg.is_finite()
                        && p.lon_deg.is_finite()
                        && p.alt_m.is_finite()
                        && p.lat_deg.abs() <= 90.0
                        && p.lon_deg.abs() <= 180.0
                };
                if !in_range(&a.home) {
                    return Err(format!("{file}: home out of range: {:?}", a.home));
                }
                for (i, item) in a.items.iter().enumerate() {
                    if item.index != i {
                        return Err(format!("{file}: item {i} has index {}", item.index));
                    }
                    if let Some(p) = item.position.filter(|p| !in_range(p)) {
                        return Err(format!("{file}: item {i} position out of range: {p:?}"));
                    }
                }
            }
            _ => return Err(format!("{file}: reading twice gave different results")),
        }
    }
    Ok(())
}

/// LightGBM's text model, as a card's `[trees]` names it: a model that parses evaluates
/// any row without panicking (every child index in range, every walk ending at a leaf) and
/// gives the same estimate twice; parsing the same text twice gives the same model.
pub fn check_trees(data: &[u8]) -> Result<(), String> {
    let Ok(text) = std::str::from_utf8(data) else {
        return Ok(());
    };
    let first = crate::model::trees::Trees::parse(text);
    let again = crate::model::trees::Trees::parse(text);
    let (t, u) = match (first, again) {
        (Ok(t), Ok(u)) => (t, u),
        (Err(a), Err(b)) if a.to_string() == b.to_string() => return Ok(()),
        _ => return Err("parsing is not deterministic".into()),
    };
    if t.len() != u.len() || t.feature_names() != u.feature_names() {
        return Err("parsing is not deterministic".into());
    }
    let n = t.feature_names().len();
    let mut rows: Vec<Vec<f64>> = [f64::NAN, 0.0, -0.0, 1e-40, 1.0, -1e300, f64::INFINITY]
        .iter()
        .map(|v| vec![*v; n])
        .collect();
    // And a row of the input's own bytes.
    rows.push(
        (0..n)
            .map(|i| f64::from(data[i % data.len()]) - 128.0)
            .collect(),
    );
    for x in &rows {
        let (a, b) = (t.predict(x), u.predict(x));
        if a.to_bits() != b.to_bits() && !(a.is_nan() && b.is_nan()) {
            return Err(format!("the same row gives {a} and {b}"));
        }
    }
    Ok(())
}
