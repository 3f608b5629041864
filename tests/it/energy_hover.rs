//! The first hover calibrates, live (`energy::hover`): the `multirotor` package's Tarot T18
//! (`scripts/peer-multirotor.py --quick`: its motors' current, a pymavlink .tlog with the
//! mission as a ground station logs it) is the vehicle, described by its spec sheet with
//! the hover-efficiency prior fitted on the other airframes (the T18 held out). Replayed,
//! and sent in real time over a real UDP socket to `monitor` by a pymavlink vehicle
//! (`tests/peers/tlog_udp.py`): after the first hover the remaining mission's forecast is
//! the vehicle's, the store keeps the calibrated profile, and `plan --vehicle <key>` uses
//! it.

use std::path::Path;
use std::process::Command;

use serde_json::Value;

use crate::harness::{dronewatt, json_lines, monitor_udp, peer, Monitor, RunExt};

/// The peer T18's quick flight (a 300 m hop after a 30 s hover) into `dir/t18`; its JSON summary.
fn peer_flight(dir: &Path) -> Value {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let json = dir.join("peer.json");
    let out = Command::new(root.join(".venv-py/bin/python"))
        .arg(root.join("scripts/peer-multirotor.py"))
        .args([
            "--quick",
            "--airframe",
            "t18",
            "--bin",
            env!("CARGO_BIN_EXE_dronewatt"),
            "--json",
        ])
        .arg(&json)
        .arg("--out")
        .arg(dir)
        .output()
        .expect("run .venv-py/bin/python (scripts/setup-python.sh creates it)");
    assert!(
        out.status.success(),
        "peer-multirotor.py: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    v["airframes"]["t18"].clone()
}

/// The stored vehicle's key and profile path (`dronewatt vehicles --json`).
fn stored(store: &Path) -> (String, String) {
    let out = dronewatt()
        .args(["vehicles", "--json", "--data-dir"])
        .arg(store)
        .ok();
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    let key = v[0]["key"].as_str().unwrap_or_default().to_string();
    let path = v[0]["profile"]["path"]
        .as_str()
        .unwrap_or_default()
        .to_string();
    (key, path)
}

#[test]
fn the_first_hover_calibrates_the_live_forecast_and_the_store_keeps_it() {
    let dir = tempfile::tempdir().unwrap();
    let r = peer_flight(dir.path());
    let f = &r["flights"][0];
    let truth = f["truth_wh"].as_f64().unwrap();
    // The replay (`--data-dir` a store of its own), as the harness scored it.
    let live = f["stages"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["stage"] == "live")
        .unwrap_or_else(|| panic!("no live stage: {f}"));
    assert_eq!(live["calibrated"], true, "{live}");
    let cal = &live["hover"];
    // the T18's own η_h (0.78 at the package's constants), against a prior of 0.37
    let eta = cal["eta_h"].as_f64().unwrap();
    assert!((0.7..0.85).contains(&eta), "{cal}");
    assert!(cal["prior_eta_h"].as_f64().unwrap() < 0.45, "{cal}");
    assert!(cal["hover_s"].as_f64().unwrap() >= 15.0, "{cal}");
    assert_eq!(cal["applied"], true, "{cal}");
    // The remaining mission's forecast, against what the peer still drew from then on:
    // far off on the priors, within 15 % after the hover.
    let before = live["before_err_pct"].as_f64().unwrap();
    let after = live["after_err_pct"].as_f64().unwrap();
    assert!(before > 50.0, "{live}");
    assert!(after.abs() <= 15.0 && after.abs() < before.abs(), "{live}");
    // The store kept the calibrated profile; `plan --vehicle <key>` forecasts with it.
    assert!(
        live["stored_profile"]["path"]
            .as_str()
            .is_some_and(|p| p.ends_with("-hover.toml")),
        "{live}"
    );
    assert!(live["err_pct"].as_f64().unwrap().abs() <= 10.0, "{live}");
    assert!(live["p90"].as_f64().unwrap() >= truth, "{live}");

    // Live: the same flight from a pymavlink vehicle over UDP, in real time, up to 50 s
    // (the climb, the 30 s hover, the start of the first leg).
    let spec = dir.path().join("t18/flight0-spec.toml");
    let store = dir.path().join("udp-store");
    let json = dir.path().join("udp.jsonl");
    let port = std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let mon = Monitor::listening(
        monitor_udp(port)
            .args(["--listen-only", "--vehicle"])
            .arg(&spec)
            .arg("--json")
            .arg(&json)
            .arg("--data-dir")
            .arg(&store),
        port,
        false,
    );
    let tlog = dir.path().join("t18/flight0.tlog");
    let port_s = port.to_string();
    let sent = peer(
        "tlog_udp.py",
        [
            "--tlog",
            tlog.to_str().unwrap(),
            "--port",
            &port_s,
            "--until-s",
            "50",
        ],
    );
    std::thread::sleep(std::time::Duration::from_millis(500));
    let (status, stderr) = mon.stop();
    assert!(status.success(), "{stderr}");
    let est: Vec<Value> = json_lines(&json)
        .into_iter()
        .filter(|v| v["type"] == "estimate")
        .collect();
    let first = est
        .iter()
        .position(|e| e["hover_calibration"].is_object())
        .unwrap_or_else(|| {
            panic!(
                "no calibration in {} estimates ({}): {stderr}",
                est.len(),
                String::from_utf8_lossy(&sent)
            )
        });
    let c = &est[first]["hover_calibration"];
    let udp_eta = c["eta_h"].as_f64().unwrap();
    assert!((udp_eta / eta - 1.0).abs() < 0.02, "{c} against {cal}");
    let mission = |e: &Value| e["mission_energy_wh"].as_f64();
    let before_wh = est[..first]
        .iter()
        .rev()
        .find_map(mission)
        .expect("a mission forecast before the hover");
    let after_wh = est[first..]
        .iter()
        .find_map(mission)
        .expect("a mission forecast after it");
    // What the peer drew after the hover (the replay's truth at the same point of the log).
    let left = live["truth_left_after"].as_f64().unwrap();
    assert!(before_wh / left > 1.5, "{before_wh} Wh against {left} Wh");
    assert!(
        (after_wh / left - 1.0).abs() <= 0.15,
        "{after_wh} Wh against {left} Wh"
    );
    // The store kept it, and `plan --vehicle <key>` uses it.
    let (key, path) = stored(&store);
    assert!(path.ends_with("-hover.toml"), "{key}: {path}");
    let plan = dir.path().join("t18/flight0.waypoints");
    let out = dronewatt()
        .arg("plan")
        .arg(&plan)
        .args([
            "--vehicle",
            &key,
            "--speed",
            "6",
            "--json",
            "-",
            "--data-dir",
        ])
        .arg(&store)
        .ok();
    let p: Value = serde_json::from_slice(&out.stdout).unwrap();
    let p50 = p["forecast"]["energy_p50_wh"].as_f64().unwrap();
    assert!(
        (p50 / truth - 1.0).abs() <= 0.10,
        "{p50} Wh against {truth} Wh: {p}"
    );
}

/// A spec sheet of the five facts in `dir` (`NAME.toml`): four 10-inch propellers and a LiPo
/// of `cells` cells and `mah` mAh on a vehicle of `kg` at take-off.
fn five_facts(dir: &Path, name: &str, kg: f64, cells: u32, mah: u32) -> std::path::PathBuf {
    let spec = dir.join(format!("{name}.toml"));
    std::fs::write(
        &spec,
        format!(
            "name = \"{name}\"\n[vehicle]\ntakeoff_kg = {kg:?}\nrotors = 4\nprop_diameter_m = 0.254\n\
             [battery]\ncells = {cells}\ncapacity_mah = {mah}\nchemistry = \"lipo\"\n"
        ),
    )
    .unwrap();
    spec
}

/// The simulated X500 (`simulate --vehicle x500 --payload-g 0 SIM_ARGS`) replayed with
/// `--vehicle` its five-fact spec sheet (2 kg, four 10-inch propellers, 4S 5 Ah LiPo),
/// logging at info: the replay's output.
fn x500_from_its_spec_sheet(sim_args: &[&str]) -> std::process::Output {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("x500.tlog");
    dronewatt()
        .args(["simulate", "--vehicle", "x500", "--payload-g", "0"])
        .args(sim_args)
        .arg("--out")
        .arg(&log)
        .ok();
    let spec = five_facts(dir.path(), "X500 spec", 2.0, 4, 5000);
    dronewatt()
        .env("RUST_LOG", "info")
        .args([
            "replay",
            "--speed",
            "max",
            "--json",
            "-",
            "--data-dir",
            "off",
        ])
        .arg("--vehicle")
        .arg(&spec)
        .arg(&log)
        .ok()
}

#[test]
fn a_vehicle_that_never_hovers_is_not_calibrated_and_says_so() {
    // The simulated X500 climbs and flies straight off (no hover item): no 15 s of still
    // hover in its first 180 s airborne.
    let out = x500_from_its_spec_sheet(&[
        "--seed",
        "3",
        "--wind-mps",
        "4",
        "--hover-s",
        "0",
        "--leg-m",
        "1500",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("first hover: no hover of 15 s in the first 180 s airborne"),
        "{stderr}"
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        !text.contains("hover_calibration"),
        "calibrated without a hover"
    );
}

#[test]
fn the_hover_throttle_and_the_packs_power_calibrate_before_a_full_hover() {
    // The simulated X500 (ArduPilot's MOT_THST_HOVER 0.5; its VFR_HUD throttle 50 % in a
    // hover) hovers 20 s: at the hover throttle for 10 s, before the still hover's 30 s.
    let out = x500_from_its_spec_sheet(&["--seed", "5", "--hover-s", "20", "--leg-m", "300"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("at the hover throttle (MOT_THST_HOVER 50 %)"),
        "{stderr}"
    );
    let cal = crate::harness::json_lines_of(&out.stdout)
        .into_iter()
        .find_map(|v| {
            v.get("hover_calibration")
                .filter(|c| c.is_object())
                .cloned()
        })
        .expect("a hover calibration");
    assert_eq!(cal["source"], "MOT_THST_HOVER", "{cal}");
    let (w, s) = (
        cal["hover_w"].as_f64().unwrap(),
        cal["hover_s"].as_f64().unwrap(),
    );
    assert!((10.0..12.0).contains(&s), "{cal}");
    // the simulator's X500 hovers at 284 W (its book row), avionics included
    assert!((w / 284.0 - 1.0).abs() < 0.1, "{cal}");
}

#[test]
fn a_hover_measured_with_a_payload_calibrates_plan_as_the_live_first_hover_does() {
    // The five facts' quad (1.3 kg on four 10-inch propellers). One vehicle, η_h 0.45 at its
    // take-off mass, seen twice: hovering empty at P0 and with 500 g on board at P1
    // (momentum theory: ideal power × (m/1.3)^1.5 / η + 8 W avionics, η growing with the
    // disk loading as the spec sheet's prior says, × (m/1.3)^0.2572). `plan --hover-w P1 --payload-g 500`
    // (the hover flown with the plan's payload) and `--hover-w P0 --hover-payload-g 0` must
    // find the same vehicle: before, `--hover-w` took any hover as the empty mass's and read
    // P1 as a poorer efficiency, forecasting the loaded plan ~48 % high.
    let dir = tempfile::tempdir().unwrap();
    let spec = five_facts(dir.path(), "Spec quad", 1.3, 3, 5100);
    let area = 4.0 * std::f64::consts::PI * 0.127f64.powi(2);
    let eta = |kg: f64| 0.45 * (kg / 1.3f64).powf(0.2572);
    let hover = |kg: f64| (kg * 9.81f64).powf(1.5) / (2.0 * 1.225 * area).sqrt() / eta(kg) + 8.0;
    let plan = Path::new(env!("CARGO_MANIFEST_DIR")).join("replay/demo.plan");
    let p50 = |hover_w: f64, hover_payload_g: &str| -> (f64, String) {
        let out = dronewatt()
            .arg("plan")
            .arg(&plan)
            .arg("--vehicle")
            .arg(&spec)
            .args(["--payload-g", "500", "--speed", "8", "--json", "-"])
            .args(["--hover-w", &format!("{hover_w:.3}")])
            .args(["--hover-payload-g", hover_payload_g, "--data-dir", "off"])
            .ok();
        let p: Value = serde_json::from_slice(&out.stdout).unwrap();
        let wh = p["forecast"]["energy_p50_wh"].as_f64().unwrap();
        (wh, p.to_string())
    };
    let (loaded, said) = p50(hover(1.8), "500");
    let (empty, _) = p50(hover(1.3), "0");
    assert!(
        (loaded / empty - 1.0).abs() < 0.005,
        "a hover at 1.8 kg {loaded} Wh, the same vehicle's at 1.3 kg {empty} Wh"
    );
    assert!(said.contains("with 0.50 kg of payload"), "{said}");
    // The empty hover's power taken as a loaded one is not this vehicle: a poorer P50 is not
    // what it is, the loaded hover 48 % more power than the empty one.
    let (misread, _) = p50(hover(1.3), "500");
    assert!(misread < 0.8 * loaded, "{misread} Wh against {loaded} Wh");
}
