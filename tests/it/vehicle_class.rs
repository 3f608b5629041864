//! The vehicle class over a real link: `dronewatt monitor` on a loopback UDP port, a
//! pymavlink vehicle (`tests/peers/vehicle.py`) whose HEARTBEAT says what it is. A
//! submarine, a plane and a type MAVLink does not define get no multirotor model and never
//! the M100's pack; a quadrotor with no battery monitor gets its remaining energy from the
//! model's power, said so.

use crate::harness::{dronewatt, RunExt};
use crate::link_common;
use link_common::models;

use link_common::{fly, Run};
use serde_json::Value;

/// The estimate lines made after the first HEARTBEAT (the class is known from then on).
fn after_heartbeat(r: &Run) -> Vec<&Value> {
    let lines: Vec<&Value> = r
        .all_estimates
        .iter()
        .skip_while(|e| e.get("mav_type").is_none())
        .collect();
    assert!(
        lines.len() >= 30,
        "{} estimates after the HEARTBEAT; dronewatt: {}",
        lines.len(),
        r.stderr
    );
    lines
}

#[test]
fn a_submarine_gets_the_one_line_reason_and_measured_power_only() {
    let r = fly("", false, r#"[{"send_s": 6}]"#, &["--mav-type", "12"]);
    let line = "no power model for a SUBMARINE: estimates from measured power only";
    assert_eq!(r.stderr.matches(line).count(), 1, "{}", r.stderr);
    let lines = after_heartbeat(&r);
    for e in &lines {
        assert_eq!(e["vehicle_class"], "other", "{e}");
        assert_eq!(e["mav_type"], 12, "{e}");
        assert!(models(e).is_empty(), "a model ran on a submarine: {e}");
        // No pack configured or sent: the M100's is never assumed for it.
        assert_eq!(e["remaining_source"], "capacity not known", "{e}");
        assert!(e["remaining_wh"].is_null(), "{e}");
        assert!(e["time_to_empty_s"].is_null(), "{e}");
        assert!(e["capacity_wh"].is_null(), "{e}");
    }
    // Energy used from the measured 500 ± 40 W: about 500 W × the time flown.
    let last = lines.last().unwrap();
    let first = lines.first().unwrap();
    let flown_h = (last["t"].as_f64().unwrap() - first["t"].as_f64().unwrap()) / 3600.0;
    let used = last["energy_used_wh"].as_f64().unwrap() - first["energy_used_wh"].as_f64().unwrap();
    assert!(
        (used / flown_h - 500.0).abs() < 40.0,
        "{used} Wh in {flown_h} h"
    );
    assert_eq!(
        r.summary["vehicle_kinds"][0], "other: SUBMARINE (12)",
        "{}",
        r.summary
    );
}

#[test]
fn a_submarine_with_a_configured_pack_gets_remaining_energy_from_measured_power() {
    let r = fly(
        "[energy]\ncapacity_wh = 50.0\n",
        false,
        r#"[{"send_s": 6}]"#,
        &["--mav-type", "12"],
    );
    let lines = after_heartbeat(&r);
    let last = lines.last().unwrap();
    assert!(models(last).is_empty(), "{last}");
    let left = last["remaining_wh"].as_f64().unwrap();
    let used = last["energy_used_wh"].as_f64().unwrap();
    // No rest is read: the pack starts load-compensated (a full pack here, at the top of its
    // window) a few seconds in, and counts on from there.
    assert_eq!(
        last["remaining_source"], "load-compensated voltage",
        "{last}"
    );
    assert!(
        left <= 50.0 - used + 1e-6 && left > 50.0 - used - 1.0,
        "{last}"
    );
    // Time to empty at the measured ~500 W.
    let tte = last["time_to_empty_s"].as_f64().unwrap();
    assert!(
        (tte - 3600.0 * left / 500.0).abs() < 0.15 * tte,
        "{tte} s for {left} Wh"
    );
}

#[test]
fn an_unknown_mav_type_is_other_with_its_number() {
    let r = fly("", false, r#"[{"send_s": 6}]"#, &["--mav-type", "99"]);
    assert!(r.stderr.contains("MAV_TYPE 99"), "{}", r.stderr);
    for e in after_heartbeat(&r) {
        assert_eq!(e["vehicle_class"], "other", "{e}");
        assert!(models(e).is_empty(), "{e}");
    }
    assert_eq!(r.count("frames_bad"), 0, "{}", r.summary);
}

#[test]
fn a_plane_gets_fixed_wing_estimates_and_not_the_m100_models_or_pack() {
    // A plane drawing 60 ± 5 W.
    let r = fly(
        "",
        false,
        r#"[{"send_s": 12}]"#,
        &["--mav-type", "1", "--power-w", "60", "--power-swing-w", "5"],
    );
    let lines = after_heartbeat(&r);
    for e in &lines {
        assert_eq!(e["vehicle_class"], "fixed_wing", "{e}");
        assert_eq!(models(e), ["fixed_wing"], "{e}");
        // The M100's 129.96 Wh is not shown as this vehicle's pack.
        assert!(e["capacity_wh"].is_null(), "{e}");
        assert_eq!(e["remaining_source"], "capacity not known", "{e}");
    }
    // Cruising north at 10 m/s into a 2 m/s wind from the south: 8 m/s through the air
    // (ground − WIND: the peer has no airspeed sensor), level, about 425 m up: a 2 kg foam
    // plane's ~33 W (by hand: (3.95 + 9.9) W / 0.5 + 5 W at sea level; a little less
    // dense air up there).
    let cruise: Vec<f64> = lines
        .iter()
        .filter(|e| e["t"].as_f64().unwrap() - lines[0]["t"].as_f64().unwrap() > 6.0)
        .map(|e| e["models"]["fixed_wing"].as_f64().unwrap())
        .collect();
    assert!(!cruise.is_empty());
    for p in &cruise {
        assert!((28.0..38.0).contains(p), "fixed_wing {p} W in cruise");
    }
    assert!(
        r.stderr.contains("vehicle class: fixed_wing"),
        "{}",
        r.stderr
    );
    // Adapted on this plane (its own regression, then the affine fit): nearer the measured
    // ~60 W than the generic plane's ~33 W by the end.
    let last = lines.last().unwrap();
    let adapted = last["adapted"]["fixed_wing"].as_f64().unwrap();
    let raw = last["models"]["fixed_wing"].as_f64().unwrap();
    let measured = last["measured_w"].as_f64().unwrap();
    assert!(
        (adapted - measured).abs() < 0.5 * (raw - measured).abs(),
        "adapted {adapted} W, raw {raw} W, measured {measured} W"
    );
}

#[test]
fn no_battery_telemetry_takes_the_models_power_against_the_pack_and_says_so() {
    let r = fly(
        "[energy]\ncapacity_wh = 60.0\n",
        false,
        r#"[{"send_s": 6}]"#,
        &["--no-battery"],
    );
    let lines = after_heartbeat(&r);
    let warning = "the vehicle sends no battery telemetry";
    assert_eq!(r.stderr.matches(warning).count(), 1, "{}", r.stderr);
    let last = lines.last().unwrap();
    assert_eq!(last["vehicle_class"], "multirotor", "{last}");
    assert!(last["measured_w"].is_null(), "{last}");
    assert_eq!(last["remaining_source"], "model power", "{last}");
    assert_eq!(last["capacity_wh"], 60.0, "{last}");
    let used = last["energy_used_wh"].as_f64().unwrap();
    assert!(used > 0.0, "{last}");
    let left = last["remaining_wh"].as_f64().unwrap();
    assert!((left + used - 60.0).abs() < 1e-6, "{last}");
}

#[test]
fn a_quadplane_switching_to_forward_flight_is_followed_and_each_phase_gets_its_models() {
    // HEARTBEAT FIXED_WING (as ArduPlane quadplanes may say), QHOVER and vtol_state MC for
    // 4 s, a 1 s transition, then AUTO and FW.
    let r = fly(
        "",
        false,
        r#"[{"send_s": 9}]"#,
        &["--mav-type", "1", "--vtol-fw-after-s", "4"],
    );
    let lines = after_heartbeat(&r);
    let state = |e: &Value| e["vtol_state"].as_str().unwrap_or("").to_string();
    for e in &lines {
        assert_eq!(e["vehicle_class"], "vtol", "{e}");
        let m = models(e);
        match state(e).as_str() {
            "fw" => assert_eq!(m, ["fixed_wing"], "{e}"),
            "mc" | "transition_to_fw" => {
                assert!(m.iter().any(|n| n == "dandrea"), "{e}");
                assert!(!m.iter().any(|n| n == "fixed_wing"), "{e}");
            }
            other => panic!("vtol_state {other:?}: {e}"),
        }
    }
    let seen: Vec<String> = lines.iter().map(|e| state(e)).collect();
    let first_fw = seen.iter().position(|s| s == "fw").expect("a FW phase");
    assert!(seen[..first_fw].iter().any(|s| s == "mc"), "{seen:?}");
    assert!(seen[first_fw..].iter().all(|s| s == "fw"), "{seen:?}");
    for switch in [
        "vtol (mc) → vtol (transition_to_fw)",
        "vtol (transition_to_fw) → vtol (fw)",
    ] {
        assert_eq!(
            r.stderr.matches(switch).count(),
            1,
            "{switch}: {}",
            r.stderr
        );
    }
    let kinds = &r.summary["vehicle_kinds"];
    assert!(
        kinds.as_array().unwrap().iter().any(|k| k == "vtol (fw)"),
        "{kinds}"
    );
}

#[test]
fn a_replayed_quadplane_log_shows_vtol_both_phases_and_no_m100_pack() {
    // The pymavlink quadplane writes its own telemetry log (to a UDP port nobody holds),
    // which `dronewatt replay` then reads like any ground station's .tlog.
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("quadplane.tlog");
    record_quadplane_tlog(&log, 9);
    let out = dronewatt()
        .arg("replay")
        .arg(&log)
        .args(["--speed", "max", "--json", "-", "--data-dir", "off"])
        .env("RUST_LOG", "info")
        .out();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let lines: Vec<Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let estimates: Vec<&Value> = lines
        .iter()
        .filter(|l| l["type"] == "estimate" && l.get("mav_type").is_some())
        .collect();
    assert!(
        estimates.len() > 50,
        "{} estimates; {stderr}",
        estimates.len()
    );
    let mut phases = Vec::new();
    for e in &estimates {
        assert_eq!(e["vehicle_class"], "vtol", "{e}");
        assert!(
            e["capacity_wh"].is_null(),
            "the M100's pack on a quadplane: {e}"
        );
        let state = e["vtol_state"].as_str().unwrap().to_string();
        let m = models(e);
        if state == "fw" {
            assert_eq!(m, ["fixed_wing"], "{e}");
        } else {
            assert!(!m.iter().any(|n| n == "fixed_wing"), "{e}");
        }
        if phases.last() != Some(&state) {
            phases.push(state);
        }
    }
    assert_eq!(phases, ["mc", "transition_to_fw", "fw"], "{stderr}");
    let summary = lines.last().unwrap();
    assert_eq!(
        summary["vehicle_kinds"],
        serde_json::json!(["vtol (mc)", "vtol (transition_to_fw)", "vtol (fw)"]),
        "{summary}"
    );
    assert!(
        stderr.contains("vtol (transition_to_fw) → vtol (fw)"),
        "{stderr}"
    );
}

#[test]
fn the_profiles_class_wins_over_the_heartbeat() {
    // The X500 profile told it is a boat (`[vehicle] class = "other"`): a quadrotor's
    // HEARTBEAT, but no model runs.
    let dir = tempfile::tempdir().unwrap();
    let x500 = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/config/vehicles/x500.toml"
    ))
    .unwrap();
    let profile = dir.path().join("boat.toml");
    std::fs::write(
        &profile,
        x500.replacen("[vehicle]\n", "[vehicle]\nclass = \"other\"\n", 1),
    )
    .unwrap();
    let r = fly(
        &format!("vehicle = {:?}\n", profile.to_str().unwrap()),
        false,
        r#"[{"send_s": 5}]"#,
        &[],
    );
    assert!(
        r.stderr
            .contains("vehicle class: other (from the vehicle profile's [vehicle] class)"),
        "{}",
        r.stderr
    );
    let lines = after_heartbeat(&r);
    for e in &lines {
        assert_eq!(e["vehicle_class"], "other", "{e}");
        assert_eq!(e["mav_type"], 2, "{e}");
        assert!(models(e).is_empty(), "{e}");
    }
    // A class that does not exist is an error naming the key.
    let bad = x500.replacen("[vehicle]\n", "[vehicle]\nclass = \"blimp\"\n", 1);
    let err = format!(
        "{:#}",
        dronewatt::model::profile::VehicleProfile::from_toml(&bad, "boat.toml").unwrap_err()
    );
    assert!(err.contains("class") && err.contains("blimp"), "{err}");
}

#[test]
fn learn_takes_only_the_windows_flown_on_rotors() {
    // A quadplane's log: `learn` (which fits the multirotor models) keeps its hover and
    // transition windows and leaves its forward flight out.
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("quadplane.tlog");
    record_quadplane_tlog(&log, 8);
    let cfg = dronewatt::config::Config::default();
    let f = dronewatt::offline::learn::log_windows(&log, 1, &cfg).unwrap();
    assert!(f.windows.len() > 20, "{} windows", f.windows.len());
    for w in &f.windows {
        let k = w.last().vehicle;
        assert_eq!(k.class, dronewatt::features::VehicleClass::Vtol);
        assert_ne!(k.vtol_state, dronewatt::features::VtolState::Fw, "{k:?}");
    }
    // About 5 of the 8 s (hover and transition) at 10 windows a second, not the FW 3 s.
    assert!(f.windows.len() < 60, "{} windows", f.windows.len());
}

/// The pymavlink quadplane (MAV_TYPE 1, forward flight after 4 s) flying `send_s` seconds
/// and writing its own telemetry log to `log` (sent to a UDP port nobody holds).
fn record_quadplane_tlog(log: &std::path::Path, send_s: u32) {
    let port = link_common::free_udp_port();
    let plan = format!(r#"[{{"send_s": {send_s}}}]"#);
    let peer =
        std::process::Command::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.venv-py/bin/python"))
            .arg(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/tests/peers/vehicle.py"
            ))
            .args(["--to", &format!("udpout:127.0.0.1:{port}"), "--plan", &plan])
            .args([
                "--mav-type",
                "1",
                "--vtol-fw-after-s",
                "4",
                "--listen-after-s",
                "0",
            ])
            .arg("--tlog")
            .arg(log)
            .output()
            .expect("run .venv-py/bin/python (make setup creates it)");
    assert!(
        peer.status.success(),
        "{}",
        String::from_utf8_lossy(&peer.stderr)
    );
}
