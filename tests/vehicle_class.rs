//! The vehicle class over a real link: `dronewatt monitor` on a loopback UDP port, a
//! pymavlink vehicle (`tests/peers/vehicle.py`) whose HEARTBEAT says what it is. A
//! submarine, a plane and a type MAVLink does not define get no multirotor model and never
//! the M100's pack; a quadrotor with no battery monitor gets its remaining energy from the
//! model's power, said so.

mod link_common;

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

fn models(e: &Value) -> Vec<String> {
    e["models"]
        .as_object()
        .map(|m| m.keys().cloned().collect())
        .unwrap_or_default()
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
        assert_eq!(e["remaining_source"], "unknown pack", "{e}");
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
    assert!((left + used - 50.0).abs() < 1e-6, "{last}");
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
fn a_plane_gets_no_multirotor_model_and_not_the_m100_pack() {
    let r = fly("", false, r#"[{"send_s": 6}]"#, &["--mav-type", "1"]);
    for e in after_heartbeat(&r) {
        assert_eq!(e["vehicle_class"], "fixed_wing", "{e}");
        for m in models(e) {
            assert!(
                m.starts_with("fixed_wing"),
                "multirotor model {m} on a plane: {e}"
            );
        }
        // The M100's 129.96 Wh is not shown as this vehicle's pack.
        assert!(e["capacity_wh"].is_null(), "{e}");
        assert_eq!(e["remaining_source"], "unknown pack", "{e}");
    }
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
