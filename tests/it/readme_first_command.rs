//! The README's first command, as an operator runs it: `dronewatt monitor udpin:…` from `/`,
//! with no config, on a vehicle whose radio carries everything at 1 Hz (pymavlink,
//! `tests/peers/vehicle.py` with `rate_hz` 1) flying a small 3S pack down to its
//! `BATT_LOW_VOLT`: estimates through the flight, and a default alert before the crossing,
//! in `--json` and as a STATUSTEXT on the ground station.

use crate::harness::{dronewatt, json_lines, Monitor};
use crate::link_common::{free_udp_port, peer_then_stop};

#[test]
fn the_readme_first_command_from_slash_on_a_1_hz_vehicle_gives_estimates_and_alerts() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("out.jsonl");
    let port = free_udp_port();
    let dw = Monitor::listening(
        dronewatt()
            .current_dir("/")
            .env("XDG_CACHE_HOME", dir.path().join("cache"))
            .args([
                "monitor",
                &format!("udpin:127.0.0.1:{port}"),
                "-q",
                "--json",
            ])
            .arg(&json),
        port,
        false,
    );
    // 3 s at rest (11.40 V: 40 % of a 3S LiPo), then 24 s at 50 W, every message at 1 Hz.
    let pack = r#"{"cells": 3, "wh": 4, "rest_v": 11.40, "r0": 0.12, "r1": 0.08, "tau_s": 10}"#;
    let to = format!("udpout:127.0.0.1:{port}");
    let (peer, stderr) = peer_then_stop(
        dw,
        "vehicle.py",
        &[
            "--to",
            &to,
            "--plan",
            r#"[{"send_s": 3, "ground": true, "rate_hz": 1}, {"send_s": 24, "rate_hz": 1}]"#,
            "--pack",
            pack,
            "--power-w",
            "50",
            "--power-swing-w",
            "5",
            "--params",
            r#"{"BATT_LOW_VOLT": 10.5, "BATT_CRT_VOLT": 10.0, "BATT_CAPACITY": 360}"#,
        ],
    );
    let lines = json_lines(&json);
    let est: Vec<f64> = lines
        .iter()
        .filter(|l| l["type"] == "estimate")
        .filter(|l| l["models"].as_object().is_some_and(|m| !m.is_empty()))
        .filter_map(|l| l["t"].as_f64())
        .collect();
    assert!(est.len() >= 15, "{} estimates at 1 Hz: {stderr}", est.len());
    let crossed_at = lines
        .iter()
        .filter(|l| l["type"] == "estimate")
        .find(|e| e["battery_v"].as_f64().is_some_and(|v| v < 10.5))
        .and_then(|e| e["t"].as_f64())
        .unwrap_or_else(|| panic!("the pack never sagged under 10.5 V: {stderr}"));
    let raised: Vec<_> = lines
        .iter()
        .filter(|l| l["type"] == "alert" && l["state"] == "raised")
        .collect();
    let first = raised
        .iter()
        .filter_map(|a| a["t"].as_f64())
        .fold(f64::INFINITY, f64::min);
    assert!(
        first < crossed_at,
        "first alert at {first} s, the voltage crossed at {crossed_at} s: {raised:?}\n{stderr}"
    );
    let texts = peer["statustexts"].as_array().expect("statustexts");
    assert!(
        !texts.is_empty(),
        "no alert reached the ground station (raised {raised:?})"
    );
}
