//! Alert rules on synthetic estimate sequences: debounce, hysteresis, repeat, every kind's
//! value, and configuration errors that name the file, the key and why.

use dronewatt::alert::AlertEngine;
use dronewatt::config::Config;
use dronewatt::features::{Sample, N_FEATURES};
use dronewatt::report::EnergyState;
use dronewatt::report::{AlertEvent, AlertState};
use dronewatt::report::{Estimate, ModelEstimate};

fn est(t_s: f64, measured_w: Option<f32>, models: &[(&str, f32)]) -> Estimate {
    Estimate {
        arrived: None,
        t_s,
        sample: Sample {
            t_s,
            features: [0.0; N_FEATURES],
            measured_w,
            voltage_v: None,
            home: None,
            stale_mask: 0,
            battery_remaining_pct: None,
            vehicle: Default::default(),
            air: Default::default(),
        },
        models: models
            .iter()
            .map(|(n, p)| ModelEstimate::new(n.to_string(), *p, None))
            .collect(),
    }
}

/// An estimate at `t_s` of a vehicle flying at a measured 300 W, with no model.
fn flying(t_s: f64) -> Estimate {
    est(t_s, Some(300.0), &[])
}

fn energy(remaining_wh: f64) -> EnergyState {
    EnergyState {
        remaining_wh: Some(remaining_wh),
        remaining_pct: Some(remaining_wh / 129.96 * 100.0),
        ..Default::default()
    }
}

fn parse(toml_text: &str) -> Config {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("alerts.toml");
    std::fs::write(&p, toml_text).unwrap();
    Config::load(&p).unwrap_or_else(|e| panic!("{e}"))
}

fn load_err(toml_text: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.toml");
    std::fs::write(&p, toml_text).unwrap();
    match Config::load(&p) {
        Ok(_) => panic!("accepted:\n{toml_text}"),
        Err(e) => e.to_string(),
    }
}

/// The alert engine of a config's `[[alerts]]`.
fn engine(toml_text: &str) -> AlertEngine {
    AlertEngine::new(&parse(toml_text).alerts).unwrap()
}

/// Feed `(t, remaining_wh)` pairs; collect the events.
fn run(engine: &mut AlertEngine, seq: &[(f64, f64)]) -> Vec<AlertEvent> {
    seq.iter()
        .flat_map(|&(t, wh)| engine.evaluate(&flying(t), &energy(wh)))
        .collect()
}

#[test]
fn hysteresis_raises_once_on_a_noisy_crossing() {
    let mut eng = engine(
        r#"
        [[alerts]]
        name = "low"
        kind = "remaining_below"
        below_wh = 30
        clear_wh = 33
        "#,
    );
    // Remaining falls through 30 Wh with ±1.5 Wh noise: it crosses 30 many times.
    let seq: Vec<(f64, f64)> = (0..200)
        .map(|i| {
            (
                i as f64 * 0.1,
                35.0 - i as f64 * 0.05 + if i % 2 == 0 { 1.5 } else { -1.5 },
            )
        })
        .collect();
    let crossings = seq
        .windows(2)
        .filter(|w| (w[0].1 < 30.0) != (w[1].1 < 30.0))
        .count();
    assert!(
        crossings > 5,
        "the sequence must be noisy around the level ({crossings})"
    );
    let ev = run(&mut eng, &seq);
    assert_eq!(ev.len(), 1, "{ev:?}");
    assert_eq!(ev[0].state, AlertState::Raised);
    assert_eq!(ev[0].severity, "warning");
    assert!(ev[0].message.starts_with("low "), "{}", ev[0].message);
    // It clears only above 33 Wh (a charged battery swapped in), once.
    let ev = run(&mut eng, &[(21.0, 32.0), (21.1, 33.5), (21.2, 34.0)]);
    assert_eq!(ev.len(), 1);
    assert_eq!(ev[0].state, AlertState::Cleared);
    assert_eq!(ev[0].t, 21.1);
}

#[test]
fn without_hysteresis_the_same_crossing_flaps() {
    // The control for the test above: the clear level at the raise level flaps on noise.
    let mut eng = engine("[[alerts]]\nname = \"low\"\nkind = \"remaining_below\"\nbelow_wh = 30\n");
    let seq: Vec<(f64, f64)> = (0..40)
        .map(|i| (i as f64 * 0.1, if i % 2 == 0 { 31.0 } else { 29.0 }))
        .collect();
    let ev = run(&mut eng, &seq);
    // The first step is above the level; every one after it raises or clears.
    assert_eq!(ev.len(), 39, "raise and clear on every step");
}

#[test]
fn debounce_needs_the_condition_to_hold_for_for_s() {
    let mut eng = engine(
        r#"
        [[alerts]]
        name = "spike"
        kind = "power_above"
        above_w = 800
        clear_w = 700
        for_s = 2
        severity = "MAV_SEVERITY_CRITICAL"
        "#,
    );
    let e0 = EnergyState::default();
    // A 1.5 s spike (t 1.0..=2.5) does not raise.
    let mut ev = Vec::new();
    for i in 0..50 {
        let t = i as f64 * 0.1;
        let p = if (1.0..=2.5).contains(&t) {
            900.0
        } else {
            500.0
        };
        ev.extend(eng.evaluate(&est(t, Some(p), &[]), &e0));
    }
    assert!(ev.is_empty(), "{ev:?}");
    // A sustained one raises exactly for_s after it began.
    for i in 50..100 {
        let t = i as f64 * 0.1;
        ev.extend(eng.evaluate(&est(t, Some(900.0), &[]), &e0));
    }
    assert_eq!(ev.len(), 1, "{ev:?}");
    assert!((ev[0].t - 7.0).abs() < 1e-9, "raised at {}", ev[0].t);
    assert_eq!(ev[0].severity, "critical");
    // Unknown measured power neither raises nor clears.
    assert!(eng.evaluate(&est(10.0, None, &[]), &e0).is_empty());
}

#[test]
fn repeat_says_it_again_while_raised() {
    let mut eng = engine(
        r#"
        [[alerts]]
        name = "low"
        kind = "remaining_below"
        below_pct = 20
        repeat_s = 10
        message = "Battery low"
        "#,
    );
    let seq: Vec<(f64, f64)> = (0..=350).map(|i| (i as f64 * 0.1, 10.0)).collect();
    let ev = run(&mut eng, &seq);
    let ts: Vec<f64> = ev.iter().map(|e| e.t).collect();
    assert_eq!(ts, vec![0.0, 10.0, 20.0, 30.0], "{ev:?}");
    assert!(
        ev.iter()
            .all(|e| e.state == AlertState::Raised && e.message.starts_with("Battery low 7.7%")),
        "{ev:?}"
    );
}

#[test]
fn every_kind_watches_its_own_value() {
    let mut eng = engine(
        r#"
        [energy]
        cell_count = 6

        [[alerts]]
        name = "tte"
        kind = "time_to_empty_below"
        below_s = 300
        [[alerts]]
        name = "home"
        kind = "home_margin_below"
        below_wh = 0
        severity = "critical"
        [[alerts]]
        name = "dev"
        kind = "deviation_above"
        above_w = 100
        model = "tseng"
        [[alerts]]
        name = "spread"
        kind = "models_disagree"
        above_w = 200
        [[alerts]]
        name = "cell"
        kind = "cell_voltage_below"
        below_v = 3.5
        [[alerts]]
        name = "lost"
        kind = "telemetry_lost"
        for_s = 1
        "#,
    );
    let calm = EnergyState {
        time_to_empty_s: Some(900.0),
        home_margin_wh: Some(20.0),
        cell_voltage_v: Some(3.9),
        ..Default::default()
    };
    let e = est(0.0, Some(500.0), &[("tseng", 480.0), ("lstm", 510.0)]);
    assert!(eng.evaluate(&e, &calm).is_empty());
    let bad = EnergyState {
        time_to_empty_s: Some(200.0),
        home_margin_wh: Some(-1.0),
        cell_voltage_v: Some(3.4),
        ..Default::default()
    };
    let mut e = est(1.0, Some(500.0), &[("tseng", 350.0), ("lstm", 600.0)]);
    e.sample.stale_mask = u32::MAX;
    let mut names: Vec<String> = eng.evaluate(&e, &bad).into_iter().map(|a| a.rule).collect();
    // Telemetry lost needs for_s = 1 of staleness: not yet.
    names.sort();
    assert_eq!(names, ["cell", "dev", "home", "spread", "tte"]);
    e.t_s = 2.0;
    let ev = eng.evaluate(&e, &bad);
    assert_eq!(ev.len(), 1);
    assert_eq!(ev[0].rule, "lost");
}

#[test]
fn bad_rules_name_the_file_the_key_and_why() {
    let cases = [
        ("[[alerts]]\nname = \"a\"\nkind = \"remaining_below\"\nbelow_wh = 30\nclear_wh = 20\n", "clear_wh = 20"),
        ("[[alerts]]\nname = \"a\"\nkind = \"remaining_below\"\n", "exactly one of below_wh, below_pct"),
        ("[[alerts]]\nname = \"a\"\nkind = \"power_above\"\nabove_w = 800\nclear_w = 900\n", "clear_w = 900"),
        ("[[alerts]]\nname = \"a\"\nkind = \"power_above\"\nabove_w = 800\nbelow_wh = 3\n", "below_wh"),
        ("[[alerts]]\nname = \"a\"\nkind = \"volcano\"\n", "volcano"),
        ("[[alerts]]\nname = \"a\"\nkind = \"power_above\"\nabove_w = 800\nseverity = \"loud\"\n", "severity 'loud'"),
        ("[[alerts]]\nname = \"a\"\nkind = \"telemetry_lost\"\n", "telemetry_lost needs for_s > 0"),
        ("[[alerts]]\nname = \"a\"\nkind = \"power_above\"\nabove_w = 1\n[[alerts]]\nname = \"a\"\nkind = \"power_above\"\nabove_w = 2\n", "alerts[1].name = 'a'"),
        ("[[alerts]]\nname = \"a\"\nkind = \"power_above\"\nabove_w = 800\nfor_s = -1\n", "alerts[0] (a).for_s = -1"),
        ("[energy]\ncapacity_wh = 0\n", "energy.capacity_wh = 0"),
        ("[sinks.mavlink]\ncomponent_id = 1\n", "sinks.mavlink.component_id = 1"),
        ("[sinks.web]\nbind = \"localhost\"\n", "sinks.web.bind = 'localhost'"),
    ];
    for (text, want) in cases {
        let err = load_err(text);
        assert!(err.contains("bad.toml"), "no file name in: {err}");
        assert!(err.contains(want), "expected '{want}' in: {err}");
    }
}

#[test]
fn mission_margin_below_debounces_holds_through_noise_and_waits_for_a_mission() {
    let mut eng = engine(
        r#"
        [[alerts]]
        name = "mission_margin"
        kind = "mission_margin_below"
        below_wh = 0
        clear_wh = 3
        for_s = 2
        severity = "critical"
        message = "mission cannot finish with reserve - return now"
        "#,
    );
    let state = |m: Option<f64>| EnergyState {
        remaining_wh: Some(80.0),
        mission_margin_wh: m,
        ..Default::default()
    };
    // No mission known: nothing, however long.
    let none: Vec<_> = (0..50)
        .flat_map(|i| eng.evaluate(&flying(i as f64 * 0.1), &state(None)))
        .collect();
    assert!(none.is_empty(), "{none:?}");
    // The margin dips under 0 for 1 s (debounce: no alert); then under 0 for 3 s (raised
    // once, after 2 s) and ±1.5 Wh for 17 s: never cleared (it must come back above 3 Wh).
    let mut events = Vec::new();
    for i in 0..10 {
        events.extend(eng.evaluate(&flying(5.0 + i as f64 * 0.1), &state(Some(-1.0))));
    }
    events.extend(eng.evaluate(&flying(6.0), &state(Some(5.0))));
    assert!(events.is_empty(), "a 1 s dip is debounced: {events:?}");
    for i in 0..200 {
        let m = if i < 30 {
            -1.0
        } else if i % 2 == 0 {
            -1.5
        } else {
            1.5
        };
        events.extend(eng.evaluate(&flying(7.0 + i as f64 * 0.1), &state(Some(m))));
    }
    assert_eq!(events.len(), 1, "{events:?}");
    assert_eq!(events[0].state, AlertState::Raised);
    assert!(
        (events[0].t - 9.0).abs() < 0.15,
        "raised 2 s after 7 s: {}",
        events[0].t
    );
    assert!(
        events[0]
            .message
            .starts_with("mission cannot finish with reserve"),
        "{}",
        events[0].message
    );
    let cleared: Vec<_> = eng.evaluate(&flying(30.0), &state(Some(3.5)));
    assert_eq!(cleared.len(), 1);
    assert_eq!(cleared[0].state, AlertState::Cleared);
}

#[test]
fn vehicle_voltage_below_follows_the_autopilots_own_threshold() {
    use dronewatt::report::{BatteryFacts, Provenance, Sourced};
    let mut eng = engine(
        r#"
        [[alerts]]
        name = "pack_low"
        kind = "vehicle_voltage_below"
        threshold = "low"
        margin_v = 0.2
        clear_margin_v = 0.4
        "#,
    );
    let at = |t: f64, v: f32| {
        let mut e = flying(t);
        e.sample.voltage_v = Some(v);
        e
    };
    // The vehicle has not said its threshold: quiet, whatever the voltage.
    assert!(eng
        .evaluate(&at(0.0, 10.0), &EnergyState::default())
        .is_empty());
    // BATT_LOW_VOLT = 14.4 V: raises under 14.6 V, clears from 14.8 V.
    let low = Sourced::new(14.4, Provenance::Parameter("BATT_LOW_VOLT".into()));
    let en = EnergyState {
        battery: BatteryFacts {
            low_voltage_v: Some(low),
            ..Default::default()
        }
        .into(),
        ..Default::default()
    };
    assert!(eng.evaluate(&at(1.0, 14.7), &en).is_empty());
    let raised = eng.evaluate(&at(2.0, 14.5), &en);
    assert_eq!(raised.len(), 1);
    assert_eq!(raised[0].state, AlertState::Raised);
    assert!(
        eng.evaluate(&at(3.0, 14.7), &en).is_empty(),
        "hysteresis: 14.7 V is not yet 14.8 V"
    );
    assert_eq!(
        eng.evaluate(&at(4.0, 14.9), &en)[0].state,
        AlertState::Cleared
    );
    // A clear margin on the wrong side names its key.
    let err = load_err("[[alerts]]\nname = \"x\"\nkind = \"vehicle_voltage_below\"\nthreshold = \"critical\"\nmargin_v = 0.5\nclear_margin_v = 0.1\n");
    assert!(err.contains("clear_margin_v"), "{err}");
}

#[test]
fn voltage_forecast_below_warns_before_the_sag_with_what_when_and_by_how_much() {
    use dronewatt::report::PackState;
    let mut eng = engine(
        r#"
        [[alerts]]
        name = "sag"
        kind = "voltage_forecast_below"
        clear_margin_v = 0.2
        "#,
    );
    let en = |v_min: Option<f64>, low: Option<f64>| EnergyState {
        pack: PackState {
            v_min_forecast_v: v_min,
            v_min_forecast_at_s: Some(185.0),
            low_threshold_v: low,
            ..Default::default()
        },
        ..Default::default()
    };
    // No forecast yet, or no threshold: quiet.
    assert!(eng.evaluate(&flying(0.0), &en(None, Some(21.0))).is_empty());
    assert!(eng.evaluate(&flying(1.0), &en(Some(20.0), None)).is_empty());
    assert!(eng
        .evaluate(&flying(2.0), &en(Some(21.3), Some(21.0)))
        .is_empty());
    // The final climb sags to 20.6 V, under the 21.0 V low threshold, in 3 min 5 s.
    let raised = eng.evaluate(&flying(3.0), &en(Some(20.6), Some(21.0)));
    assert_eq!(raised.len(), 1);
    assert_eq!(raised[0].state, AlertState::Raised);
    assert!(
        raised[0].message.contains("20.6V") && raised[0].message.contains("3:05"),
        "{}",
        raised[0].message
    );
    assert!(
        raised[0].message.len() <= 50,
        "a STATUSTEXT holds 50 bytes: {}",
        raised[0].message
    );
    assert!(
        eng.evaluate(&flying(4.0), &en(Some(21.1), Some(21.0)))
            .is_empty(),
        "hysteresis"
    );
    assert_eq!(
        eng.evaluate(&flying(5.0), &en(Some(21.3), Some(21.0)))[0].state,
        AlertState::Cleared
    );
    // An explicit level in volts, and a bad one named.
    let mut eng =
        engine("[[alerts]]\nname = \"s\"\nkind = \"voltage_forecast_below\"\nbelow_v = 22.0\n");
    assert_eq!(eng.evaluate(&flying(0.0), &en(Some(21.9), None)).len(), 1);
    let err =
        load_err("[[alerts]]\nname = \"x\"\nkind = \"voltage_forecast_below\"\nbelow_v = -1\n");
    assert!(err.contains("below_v"), "{err}");
}
