//! `dronewatt-lab plan-eval --dump-live DIR` (hidden): what the live-correction analysis of
//! `docs/src/mission.md` ("Learning from the flight so far") reads, one JSON file per
//! **training** flight (`<flight>.json`) plus `calibration.json`; never a test flight.
//! `lab/scripts/mission/lab_live.py DIR` turns it into the section's table and correlations.
//!
//! A flight's file holds:
//! - `flight`, `route`, `speed`, `payload`, `wind` (`[m/s, from deg]`, the plan's), `dt`
//!   (the plan's sample period, s), `measured_wh`, `live_forecast_rest_wh` (`plan-eval`'s
//!   rolling-validation score, for a check);
//! - `i0`, `ih`, `i1`: the first airborne row, the half-time row, the last airborne row;
//!   `k`: the plan sample found at `ih` (`plan-eval`'s live point); `row_k`: the plan sample
//!   found at each row `i0..=i1` (the locator carried on past half time);
//! - `legs`: `[label, first sample, one past the last]`;
//! - `samples`: per plan sample `[phase, v_h, v_z, leg, e, n, u, work up Wh, work down Wh]`
//!   (phase as [`phase_of`]: 0 vertical climb, 1 vertical descent, 2 other);
//! - `models`: per member of the calibration `{name, e}`, its uncorrected P50 energy per
//!   plan sample, Wh;
//! - `rows`: per recording row `[t s, V·I W, ∫V·I Wh from the start, anemometer m/s,
//!   anemometer from deg, v right, v forward, v up]`.

use std::io::Write;
use std::path::Path;

use anyhow::Context;
use serde_json::json;

use crate::forecast_fit::score::FlightScore;
use crate::forecast_fit::{Prepared, LOCATE_HORIZON_S};
use dronewatt::features::idx;
use dronewatt::mission::forecast::{phase_of, vertical_work_w, Calibration};
use dronewatt::mission::trajectory::enu_of;
use dronewatt::model::profile::VehicleProfile;
use dronewatt::offline::data::TEST_FLIGHTS;
use dronewatt::source::logs::dataset::Flight;

/// Write the dump of every training flight in `train` (each with its rolling-validation
/// score in `scores`) to `dir`. A test flight is refused, whatever the caller passes.
pub(crate) fn dump_live(
    dir: &Path,
    flights: &[Flight],
    train: &[Prepared],
    scores: &[FlightScore],
    cal: &Calibration,
) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let ids: Vec<u32> = train.iter().map(|p| p.flight).collect();
    if let Some(t) = ids.iter().find(|f| TEST_FLIGHTS.contains(f)) {
        anyhow::bail!("flight {t} is a test flight: --dump-live writes training flights only");
    }
    write_json(
        &dir.join("calibration.json"),
        &json!({ "calibration": cal, "training_flights": ids, "test_flights": TEST_FLIGHTS }),
    )?;
    for (p, s) in train.iter().zip(scores) {
        let f = flights
            .iter()
            .find(|f| f.flight == p.flight)
            .with_context(|| format!("flight {} missing", p.flight))?;
        write_json(
            &dir.join(format!("{}.json", p.flight)),
            &flight_json(f, p, s, cal)?,
        )?;
    }
    Ok(())
}

fn write_json(path: &Path, v: &serde_json::Value) -> anyhow::Result<()> {
    let file = std::fs::File::create(path).with_context(|| format!("{}", path.display()))?;
    let mut w = std::io::BufWriter::new(file);
    serde_json::to_writer(&mut w, v)?;
    w.flush()?;
    Ok(())
}

/// One flight's dump (see the module docs); the locator as in
/// [`crate::forecast_fit::prepare`], carried on to the last airborne row.
fn flight_json(
    f: &Flight,
    p: &Prepared,
    s: &FlightScore,
    cal: &Calibration,
) -> anyhow::Result<serde_json::Value> {
    let rows = &f.rows;
    let cum = &p.cum_wh;
    let [i0, ih, i1] = p.live_rows;
    let traj = &p.traj;
    let horizon = (LOCATE_HORIZON_S / traj.dt_s) as usize;
    let mut k = 0usize;
    let mut row_k = Vec::with_capacity(i1 + 1 - i0);
    for r in &rows[i0..=i1] {
        let (e, n) = enu_of(&p.home, r.lat_deg, r.lon_deg);
        k = traj.locate(
            k,
            horizon,
            [e as f32, n as f32, (r.alt_m - p.home.alt_m) as f32],
        );
        row_k.push(k);
    }
    if ih.checked_sub(i0).and_then(|j| row_k.get(j)) != Some(&p.live_k) {
        anyhow::bail!("flight {}: the locator disagrees with plan-eval", f.flight);
    }
    let kg = VehicleProfile::m100().mass_kg(0.0);
    let samples: Vec<serde_json::Value> = traj
        .samples
        .iter()
        .enumerate()
        .map(|(j, x)| {
            let v = &x.features;
            let [up, down] = vertical_work_w(x, kg);
            let enu = traj.enu_m.get(j).copied().unwrap_or_default();
            json!([
                phase_of(x),
                v[idx::VX].hypot(v[idx::VY]),
                v[idx::VZ],
                traj.leg_of.get(j).copied().unwrap_or(0),
                enu[0],
                enu[1],
                enu[2],
                up * traj.dt_s / 3600.0,
                down * traj.dt_s / 3600.0
            ])
        })
        .collect();
    let row_list: Vec<serde_json::Value> = rows
        .iter()
        .zip(cum)
        .map(|(r, c)| {
            json!([
                r.time_s,
                r.voltage_v * r.current_a,
                c,
                r.wind_speed,
                r.wind_angle,
                r.vel[0],
                r.vel[1],
                r.vel[2]
            ])
        })
        .collect();
    let legs: Vec<serde_json::Value> = traj
        .legs
        .iter()
        .map(|l| json!([l.label, l.samples.start, l.samples.end]))
        .collect();
    let models: Vec<serde_json::Value> = p
        .raw
        .iter()
        .filter(|m| cal.members.iter().any(|c| c.model == m.name))
        .map(|m| json!({ "name": m.name, "e": m.sample_wh }))
        .collect();
    Ok(json!({
        "flight": p.flight,
        "route": p.route,
        "speed": p.speed_m_s,
        "payload": p.payload_g,
        "wind": [p.wind.speed_m_s, p.wind.from_deg],
        "dt": traj.dt_s,
        "measured_wh": p.measured_wh,
        "live_forecast_rest_wh": s.live_forecast_rest_wh,
        "i0": i0,
        "ih": ih,
        "i1": i1,
        "k": p.live_k,
        "row_k": row_k,
        "legs": legs,
        "samples": samples,
        "models": models,
        "rows": row_list,
    }))
}
