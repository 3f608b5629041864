//! The vehicle's own battery parameters, end to end with independent peers:
//!
//! - live: pymavlink plays an ArduPilot or a PX4 autopilot (`tests/peers/vehicle_params.py`)
//!   that answers PARAM_REQUEST_READ in its firmware's encoding, drops the first capacity
//!   request and does not have one of the parameters; `dronewatt monitor` must ask again,
//!   give up on the missing one, and size the battery from the answers.
//! - replay: a `.tlog` written by pymavlink (`tests/peers/param_tlog.py`) carrying the ground
//!   station's logged PARAM_VALUE: remaining energy follows the vehicle's capacity, and says
//!   so; without the PARAM_VALUEs, or with `capacity_wh` in the config, it says that instead.

use crate::harness::{dronewatt, json_lines, monitor_udp, Monitor, RunExt};
use crate::link_common::{self, free_udp_port};
use std::process::Command;

const PYTHON: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/.venv-py/bin/python");

fn peer(name: &str) -> String {
    format!("{}/tests/peers/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn last_estimate(lines: &[serde_json::Value]) -> &serde_json::Value {
    lines
        .iter()
        .rev()
        .find(|l| l["type"] == "estimate")
        .expect("no estimate line")
}

/// Run `dronewatt monitor` against the pymavlink autopilot; (peer's JSON, dronewatt's
/// JSON lines, dronewatt's stderr).
fn monitor(autopilot: &str) -> (serde_json::Value, Vec<serde_json::Value>, String) {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("out.jsonl");
    let port = free_udp_port();
    let dw = Monitor::listening(monitor_udp(port).arg("--json").arg(&json), port, false);
    let port = port.to_string();
    let args = ["--port", &port, "--autopilot", autopilot];
    let (heard, err) = link_common::peer_then_stop(dw, "vehicle_params.py", &args);
    (heard, json_lines(&json), err)
}

#[test]
fn ardupilot_parameters_size_the_battery_over_a_live_link() {
    let (heard, lines, err) = monitor("ardupilot");
    let req = &heard["requests"];
    // The dropped capacity request was sent again, and answered the second time.
    assert_eq!(
        heard["dropped"],
        serde_json::json!(["BATT_CAPACITY"]),
        "{heard}"
    );
    assert_eq!(req["BATT_CAPACITY"], 2, "{heard}");
    // A parameter this vehicle lacks: asked the bounded number of times, then given up.
    assert_eq!(req["BATT_CRT_MAH"], 3, "{heard}");
    assert!(
        err.contains("BATT_CRT_MAH") && err.contains("did not answer"),
        "{err}"
    );
    assert!(req["AUTOPILOT_VERSION"].as_u64().unwrap() >= 1, "{heard}");
    // 3300 mAh × 3 cells (MOT_BAT_VOLT_MAX 12.6 V = 3 × 4.2: a LiPo) × 3.7 V = 36.63 Wh, from
    // the vehicle.
    let e = last_estimate(&lines);
    assert_eq!(
        e["capacity_source"], "vehicle parameter BATT_CAPACITY",
        "{e}"
    );
    assert!(
        (e["capacity_wh"].as_f64().unwrap() - 36.63).abs() < 1e-6,
        "{e}"
    );
    assert_eq!(
        (e["cell_count"].as_u64(), e["cell_count_source"].as_str()),
        (Some(3), Some("vehicle parameter MOT_BAT_VOLT_MAX")),
        "{e}"
    );
    assert_eq!(
        (e["chemistry"].as_str(), e["chemistry_source"].as_str()),
        (Some("lipo"), Some("vehicle parameter MOT_BAT_VOLT_MAX")),
        "{e}"
    );
    // No rest is read: the pack starts load-compensated a few seconds in (full, here) and
    // counts on from there.
    let remaining = e["remaining_wh"].as_f64().unwrap();
    let used = e["energy_used_wh"].as_f64().unwrap();
    assert_eq!(e["remaining_source"], "load-compensated voltage", "{e}");
    assert!(
        remaining <= 36.63 - used + 1e-6 && remaining > 36.63 - used - 1.0,
        "{e}"
    );
}

#[test]
fn px4_packed_integers_decode_over_a_live_link() {
    let (heard, lines, _) = monitor("px4");
    assert_eq!(heard["requests"]["BAT1_CAPACITY"], 2, "{heard}");
    // BAT1_N_CELLS = 4 arrives packed into the float's bits; cast it would read 5.6e-45.
    let e = last_estimate(&lines);
    assert_eq!(
        (e["cell_count"].as_u64(), e["cell_count_source"].as_str()),
        (Some(4), Some("vehicle parameter BAT1_N_CELLS")),
        "{e}"
    );
    assert_eq!(
        e["capacity_source"], "vehicle parameter BAT1_CAPACITY",
        "{e}"
    );
    assert!(
        (e["capacity_wh"].as_f64().unwrap() - 5.0 * 4.0 * 3.7).abs() < 1e-6,
        "{e}"
    );
}

/// Replay a pymavlink-written tlog (with or without the logged PARAM_VALUEs) with this
/// config; the JSON lines.
fn replay(with_params: bool, config: &str) -> Vec<serde_json::Value> {
    let dir = tempfile::tempdir().unwrap();
    let tlog = dir.path().join("flight.tlog");
    let mut cmd = Command::new(PYTHON);
    cmd.arg(peer("param_tlog.py")).arg("--out").arg(&tlog);
    if !with_params {
        cmd.arg("--no-params");
    }
    let out = cmd.output().expect("run .venv-py/bin/python");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let cfg = dir.path().join("c.toml");
    std::fs::write(&cfg, config).unwrap();
    let json = dir.path().join("out.jsonl");
    let _out = dronewatt()
        .args(["replay", "--speed", "max", "-q", "--config"])
        .arg(&cfg)
        .arg("--json")
        .arg(&json)
        .arg(&tlog)
        .ok();
    json_lines(&json)
}

#[test]
fn a_replayed_tlog_takes_the_logged_capacity() {
    // 60 s at 150 W: 2.5 Wh used.
    let with = replay(true, "");
    let e = last_estimate(&with);
    assert_eq!(
        e["capacity_source"], "vehicle parameter BATT_CAPACITY",
        "{e}"
    );
    let used = e["energy_used_wh"].as_f64().unwrap();
    assert!((used - 2.5).abs() < 0.1, "{e}");
    // Load-compensated (no rest in this log): to the usable floor over BATT_LOW_VOLT, never
    // more than the capacity less what was used.
    let remaining = e["remaining_wh"].as_f64().unwrap();
    assert!(
        remaining <= 36.63 - used + 1e-6 && remaining > 36.63 - used - 3.0,
        "{e}"
    );
    // The same flight without the parameter fetch: the capacity is not known (never the
    // M100's pack), remaining energy is null, and it says why.
    let without = replay(false, "");
    let e = last_estimate(&without);
    assert!(e["capacity_wh"].is_null(), "{e}");
    assert!(
        e["capacity_source"]
            .as_str()
            .is_some_and(|s| s.starts_with("not known")),
        "{e}"
    );
    assert!(e["remaining_wh"].is_null(), "{e}");
    assert_eq!(e["remaining_source"], "capacity not known", "{e}");
    assert!(
        (e["energy_used_wh"].as_f64().unwrap() - used).abs() < 0.01,
        "{e}"
    );
    // The config wins over the vehicle.
    let configured = replay(true, "[energy]\ncapacity_wh = 50\n");
    let e = last_estimate(&configured);
    assert_eq!(
        (e["capacity_wh"].as_f64(), e["capacity_source"].as_str()),
        (Some(50.0), Some("config")),
        "{e}"
    );
}
