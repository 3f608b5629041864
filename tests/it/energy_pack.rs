//! The pack over a real socket: pymavlink (`tests/peers/vehicle.py --pack`) flies a small 3S
//! LiPo that rests on the ground, then sags as it drains; `dronewatt monitor` must read the
//! resting voltage as the start state and raise `voltage_forecast_below` before the measured
//! voltage crosses the low threshold (3.5 V a cell: 10.5 V).

use crate::link_common;

use link_common::*;

const CONFIG: &str = r#"
[energy]
capacity_wh = 4
cell_count = 3
chemistry = "lipo"

[[alerts]]
name = "sag"
kind = "voltage_forecast_below"
severity = "critical"
clear_margin_v = 0.3
"#;

#[test]
fn a_sagging_pack_warns_before_its_voltage_crosses_the_low_threshold() {
    // 3 s at rest (11.40 V: 40 % of a LiPo), then 20 s at 50 W ± 5 W (a small pack, worked hard:
    // it crosses 10.5 V about 12 s after take-off).
    let pack = r#"{"cells": 3, "wh": 4, "rest_v": 11.40, "r0": 0.12, "r1": 0.08, "tau_s": 10}"#;
    let r = fly(
        CONFIG,
        false,
        r#"[{"send_s": 3, "ground": true}, {"send_s": 20}]"#,
        &["--pack", pack, "--power-w", "50", "--power-swing-w", "5"],
    );
    assert_eq!(r.count("missed_reports"), 0, "{}", r.summary);

    // The start state is the resting voltage, not a full pack.
    let flying: Vec<_> = r
        .estimates
        .iter()
        .filter(|e| e["measured_w"].as_f64().is_some_and(|w| w > 20.0))
        .collect();
    let first = flying
        .first()
        .unwrap_or_else(|| panic!("no estimate in flight; dronewatt: {}", r.stderr));
    assert_eq!(first["remaining_source"], "resting voltage", "{first}");
    let rest = first["battery_rest_v"].as_f64().expect("a resting voltage");
    assert!((rest - 11.40).abs() < 0.05, "rest {rest} V");
    assert!(
        first["soc_pct"]
            .as_f64()
            .is_some_and(|s| (30.0..60.0).contains(&s)),
        "{first}"
    );

    // The measured voltage crosses 10.5 V during the flight …
    let crossed_at = flying
        .iter()
        .find(|e| e["battery_v"].as_f64().is_some_and(|v| v < 10.5))
        .map(|e| e["t"].as_f64().unwrap())
        .unwrap_or_else(|| {
            panic!(
                "the pack never sagged under 10.5 V; last: {}",
                flying.last().unwrap()
            )
        });
    // … and the alert came first, saying when.
    let raised = r
        .alerts
        .iter()
        .find(|a| a["rule"] == "sag" && a["state"] == "raised")
        .unwrap_or_else(|| {
            panic!(
                "voltage_forecast_below never raised: {:?}\n{}",
                r.alerts, r.stderr
            )
        });
    let raised_at = raised["t"].as_f64().unwrap();
    assert!(
        raised_at < crossed_at,
        "raised at {raised_at} s, the voltage crossed at {crossed_at} s"
    );
    let at_raise = flying
        .iter()
        .find(|e| e["t"].as_f64().unwrap() >= raised_at)
        .expect("an estimate at the alert");
    let to_low = at_raise["time_to_low_v_s"]
        .as_f64()
        .expect("a time to the low threshold");
    assert!(to_low > 0.0 && to_low < 600.0, "{at_raise}");
    assert!(
        at_raise["v_min_forecast_v"]
            .as_f64()
            .is_some_and(|v| v < 10.5),
        "{at_raise}"
    );
    assert!(
        at_raise["internal_r_ohm"].as_f64().is_some_and(|r| r > 0.0),
        "{at_raise}"
    );
    // The ground station heard it as a STATUSTEXT.
    let texts = r.peer["statustexts"].as_array().expect("statustexts");
    assert!(
        texts
            .iter()
            .any(|t| t.as_str().is_some_and(|t| t.starts_with("sag"))),
        "{texts:?}"
    );
}
