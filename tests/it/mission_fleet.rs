//! A fleet's missions, each forecast on its own vehicle's chain: three simulated vehicles
//! (system ids 1, 2, 3) fly out-and-back plans of 250, 500 and 750 m in one `.tlog`, each
//! logging its own mission download. Replayed, every vehicle must get its own mission
//! forecast (from its own plan: the longer the plan, the more energy) and its own mission
//! alerts, and the forecast of what is left must fall as each flies.

use std::collections::BTreeMap;

use crate::harness::replay_json;

use dronewatt::sim::{self, SimMission, SimOptions};

/// An out-and-back plan `out_m` north of the data set's site (ArduPilot layout: home item 0,
/// take-off to 25 m, the far point, return to launch).
fn plan(out_m: f64) -> String {
    let lat = 40.45906 + out_m / 111_320.0;
    format!(
        "QGC WPL 110\n\
         0\t1\t0\t16\t0\t0\t0\t0\t40.4590600\t-79.7828200\t268.7\t1\n\
         1\t0\t3\t22\t0\t0\t0\t0\t0\t0\t25\t1\n\
         2\t0\t3\t16\t0\t0\t0\t0\t{lat:.7}\t-79.7828200\t25\t1\n\
         3\t0\t3\t20\t0\t0\t0\t0\t0\t0\t0\t1\n"
    )
}

#[test]
fn each_vehicle_of_a_fleet_gets_its_own_mission_forecast_and_alerts() {
    let dir = tempfile::tempdir().unwrap();
    let outs = [250.0, 500.0, 750.0];
    let mut flights = Vec::new();
    for (i, out_m) in outs.iter().enumerate() {
        let path = dir.path().join(format!("v{i}.waypoints"));
        std::fs::write(&path, plan(*out_m)).unwrap();
        let p = dronewatt::mission::plan::Plan::load(&path).unwrap();
        let (route, mission) = SimMission::from_plan(&p, 10.0, sim::Autopilot::Ardupilot).unwrap();
        let mut f = sim::simulate(&SimOptions {
            route,
            mission: Some(mission),
            wind_mps: 0.0,
            seed: i as u64,
            ..Default::default()
        })
        .unwrap();
        // Vehicle i + 1, starting 37 ms after the one before (as `simulate --vehicles` does).
        for r in &mut f.records {
            r.header.system_id = i as u32 + 1;
            r.t_us += i as u64 * 37_000;
        }
        flights.push(f);
    }
    let tlog = dir.path().join("fleet.tlog");
    let merged = sim::SimFlight {
        records: sim::merge(&flights),
        truth: Vec::new(),
    };
    sim::output::write_tlog(&tlog, &merged).unwrap();
    // A margin rule every vehicle with a mission raises: each vehicle's alert is its own.
    let cfg = dir.path().join("dw.toml");
    let calibrated = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/config/vehicles/m100-calibrated.toml"
    );
    std::fs::write(
        &cfg,
        format!("[forecast.live]\ncalibrated_profile = \"{calibrated}\"\n\n") + "[[alerts]]\nname = \"mission_margin\"\nkind = \"mission_margin_below\"\nbelow_wh = 10000\n\
         clear_wh = 10001\nfor_s = 1\nseverity = \"warning\"\nmessage = \"margin\"\n",
    )
    .unwrap();
    let lines = replay_json(
        &tlog,
        &["--config", cfg.to_str().unwrap(), "--data-dir", "off"],
    );

    // Per vehicle: its mission forecasts (t, energy left P50) and its mission alerts.
    let mut forecasts: BTreeMap<u64, Vec<(f64, f64)>> = BTreeMap::new();
    let mut alerts: BTreeMap<u64, usize> = BTreeMap::new();
    for v in &lines {
        let Some(id) = v["system_id"].as_u64() else {
            continue;
        };
        if v["type"] == "estimate" {
            if let Some(e) = v["mission_energy_wh"].as_f64() {
                forecasts
                    .entry(id)
                    .or_default()
                    .push((v["t"].as_f64().unwrap(), e));
            }
        }
        if v["type"] == "alert" && v["rule"] == "mission_margin" && v["state"] == "raised" {
            *alerts.entry(id).or_default() += 1;
        }
    }
    assert_eq!(
        forecasts.keys().copied().collect::<Vec<_>>(),
        vec![1, 2, 3],
        "every vehicle has its mission forecast"
    );
    assert_eq!(
        alerts.keys().copied().collect::<Vec<_>>(),
        vec![1, 2, 3],
        "every vehicle has its mission alert: {alerts:?}"
    );
    // Each forecast is of its own plan: the first (the whole mission, before take-off)
    // grows with the plan's length, and is near what that vehicle drew.
    let first: Vec<f64> = forecasts.values().map(|f| f[0].1).collect();
    let drawn: Vec<f64> = flights.iter().map(|f| f.energy_wh()).collect();
    eprintln!(
        "first forecasts {first:?} at {:?}; drawn {drawn:?}",
        forecasts.values().map(|f| f[0].0).collect::<Vec<_>>()
    );
    for (i, f) in flights.iter().enumerate() {
        let drawn = f.energy_wh();
        assert!(
            (0.85 * drawn..1.15 * drawn).contains(&first[i]),
            "vehicle {}: forecast {:.1} Wh for a flight that drew {drawn:.1} Wh ({first:?})",
            i + 1,
            first[i]
        );
    }
    assert!(
        first[0] < first[1] && first[1] < first[2],
        "longer plans, more energy: {first:?}"
    );
    // Going out and back twice as far takes about twice the cruise energy: the difference
    // between the plans is ~ the same for each 250 m step.
    let (d1, d2) = (first[1] - first[0], first[2] - first[1]);
    assert!(
        d1 > 0.0 && (d2 / d1 - 1.0).abs() < 0.25,
        "each 250 m step costs about the same: {first:?}"
    );
    // And each falls as its vehicle flies: near nothing at the end.
    for (id, f) in &forecasts {
        let (start, end) = (f[0].1, f[f.len() - 1].1);
        assert!(
            end < 0.15 * start,
            "vehicle {id}: {start:.1} Wh left at the start, {end:.1} Wh at the end"
        );
    }
}
