//! The pack over a real socket: pymavlink (`tests/peers/vehicle.py --pack`) flies a small 3S
//! LiPo that rests on the ground, then sags as it drains; `dronewatt monitor` must read the
//! resting voltage as the start state and raise `voltage_forecast_below` before the measured
//! voltage crosses the low threshold (3.5 V a cell: 10.5 V).

use crate::harness::{dronewatt, monitor_udp, Monitor, RunExt};
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

/// One `dronewatt monitor` run with the vehicle store in `data_dir`: the peer flies `plan`
/// with `peer_args`; the estimates with models.
fn fly_stored(
    data_dir: &std::path::Path,
    plan: &str,
    peer_args: &[&str],
) -> Vec<serde_json::Value> {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("dw.toml");
    std::fs::write(&cfg, CONFIG).unwrap();
    let json = dir.path().join("out.jsonl");
    let port = free_udp_port();
    let dw = Monitor::listening(
        monitor_udp(port)
            .arg("--config")
            .arg(&cfg)
            .arg("--data-dir")
            .arg(data_dir)
            .arg("--json")
            .arg(&json)
            .env("RUST_LOG", "dronewatt=info"),
        port,
        false,
    );
    let to = format!("udpout:127.0.0.1:{port}");
    let args: Vec<&str> = ["--to", &to, "--plan", plan]
        .into_iter()
        .chain(peer_args.iter().copied())
        .collect();
    let (_, stderr) = peer_then_stop(dw, "vehicle.py", &args);
    let text = std::fs::read_to_string(&json).unwrap();
    let est: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|v| v["type"] == "estimate" && v["battery_rest_v"].is_number())
        .collect();
    assert!(!est.is_empty(), "no start state read; dronewatt: {stderr}");
    est
}

/// Pack health per pack over a real socket: the vehicle identifies its pack (BATTERY_INFO
/// `serial_number`, `vehicle.py --pack-serial`). Pack A flies, then pack B on the same
/// vehicle moments later: B never flew here, so nothing carries over to it (per vehicle, the
/// last flight so soon would have). Pack A again carries over from A's own flight, past B's;
/// a run with no identity falls back to the vehicle's last flight (the gap rule).
/// `dronewatt vehicles` lists each pack's flights in a row of its own.
#[test]
fn the_pack_history_follows_the_packs_serial() {
    let store = tempfile::tempdir().unwrap();
    let pack = r#"{"cells": 3, "wh": 4, "rest_v": 11.40, "r0": 0.12, "r1": 0.08, "tau_s": 10}"#;
    let plan = r#"[{"send_s": 3, "ground": true}, {"send_s": 6}, {"send_s": 3, "ground": true}]"#;
    let base = ["--pack", pack, "--power-w", "50", "--power-swing-w", "5"];
    let carried = |serial: Option<&str>| {
        let mut args = base.to_vec();
        match serial {
            Some(s) => args.extend(["--pack-serial", s]),
            // No BATTERY_INFO: it answers its parameter reads, as an autopilot does, with the
            // capacity its BATTERY_INFO gave on the runs before (vehicle.py's 6S 5700 mAh),
            // so the store's lookup, which waits for what the vehicle says of its pack (or
            // 5 s: `vehicle::store::lookup_due`), finds the same vehicle at once.
            None => args.extend(["--params", r#"{"BATT_CAPACITY": 5700}"#]),
        }
        let est = fly_stored(store.path(), plan, &args);
        est.iter()
            .any(|e| e["pack_carried_over"].as_bool() == Some(true))
    };
    assert!(!carried(Some("A-0001")), "the store was empty");
    assert!(
        !carried(Some("B-0002")),
        "pack B never flew on this vehicle"
    );
    assert!(
        carried(Some("A-0001")),
        "pack A's own last flight carries over"
    );
    assert!(
        carried(None),
        "no identity: the vehicle's last flight, moments ago"
    );

    let out = dronewatt()
        .args(["vehicles", "--data-dir"])
        .arg(store.path())
        .out();
    assert!(out.status.success());
    let listing = String::from_utf8_lossy(&out.stdout);
    assert!(
        listing.contains("pack A-0001 (2 flight(s))")
            && listing.contains("pack B-0002 (1 flight(s))")
            && listing.contains("pack (per vehicle: no pack id heard)"),
        "{listing}"
    );
    let out = dronewatt()
        .args(["vehicles", "--json", "--data-dir"])
        .arg(store.path())
        .out();
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let ids: Vec<_> = v[0]["flights"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["pack_id"].as_str())
        .collect();
    assert_eq!(ids, [Some("A-0001"), Some("B-0002"), Some("A-0001"), None]);
}
