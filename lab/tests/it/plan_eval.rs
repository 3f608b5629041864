//! `plan-eval` on a subset of the real data set (fit on training flights, score test flights
//! 276 and 277) with loose bounds; R7's staged altitudes flown as slanted climbs that the
//! vertical-work term prices.

use dronewatt::config::Config;
use dronewatt_lab::plan_eval::{plan_eval, PlanEvalOptions};

#[test]
fn plan_eval_on_a_subset_forecasts_r1_flights_within_loose_bounds() {
    let data = dronewatt::default_data_path();
    let mut cfg = Config::default();
    cfg.models.lstm.enabled = false; // the physics models suffice here; the LSTM runs in the full evaluation
    let cal = dronewatt::model::profile::VehicleProfile::load(
        &crate::harness::root().join("config/vehicles/m100-calibrated.toml"),
    )
    .unwrap();
    let mut models = dronewatt::offline::chain::eval_models(&cfg, Some(&cal)).unwrap();
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
    let ds = dronewatt::source::logs::dataset::read_flights(
        &dronewatt::default_data_path(),
        Some(&[278]),
    )
    .unwrap();
    let f = &ds.flights[0];
    assert_eq!(
        (f.route.as_str(), f.altitude_text.as_str()),
        ("R7", "25-50-100-25")
    );
    let plan = dronewatt_lab::route::flight_plan(f, f).unwrap();
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
        &crate::harness::root().join("config/vehicles/m100-calibrated.toml"),
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
