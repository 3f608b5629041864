//! NASA ProgPy as the independent pack (issue 44): `tests/peers/progpy_flights.py` builds
//! packs of ProgPy's 18650 electrochemistry cell and flies them; dronewatt, which was never
//! tuned on them, must not forecast the low-voltage crossing late.
//!
//! - A pymavlink vehicle over real UDP (`tests/peers/vehicle.py --progpy`) on a 3S ProgPy pack,
//!   rested at 35 %, hovering until it sags under 10.5 V (3.5 V a cell): `voltage_forecast_below`
//!   must be raised before the measured voltage crosses.
//! - The harness's quick flight (a 3S1P at 45 %, ~10 min to `BATT_LOW_VOLT`, written as an
//!   ArduPilot .tlog with ProgPy's truth beside it), replayed: the time to the low threshold
//!   forecast at 25, 50 and 75 % of the way is never more than 25 % too long.
//!   (The whole ProgPy table is `lab/scripts/battery/progpy_score.py`, too long for CI.)

use std::path::Path;
use std::process::Command;

use crate::harness::replay_json;
use crate::link_common;

use link_common::*;

const CONFIG: &str = r#"
[energy]
capacity_wh = 23
cell_count = 3
chemistry = "liion"

[[alerts]]
name = "sag"
kind = "voltage_forecast_below"
severity = "critical"
clear_margin_v = 0.3
"#;

#[test]
fn a_progpy_pack_over_udp_warns_before_its_voltage_crosses_the_low_threshold() {
    // 3 s at rest, then 30 s at 28 W ± 2 W: ProgPy's cell crosses 10.5 V about 18 s after
    // take-off (its surface empties under load).
    let r = fly(
        CONFIG,
        false,
        r#"[{"send_s": 3, "ground": true}, {"send_s": 30}]"#,
        &[
            "--progpy",
            r#"{"cell": "electrochem", "s": 3, "p": 1, "soc0": 0.35}"#,
            "--power-w",
            "28",
            "--power-swing-w",
            "2",
        ],
    );
    assert_eq!(r.count("missed_reports"), 0, "{}", r.summary);
    let flying: Vec<_> = r
        .estimates
        .iter()
        .filter(|e| e["measured_w"].as_f64().is_some_and(|w| w > 15.0))
        .collect();
    let first = flying
        .first()
        .unwrap_or_else(|| panic!("no estimate in flight; dronewatt: {}", r.stderr));
    assert_eq!(first["remaining_source"], "resting voltage", "{first}");
    let crossed_at = flying
        .iter()
        .find(|e| e["battery_v"].as_f64().is_some_and(|v| v < 10.5))
        .and_then(|e| e["t"].as_f64())
        .unwrap_or_else(|| panic!("never under 10.5 V; last: {:?}", flying.last()));
    let raised_at = r
        .alerts
        .iter()
        .find(|a| a["rule"] == "sag" && a["state"] == "raised")
        .and_then(|a| a["t"].as_f64())
        .unwrap_or_else(|| panic!("voltage_forecast_below never raised: {}", r.stderr));
    assert!(
        raised_at < crossed_at,
        "raised at {raised_at} s, the voltage crossed at {crossed_at} s"
    );
}

/// The latest `key` of an estimate at or before `t` (s on the log's clock).
fn at(est: &[serde_json::Value], t: f64, key: &str) -> Option<f64> {
    est.iter()
        .filter(|e| e["t"].as_f64().is_some_and(|te| te <= t + 1e-6))
        .filter_map(|e| e[key].as_f64())
        .next_back()
}

#[test]
fn the_progpy_quick_flight_is_never_forecast_late() {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = Command::new(root.join(".venv-py/bin/python"))
        .arg(root.join("tests/peers/progpy_flights.py"))
        .args(["--quick", "--out"])
        .arg(dir.path())
        .output()
        .expect("run .venv-py/bin/python (scripts/setup-python.sh creates it)");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let truth: serde_json::Value = serde_json::from_slice(
        &std::fs::read(dir.path().join("quick-ec-3s1p.truth.json")).unwrap(),
    )
    .unwrap();
    let cfg = dir.path().join("li.toml");
    std::fs::write(&cfg, "[energy]\nchemistry = \"liion\"\n").unwrap();
    let cfg = cfg.to_str().unwrap().to_string();
    let mut est: Vec<_> = replay_json(
        &dir.path().join("quick-ec-3s1p.tlog"),
        &["--data-dir", "off", "--config", &cfg],
    )
    .into_iter()
    .filter(|e| e["type"] == "estimate")
    .collect();
    // the JSON's clock starts at the log's first frame, the flight's first tick (0.1 s)
    for e in &mut est {
        let t = e["t"].as_f64().unwrap() + 0.1;
        e["t"] = t.into();
    }
    let (t0, tc) = (
        truth["t_takeoff"].as_f64().unwrap(),
        truth["t_cross"]
            .as_f64()
            .expect("the pack crossed BATT_LOW_VOLT"),
    );
    assert!(tc - t0 > 60.0, "{truth}");
    for q in [0.25, 0.5, 0.75] {
        let tq = t0 + q * (tc - t0);
        let left = tc - tq;
        let said = at(&est, tq, "time_to_low_v_s")
            .unwrap_or_else(|| panic!("no time to the low threshold at {q}"));
        assert!(
            said <= 1.25 * left,
            "at {q} of the way: forecast {said:.0} s, truth {left:.0} s (more than 25 % late)"
        );
    }
}
