//! The simulated plane and quadplane (`dronewatt simulate --vehicle plane|quadplane`) as a
//! user meets them: a quadplane's tlog replayed shows `vtol` and both phases with the right
//! models in each; a plane streamed over real UDP into `dronewatt monitor` gets fixed-wing
//! estimates; PX4's telemetry says the same; the energy used matches the simulator's truth.

use crate::harness::{dronewatt, monitor_udp, Monitor};

use serde_json::Value;

use crate::link_common;
use link_common::models;

/// `simulate ARGS --out DIR/NAME.tlog --truth DIR/NAME.csv`; returns the tlog and the truth
/// energy (Wh, from the CSV's 10 Hz power).
fn simulate(dir: &std::path::Path, name: &str, args: &[&str]) -> (std::path::PathBuf, f64) {
    let log = dir.join(format!("{name}.tlog"));
    let truth = dir.join(format!("{name}.csv"));
    let out = dronewatt()
        .arg("simulate")
        .args(args)
        .arg("--out")
        .arg(&log)
        .arg("--truth")
        .arg(&truth)
        .output()
        .expect("run dronewatt simulate");
    if !out.status.success() {
        panic!("simulate failed: {}", String::from_utf8_lossy(&out.stderr));
    }
    let text = std::fs::read_to_string(&truth).expect("truth CSV");
    let wh: f64 = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(2).unwrap().parse::<f64>().unwrap() * 0.1 / 3600.0)
        .sum();
    (log, wh)
}

/// `replay LOG --speed max --json -`: the estimate lines, the summary, stderr.
fn replay(log: &std::path::Path) -> (Vec<Value>, Value, String) {
    let out = dronewatt()
        .arg("replay")
        .arg(log)
        .args(["--speed", "max", "--json", "-"])
        .output()
        .expect("run dronewatt replay");
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(out.status.success(), "{stderr}");
    let (mut est, mut summary) = (Vec::new(), Value::Null);
    for l in String::from_utf8_lossy(&out.stdout).lines() {
        let v: Value = serde_json::from_str(l).unwrap_or_else(|e| panic!("{l}: {e}"));
        match v["type"].as_str() {
            Some("estimate") => est.push(v),
            Some("summary") => summary = v,
            _ => {}
        }
    }
    (est, summary, stderr)
}

#[test]
fn a_replayed_quadplane_shows_vtol_every_phase_in_order_and_each_phases_models() {
    let dir = tempfile::tempdir().unwrap();
    for autopilot in ["ardupilot", "px4"] {
        let (log, truth_wh) = simulate(
            dir.path(),
            autopilot,
            &[
                "--vehicle",
                "quadplane",
                "--autopilot",
                autopilot,
                "--leg-m",
                "500",
                "--hover-s",
                "20",
            ],
        );
        let (est, _, stderr) = replay(&log);
        assert!(est.len() > 1000, "{} estimates", est.len());
        // The order of the VTOL states, each run of windows once.
        let mut states: Vec<String> = Vec::new();
        for e in &est {
            assert_eq!(e["vehicle_class"], "vtol", "{autopilot}: {e}");
            let s = e["vtol_state"].as_str().unwrap_or("none").to_string();
            if states.last() != Some(&s) {
                states.push(s.clone());
            }
            let m = models(e);
            if s == "fw" {
                assert_eq!(m, ["fixed_wing"], "{autopilot}: {e}");
            } else if s != "undefined" {
                assert!(
                    m.contains(&"dandrea".to_string()) && !m.contains(&"fixed_wing".to_string()),
                    "{autopilot} {s}: {m:?}"
                );
            }
        }
        let states: Vec<&str> = states
            .iter()
            .map(String::as_str)
            .filter(|s| *s != "undefined")
            .collect();
        assert_eq!(
            states,
            ["mc", "transition_to_fw", "fw", "transition_to_mc", "mc"],
            "{autopilot}"
        );
        assert!(
            stderr.contains("vtol (fw) → vtol (transition_to_mc)"),
            "{stderr}"
        );
        // In forward flight the adapted fixed-wing model is near the measured power.
        let fw: Vec<&Value> = est.iter().filter(|e| e["vtol_state"] == "fw").collect();
        let tail = &fw[fw.len() / 2..];
        let mean = |k: &str| {
            tail.iter()
                .map(|e| e[k]["fixed_wing"].as_f64().unwrap())
                .sum::<f64>()
                / tail.len() as f64
        };
        let measured = tail
            .iter()
            .map(|e| e["measured_w"].as_f64().unwrap())
            .sum::<f64>()
            / tail.len() as f64;
        let adapted = mean("adapted");
        assert!(
            (adapted - measured).abs() < 0.1 * measured,
            "{autopilot}: adapted {adapted:.1} W, measured {measured:.1} W in FW"
        );
        // Its own pack from BATT_CAPACITY / BAT1_CAPACITY (4S 8000 mAh), never the M100's.
        let last = est.last().unwrap();
        let cap = last["capacity_wh"].as_f64().unwrap();
        assert!((cap - 118.4).abs() < 0.5, "{autopilot}: capacity {cap} Wh");
        let used = last["energy_used_wh"].as_f64().unwrap();
        assert!(
            (used - truth_wh).abs() < 0.02 * truth_wh,
            "{autopilot}: used {used} Wh, truth {truth_wh} Wh"
        );
    }
}

#[test]
fn a_simulated_plane_over_udp_into_monitor_gets_fixed_wing_estimates() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("out.jsonl");
    let port = link_common::free_udp_port();
    let dw = Monitor::listening(monitor_udp(port).arg("--json").arg(&json), port, false);
    // A ~80 s flight at 4× real time (the live chain makes its windows on the arrival clock).
    let sim = dronewatt()
        .args([
            "simulate",
            "--vehicle",
            "plane",
            "--udp",
            &format!("127.0.0.1:{port}"),
        ])
        .args(["--rate", "4", "--leg-m", "250", "--hover-s", "0"])
        .output()
        .expect("run dronewatt simulate");
    assert!(
        sim.status.success(),
        "{}",
        String::from_utf8_lossy(&sim.stderr)
    );
    std::thread::sleep(std::time::Duration::from_millis(300));
    let (status, stderr) = dw.stop();
    assert!(status.success(), "{stderr}");
    let est: Vec<Value> = std::fs::read_to_string(&json)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<Value>(l).unwrap())
        .filter(|v| v["type"] == "estimate")
        .skip_while(|e| e.get("mav_type").is_none())
        .collect();
    assert!(est.len() > 120, "{} estimates; {stderr}", est.len());
    for e in &est {
        assert_eq!(e["vehicle_class"], "fixed_wing", "{e}");
        assert_eq!(models(e), ["fixed_wing"], "{e}");
        assert_eq!(e["forecast_model"], "fixed_wing", "{e}");
    }
    assert!(stderr.contains("vehicle class: fixed_wing"), "{stderr}");
    // Cruising (the motor running, in the air): the adapted model on the plane's scale of
    // power over the second half of this short flight (the accuracy is measured on longer
    // ones: docs/src/vehicle-types.md), and its pack from BATT_CAPACITY (3S 4000 mAh = 44.4 Wh).
    let cruise: Vec<&Value> = est
        .iter()
        .filter(|e| {
            e["measured_w"].as_f64().unwrap_or(0.0) > 20.0
                && e["measured_w"].as_f64().unwrap_or(0.0) < 120.0
        })
        .collect();
    let tail = &cruise[cruise.len() / 2..];
    let mean =
        |f: &dyn Fn(&Value) -> f64| tail.iter().map(|e| f(e)).sum::<f64>() / tail.len() as f64;
    let adapted = mean(&|e| e["adapted"]["fixed_wing"].as_f64().unwrap());
    let measured = mean(&|e| e["measured_w"].as_f64().unwrap());
    assert!(
        (adapted - measured).abs() < 0.25 * measured,
        "adapted {adapted:.1} W, measured {measured:.1} W"
    );
    let cap = est.last().unwrap()["capacity_wh"].as_f64().unwrap();
    assert!((cap - 44.4).abs() < 0.5, "capacity {cap} Wh");
}

#[test]
fn a_px4_plane_is_fixed_wing_and_its_energy_matches_the_simulators_truth() {
    let dir = tempfile::tempdir().unwrap();
    let (log, truth_wh) = simulate(
        dir.path(),
        "px4-plane",
        &[
            "--vehicle",
            "plane",
            "--autopilot",
            "px4",
            "--leg-m",
            "500",
            "--hover-s",
            "30",
            "--wind-mps",
            "6",
        ],
    );
    let (est, _, stderr) = replay(&log);
    assert!(
        stderr.contains("vehicle class: fixed_wing (HEARTBEAT type FIXED_WING (1))"),
        "{stderr}"
    );
    assert!(est
        .iter()
        .skip(20)
        .all(|e| e["vehicle_class"] == "fixed_wing" && models(e) == ["fixed_wing"]));
    let used = est.last().unwrap()["energy_used_wh"].as_f64().unwrap();
    assert!(
        (used - truth_wh).abs() < 0.02 * truth_wh,
        "used {used} Wh, truth {truth_wh} Wh"
    );
}

#[test]
fn learn_fits_the_fixed_wing_model_from_plane_logs_and_scores_it_held_out() {
    // Three simulated plane flights (other seeds and payloads); learn fits on two, scores the
    // third. The plane's logs have no rotor windows: the multirotor fit is skipped, not failed.
    let dir = tempfile::tempdir().unwrap();
    let logs = dir.path().join("logs");
    std::fs::create_dir(&logs).unwrap();
    for (i, payload) in ["0", "300", "150"].iter().enumerate() {
        let seed = (31 + i).to_string();
        simulate(
            &logs,
            &format!("f{i}"),
            &[
                "--vehicle",
                "plane",
                "--seed",
                &seed,
                "--payload-g",
                payload,
                "--leg-m",
                "600",
                "--hover-s",
                "30",
            ],
        );
    }
    let out_dir = dir.path().join("learned");
    let out = dronewatt()
        .arg("learn")
        .arg(&logs)
        .args([
            "--vehicle",
            "plane",
            "--holdout-every",
            "3",
            "--data-dir",
            "off",
            "--out",
        ])
        .arg(&out_dir)
        .output()
        .expect("run dronewatt learn");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    // The held-out table's fixed_wing row: published → learned, the learned one better.
    let row = stdout
        .lines()
        .find(|l| l.starts_with("| fixed_wing |"))
        .unwrap_or_else(|| panic!("no fixed_wing row: {stdout}"));
    let cells: Vec<f64> = row
        .split('|')
        .filter_map(|c| c.trim().parse().ok())
        .collect();
    assert!(
        cells[1] < cells[0],
        "MAPE published {} → learned {}: {row}",
        cells[0],
        cells[1]
    );
    assert!(stdout.contains("forecast model: fixed_wing"), "{stdout}");
    // The learned figures in the profile's [fixed_wing], within its ranges, the geometry kept.
    let p = dronewatt::model::profile::VehicleProfile::load(&out_dir.join("profile.toml")).unwrap();
    let shipped = dronewatt::model::profile::VehicleProfile::named_or_file("plane").unwrap();
    let (fw, fw0) = (p.fixed_wing.unwrap(), shipped.fixed_wing.unwrap());
    assert_eq!(
        (fw.wing_area_m2, fw.span_m, fw.mass_kg),
        (fw0.wing_area_m2, fw0.span_m, fw0.mass_kg)
    );
    assert_ne!(fw, fw0, "nothing was fitted");
    assert!(fw.validate().is_ok());
    assert!(stderr.contains("fixed_wing fitted"), "{stderr}");
}
