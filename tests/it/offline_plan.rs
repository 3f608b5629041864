//! Mission energy forecast end to end: `dronewatt plan` on a hand-written `.waypoints`
//! file (table, JSON, plot, a bad plan's error), and `plan-eval` on a subset of the real
//! data set (fit on training flights, score test flights 276 and 277) with loose bounds;
//! R7's staged altitudes flown as slanted climbs that the vertical-work term prices.

use crate::harness::{dronewatt, RunExt};
use std::process::Command;

use dronewatt::config::Config;
use dronewatt::offline::plan_eval::{plan_eval, PlanEvalOptions};

/// A delivery run like the data set's R1: home, two waypoints ~140 m out, a hold, home.
const WPL: &str = "QGC WPL 110\n\
0\t1\t0\t16\t0\t0\t0\t0\t40.4400000\t-79.9400000\t290.0\t1\n\
1\t0\t3\t22\t0\t0\t0\t0\t0\t0\t25\t1\n\
2\t0\t3\t178\t1\t10\t-1\t0\t0\t0\t0\t1\n\
3\t0\t3\t16\t0\t0\t0\t0\t40.4405000\t-79.9385000\t25\t1\n\
4\t0\t3\t16\t5\t0\t0\t0\t40.4389000\t-79.9396000\t25\t1\n\
5\t0\t3\t206\t25\t0\t1\t0\t0\t0\t0\t1\n\
6\t0\t3\t20\t0\t0\t0\t0\t0\t0\t0\t1\n";

/// `plan` for a pack at rest and for another vehicle: the voltage along the plan, and the
/// vehicle's own models and pack, never the M100's number.
#[test]
fn plan_takes_a_pack_state_and_another_vehicle() {
    let dir = tempfile::tempdir().unwrap();
    let plan = dir.path().join("r1.waypoints");
    std::fs::write(&plan, WPL).unwrap();
    let run = |args: &[&str]| -> serde_json::Value {
        let out = dronewatt()
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .arg("plan")
            .arg(&plan)
            .args(args)
            .args(["--json", "-"])
            .ok();
        serde_json::from_slice(&out.stdout).unwrap()
    };
    let m100 = run(&[]);
    assert!(
        m100.get("pack").is_none(),
        "no start state, no voltage forecast"
    );
    // A TB48D half used (23.9 V at rest): the margin is over what it holds now.
    let half = run(&["--battery-v", "23.9"]);
    let p = &half["pack"];
    let (v_min, landing) = (
        p["v_min_v"].as_f64().unwrap(),
        p["landing_v"].as_f64().unwrap(),
    );
    assert!(v_min < landing && landing < 23.9, "{p}");
    assert!(
        (30.0..80.0).contains(&p["soc_pct"].as_f64().unwrap()),
        "{p}"
    );
    assert_eq!(
        p["low_v"].as_f64(),
        Some(21.0),
        "3.5 V a cell on 6 cells: {p}"
    );
    assert!(
        half["margin_p50_wh"].as_f64().unwrap() < m100["margin_p50_wh"].as_f64().unwrap() - 20.0,
        "{half}"
    );
    // The X500: its own models and its own 4S pack, not the M100's forecast.
    let x500 = run(&["--vehicle", "x500", "--battery-v", "16.4"]);
    assert_eq!(x500["vehicle"], "Holybro X500 V2 (4S 5000 mAh)");
    assert!(
        x500["forecast_from"]
            .as_str()
            .unwrap()
            .contains("only the M100 is calibrated"),
        "{}",
        x500["forecast_from"]
    );
    assert!(
        !x500["forecast"]["model"].as_str().unwrap().contains("_cal"),
        "{}",
        x500["forecast"]["model"]
    );
    assert_ne!(
        x500["forecast"]["energy_p50_wh"],
        m100["forecast"]["energy_p50_wh"]
    );
    assert!(
        x500["forecast"]["p90_ratio"].as_f64().unwrap() >= 1.3,
        "the P90 is widened"
    );
    assert!(
        (70.0..80.0).contains(&x500["capacity_wh"].as_f64().unwrap()),
        "5000 mAh × 4S × 3.7 V: {}",
        x500["capacity_wh"]
    );
    assert_eq!(
        (
            x500["pack"]["cells"].as_u64(),
            x500["pack"]["chemistry"].as_str()
        ),
        (Some(4), Some("lipo"))
    );
    // A name that is nothing is said so.
    let out = dronewatt()
        .arg("plan")
        .arg(&plan)
        .args([
            "--vehicle",
            "no-such-vehicle",
            "--data-dir",
            dir.path().to_str().unwrap(),
        ])
        .out();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success()
            && err.contains("no-such-vehicle")
            && err.contains("x500")
            && err.contains("store"),
        "{err}"
    );
    // A resting voltage that is not one for this pack is refused, naming the flag.
    let out = dronewatt()
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .arg("plan")
        .arg(&plan)
        .args(["--battery-v", "12.6"])
        .out();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("--battery-v 12.6"),
        "{err}"
    );
}

#[test]
fn plan_prints_legs_margin_json_and_plot() {
    let dir = tempfile::tempdir().unwrap();
    let plan = dir.path().join("r1.waypoints");
    std::fs::write(&plan, WPL).unwrap();
    let json = dir.path().join("f.json");
    let png = dir.path().join("f.png");
    let out = dronewatt()
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args([
            "plan",
            plan.to_str().unwrap(),
            "--payload-g",
            "500",
            "--wind",
            "3@200",
            "--json",
        ])
        .arg(&json)
        .arg("--plot")
        .arg(&png)
        .out();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("takeoff")
            && stdout.contains("rtl")
            && stdout.contains("margin over reserve"),
        "{stdout}"
    );
    assert!(
        stdout.contains("not modelled: item 4 (line 7): MAV_CMD 206"),
        "the camera item is listed: {stdout}"
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let f = &v["forecast"];
    let (p50, p90) = (
        f["energy_p50_wh"].as_f64().unwrap(),
        f["energy_p90_wh"].as_f64().unwrap(),
    );
    // The data set's R1 at 10 m/s with 500 g takes 15–16 Wh in ~100 s airborne; this plan is a
    // little shorter with a 5 s hold: the forecast must be an M100's energy for it.
    assert!(
        (9.0..20.0).contains(&p50) && p90 >= p50,
        "P50 {p50} P90 {p90}"
    );
    let dur = f["duration_s"].as_f64().unwrap();
    assert!((60.0..140.0).contains(&dur), "{dur}");
    let legs: f64 = f["legs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l["energy_p50_wh"].as_f64().unwrap())
        .sum();
    assert!((legs - p50).abs() < 1e-6);
    let cap = v["capacity_wh"].as_f64().unwrap();
    let usable = cap * (1.0 - v["reserve_pct"].as_f64().unwrap() / 100.0);
    assert!((v["margin_p50_wh"].as_f64().unwrap() - (usable - p50)).abs() < 1e-6);
    assert_eq!(&std::fs::read(&png).unwrap()[1..4], b"PNG");

    // a bad plan: the error names the file, the item and why
    std::fs::write(&plan, WPL.replace("40.4405000", "140.4405000")).unwrap();
    let out = dronewatt().args(["plan", plan.to_str().unwrap()]).out();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success()
            && err.contains("r1.waypoints")
            && err.contains("item 3 (line 5)")
            && err.contains("latitude 140.4405 is out of range"),
        "{err}"
    );
}

#[test]
fn plan_eval_on_a_subset_forecasts_r1_flights_within_loose_bounds() {
    let data = dronewatt::default_data_path();
    let mut cfg = Config::default();
    cfg.models.lstm.enabled = false; // the physics models suffice here; the LSTM runs in the full evaluation
    let cal = dronewatt::model::profile::VehicleProfile::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("config/vehicles/m100-calibrated.toml"),
    )
    .unwrap();
    let mut models = dronewatt::offline::eval::eval_models(&cfg, Some(&cal)).unwrap();
    // training: 40 R1 flights spread over the season, and flight 275 (the day of 276/277)
    let train: Vec<u32> = (100..=275).filter(|f| f % 4 == 0 || *f == 275).collect();
    let dump = tempfile::tempdir().unwrap();
    let opt = PlanEvalOptions {
        test: Some(vec![276, 277]),
        train: Some(train),
        ground_wind: true,
        dump_live: Some(dump.path().to_path_buf()),
    };
    let r = plan_eval(&data, &cfg, &mut models, &opt).unwrap();
    // --dump-live: one file per training flight and the calibration, never a test flight
    let mut dumped: Vec<String> = std::fs::read_dir(dump.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    dumped.sort();
    let mut want: Vec<String> = r
        .training_flights
        .iter()
        .map(|f| format!("{f}.json"))
        .chain(["calibration.json".to_string()])
        .collect();
    want.sort();
    assert_eq!(dumped, want, "training flights only");
    assert!(r.training_flights.len() >= 30, "{:?}", r.training_flights);
    assert!(
        !r.training_flights.contains(&276) && !r.training_flights.contains(&277),
        "never fit on a test flight"
    );
    for f in &r.test_flights {
        assert_eq!(
            f.geometry_from, 275,
            "R1's waypoints come from the nearest training flight of the route"
        );
        // the plan flown on paper takes as long as the flight was airborne (within 10 %)
        assert!(
            (f.planned_s / f.airborne_s - 1.0).abs() < 0.10,
            "flight {}: planned {} s, airborne {} s",
            f.flight,
            f.planned_s,
            f.airborne_s
        );
        assert!(
            f.preflight_err_pct < 8.0,
            "flight {}: pre-flight error {:.2} %",
            f.flight,
            f.preflight_err_pct
        );
        assert!(
            f.live_err_pct < 12.0,
            "flight {}: live error {:.2} %",
            f.flight,
            f.live_err_pct
        );
        assert!(f.p90_wh > f.p50_wh);
    }
    // the plan's clock runs with the flight's during it, not only in total: at half time
    // the vehicle is found where the plan has it then (the take-off's ground spin-up and
    // the measured stops and legs; defaults that matched only the total lagged ~3 s), and
    // what the plan has left from there is what the flight had left
    let mut lag: Vec<f64> = r
        .training_scores
        .iter()
        .map(|f| (f.live_t_s - f.live_plan_t_s).abs())
        .collect();
    let mut left: Vec<f64> = r
        .training_scores
        .iter()
        .map(|f| ((f.planned_s - f.live_plan_t_s) - (f.airborne_s - f.live_t_s)).abs())
        .collect();
    lag.sort_by(f64::total_cmp);
    left.sort_by(f64::total_cmp);
    assert!(
        lag[lag.len() / 2] < 2.0,
        "median |lag| at half time {:.2} s",
        lag[lag.len() / 2]
    );
    assert!(
        left[left.len() / 2] < 2.0,
        "median |planned − flown time left| {:.2} s",
        left[left.len() / 2]
    );
    let takeoff = &r.test_flights[0].plan_legs[0];
    assert!(
        takeoff.0 == "takeoff" && (takeoff.2 - (4.4 + 25.0 / 3.0)).abs() < 0.2,
        "spin-up then climb to 25 m: {takeoff:?}"
    );
    // the fit on training flights beats the autopilots' rule there, pre-flight and live
    assert!(
        r.training.preflight_median_err_pct < r.training.baseline_preflight_median_err_pct,
        "{:?}",
        r.training
    );
    assert!(
        r.training.live_median_err_pct < r.training.baseline_live_median_err_pct,
        "{:?}",
        r.training
    );
    assert!(r.training.p90_coverage_pct >= 80.0, "{:?}", r.training);
    // the members are the vehicle's own models (`_cal`: a correction cannot follow a published
    // model onto another vehicle), led by the one with the smallest training error, climbing
    // work priced; every other member ties with it (and only a tie joins: the worst `_cal`
    // models are far out of it)
    let c = &r.calibration;
    let err = |name: &str| {
        r.models_fit
            .iter()
            .find(|m| m.0 == name)
            .map(|m| m.2)
            .unwrap()
    };
    let own: Vec<&(String, f64, f64)> = r
        .models_fit
        .iter()
        .filter(|m| m.0.ends_with("_cal"))
        .collect();
    let lead = &c.members[0];
    assert!(
        c.members.iter().all(|m| m.model.ends_with("_cal"))
            && own.iter().all(|m| err(&lead.model) <= m.2),
        "{c:?} of {:?}",
        r.models_fit
    );
    assert!(
        r.basis == "vertical work" && c.members.iter().all(|m| m.climb_work[0] > 0.0),
        "{} {:?}",
        r.basis,
        c
    );
    let worst = own.iter().map(|m| m.2).fold(0.0, f64::max);
    assert!(
        c.members.iter().all(|m| err(&m.model) < worst),
        "the worst own model never ties: {c:?}"
    );
    // with several members, each is fitted alone and scored
    if c.members.len() > 1 {
        assert_eq!(
            r.members_alone
                .iter()
                .map(|t| t.model.clone())
                .collect::<Vec<_>>(),
            c.members
                .iter()
                .map(|m| m.model.clone())
                .collect::<Vec<_>>()
        );
        assert!(r.members_alone.iter().all(|t| t.test.flights == 2));
    }
    // the ground station's clock (horizontal distance at the plan's speed, no stops or
    // accelerations) leaves out time the flight spends: the baseline on it is short
    assert!(
        r.training_scores
            .iter()
            .all(|f| f.gcs_left_s < f.planned_s - f.live_plan_t_s),
        "QGC's time left is the shorter"
    );
    assert!(
        r.training.live_median_err_pct < r.training.baseline_gcs_live_median_err_pct,
        "{:?}",
        r.training
    );
    assert!(r.calibration.validate().is_ok(), "{:?}", r.calibration);
}

#[test]
fn r7s_altitude_stages_are_slanted_climbs_and_the_forecast_prices_their_climb() {
    use dronewatt::features::idx;
    use dronewatt::mission::forecast::{forecast, Calibration, Member};
    use dronewatt::mission::trajectory::{fly, Conditions, KinematicsConfig, Wind};
    let ds =
        dronewatt::source::dataset::read_flights(&dronewatt::default_data_path(), Some(&[278]))
            .unwrap();
    let f = &ds.flights[0];
    assert_eq!(
        (f.route.as_str(), f.altitude_text.as_str()),
        ("R7", "25-50-100-25")
    );
    let plan = dronewatt::offline::route::flight_plan(f, f).unwrap();
    let tr = fly(
        &plan,
        &KinematicsConfig::default(),
        &Conditions {
            wind: Wind::default(),
            payload_g: f.payload_g,
            speed_m_s: Some(f.speed_m_s),
            rate_hz: 10.0,
        },
    );
    // climbed height, vertically (take-off) and on legs that fly forward while they climb
    let (mut vertical, mut slanted) = (0.0, 0.0);
    for s in &tr.samples {
        let (vz, vh) = (
            f64::from(s.features[idx::VZ]),
            f64::from(s.features[idx::VX].hypot(s.features[idx::VY])),
        );
        if vz > 0.0 {
            *(if vh > 1.0 {
                &mut slanted
            } else {
                &mut vertical
            }) += vz * tr.dt_s;
        }
    }
    // (a slanted leg starts from a stop: its first metres climb before it has 1 m/s forward)
    assert!(
        (vertical + slanted - 100.0).abs() < 1.0 && slanted > 65.0,
        "take-off 25 m, stages 25→50→100 mostly on slanted legs: {vertical:.1} m + {slanted:.1} m"
    );
    // the fitted calibration (plan-eval's, the default) prices every metre climbed
    let profile = dronewatt::model::profile::VehicleProfile::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("config/vehicles/m100-calibrated.toml"),
    )
    .unwrap();
    let cal = Calibration::default();
    let mut models: Vec<_> = dronewatt::model::physics::models(&profile)
        .into_iter()
        .filter(|m| cal.members.iter().any(|c| c.model == m.name()))
        .collect();
    assert_eq!(
        models.len(),
        cal.members.len(),
        "every member runs with the calibrated profile"
    );
    let with = forecast(&tr, &mut models, &cal, 10, dronewatt::mission::MODEL_STRIDE);
    let flat = Calibration {
        members: cal
            .members
            .iter()
            .map(|m| Member {
                climb_work: [0.0; 2],
                ..m.clone()
            })
            .collect(),
        ..cal.clone()
    };
    let without = forecast(
        &tr,
        &mut models,
        &flat,
        10,
        dronewatt::mission::MODEL_STRIDE,
    );
    // the members' mean of scale × weight × m·g·Δh for the 100 m climbed
    let per_m: f64 = cal
        .members
        .iter()
        .map(|m| m.scale * m.climb_work[0])
        .sum::<f64>()
        / cal.members.len() as f64;
    let climb_wh = per_m * (cal.vehicle_kg + f.payload_g / 1000.0) * 9.81 * 100.0 / 3600.0;
    assert!(
        cal.members.iter().all(|m| m.climb_work[0] > 1.0),
        "a climb costs more than its potential energy: {:?}",
        cal.members
    );
    assert!(
        ((with.energy_p50_wh - without.energy_p50_wh) / climb_wh - 1.0).abs() < 0.01,
        "{} − {} vs {climb_wh}",
        with.energy_p50_wh,
        without.energy_p50_wh
    );
}

/// A plane's and a quadplane's plan (take-off, waypoints, a loiter, the landing; VTOL
/// take-off and landing for the quadplane) through `plan --vehicle plane|quadplane`: flown
/// as a plane, the same table as a multirotor's, and the plane's P50 within 10 % of what
/// the simulator draws flying the same plan.
#[test]
fn plan_flies_a_plane_and_a_quadplane_as_they_fly() {
    let dir = tempfile::tempdir().unwrap();
    let plane_wpl = "QGC WPL 110\n\
0\t1\t0\t16\t0\t0\t0\t0\t40.4400000\t-79.9400000\t290.0\t1\n\
1\t0\t3\t22\t0\t0\t0\t0\t0\t0\t60\t1\n\
2\t0\t3\t16\t0\t0\t0\t0\t40.4535000\t-79.9400000\t60\t1\n\
3\t0\t3\t19\t60\t0\t0\t0\t40.4535000\t-79.9300000\t80\t1\n\
4\t0\t3\t21\t0\t0\t0\t0\t40.4400000\t-79.9400000\t0\t1\n";
    let quad_wpl = plane_wpl
        .replace("\t22\t", "\t84\t")
        .replace("\t21\t", "\t85\t");
    let run = |vehicle: &str, text: &str, args: &[&str]| -> (serde_json::Value, String) {
        let plan = dir.path().join(format!("{vehicle}.waypoints"));
        std::fs::write(&plan, text).unwrap();
        let go = |json: bool| {
            let mut c = dronewatt();
            c.arg("plan")
                .arg(&plan)
                .args(["--vehicle", vehicle, "--wind", "4@270"])
                .args(args);
            if json {
                c.args(["--json", "-"]);
            }
            succeeds(&mut c)
        };
        (serde_json::from_str(&go(true)).unwrap(), go(false))
    };
    let labels = |v: &serde_json::Value| -> Vec<String> {
        v["forecast"]["legs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|l| l["label"].as_str().unwrap().to_string())
            .collect()
    };
    let (plane, table) = run("plane", plane_wpl, &["--payload-g", "0"]);
    assert_eq!(labels(&plane), ["takeoff", "waypoint", "loiter", "land"]);
    assert_eq!(plane["forecast"]["model"], "fixed_wing", "{plane}");
    assert_eq!(
        plane["speed_m_s"].as_f64(),
        Some(14.0),
        "the plane's cruise airspeed"
    );
    assert!(
        table.contains("item leg") && table.contains("loiter") && table.contains("total"),
        "{table}"
    );
    // the simulator flies the same plan; its energy against the forecast's
    let truth = dir.path().join("truth.csv");
    succeeds(
        dronewatt()
            .args(["simulate", "--vehicle", "plane", "--plan"])
            .arg(dir.path().join("plane.waypoints"))
            .arg("--out")
            .arg(dir.path().join("plane.tlog"))
            .arg("--truth")
            .arg(&truth)
            .args(["--wind-mps", "4", "--wind-dir-deg", "270"])
            .args(["--payload-g", "0"]),
    );
    let csv = std::fs::read_to_string(&truth).unwrap();
    let rows: Vec<(f64, f64)> = csv
        .lines()
        .skip(1)
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            (c[0].parse().unwrap(), c[2].parse().unwrap())
        })
        .collect();
    let sim_wh: f64 = rows
        .windows(2)
        .map(|w| w[0].1 * (w[1].0 - w[0].0) / 3600.0)
        .sum();
    let p50 = plane["forecast"]["energy_p50_wh"].as_f64().unwrap();
    assert!(
        (p50 / sim_wh - 1.0).abs() < 0.10,
        "forecast {p50:.2} Wh, simulated {sim_wh:.2} Wh"
    );
    let (quad, _) = run("quadplane", &quad_wpl, &[]);
    assert_eq!(
        labels(&quad),
        ["vtol takeoff", "waypoint", "loiter", "vtol land"]
    );
    let model = quad["forecast"]["model"].as_str().unwrap();
    assert!(
        model.contains("stolaroff") && model.contains("fixed_wing"),
        "{model}"
    );
    let legs = quad["forecast"]["legs"].as_array().unwrap();
    let watts = |i: usize| {
        legs[i]["energy_p50_wh"].as_f64().unwrap() * 3600.0
            / legs[i]["duration_s"].as_f64().unwrap()
    };
    assert!(
        watts(0) > 3.0 * watts(2),
        "hovering up costs more than circling: {} W vs {} W",
        watts(0),
        watts(2)
    );
}

/// Run `c`; it must succeed (its standard error shown when not). Its standard output.
fn succeeds(c: &mut Command) -> String {
    let out = c.out();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    String::from_utf8(out.stdout).unwrap()
}
