//! The pack on any vehicle (issue 44), end to end through `dronewatt replay` on logs the
//! simulator writes as an ArduCopter ground station logs them (quad-3s: 3S 3300 mAh LiPo,
//! BATT_CAPACITY / BATT_LOW_VOLT in the logged parameter fetch):
//!
//! - the same log replayed flat out and at ×10, several at once, gives byte-identical
//!   `--json` (the summary's wall-clock fields aside): parameters and estimates are ordered
//!   by the log's clock, not by the threads;
//! - without the parameters, no other vehicle's pack: the capacity is null with its reason,
//!   the state of charge and energy used are still there; `--pack` gives the pack;
//! - attached in flight (the log cut after take-off): the pack starts load-compensated;
//! - an ArduCopter SITL-like pack that never sags (12.6 V at any current): no impossible
//!   voltage, and it says the pack does not sag, once.

use crate::harness::{dronewatt, json_lines_of, without_wall_clock, RunExt};
use dronewatt::sim::guidance::Triangle;
use dronewatt::sim::{simulate, SimFlight, SimOptions};
use dronewatt::MavMessage;
use serde_json::Value;
use std::path::Path;

/// A short ArduCopter quad-3s flight (about 40 s).
fn flight() -> SimFlight {
    let opts = SimOptions {
        vehicle: dronewatt::model::profile::VehicleProfile::named_or_file("quad-3s")
            .expect("the quad-3s profile"),
        route: Triangle {
            leg_m: 40.0,
            altitude_m: 10.0,
            speed_mps: 8.0,
            hover_s: 4.0,
        }
        .route(),
        payload_g: 0.0,
        seed: 3,
        ..SimOptions::default()
    };
    simulate(&opts).expect("simulated")
}

fn write(path: &Path, f: &SimFlight) {
    std::fs::write(path, f.to_tlog()).expect("tlog written");
}

/// `dronewatt replay --speed SPEED -q --json - ARGS LOG`: (stdout, stderr).
fn replay(log: &Path, speed: &str, args: &[&str]) -> (String, String) {
    let out = dronewatt()
        .args(["replay", "--speed", speed, "-q", "--json", "-"])
        .args(args)
        .arg(log)
        .ok();
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn estimates(stdout: &str) -> Vec<Value> {
    json_lines_of(stdout.as_bytes())
        .into_iter()
        .filter(|l| l["type"] == "estimate")
        .collect()
}

#[test]
fn replays_are_byte_identical_at_any_speed() {
    let dir = tempfile::tempdir().expect("tempdir");
    let log = dir.path().join("quad.tlog");
    write(&log, &flight());
    // Five flat out and five at ×10, all at once: the threads race as they please.
    let runs: Vec<String> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..10)
            .map(|k| {
                let log = &log;
                s.spawn(move || {
                    let speed = if k % 2 == 0 { "max" } else { "10" };
                    without_wall_clock(&replay(log, speed, &[]).0)
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("a replay"))
            .collect()
    });
    let first = &runs[0];
    let est = estimates(first);
    assert!(est.len() > 100, "{} estimates", est.len());
    for (k, r) in runs.iter().enumerate() {
        assert!(r == first, "run {k} differs from run 0");
    }
    // Never another vehicle's pack: known from the logged BATT_CAPACITY, or said unknown.
    for e in &est {
        let src = e["capacity_source"].as_str().unwrap_or("");
        assert!(
            src == "vehicle parameter BATT_CAPACITY" || src.starts_with("not known"),
            "{e}"
        );
        assert_ne!(e["capacity_wh"], 129.96, "{e}");
    }
    let last = est.last().expect("an estimate");
    assert!(
        (last["capacity_wh"].as_f64().unwrap_or(0.0) - 3.3 * 3.0 * 3.7).abs() < 1e-6,
        "{last}"
    );
}

/// The flight without its parameter fetch.
fn without_params(f: &SimFlight) -> SimFlight {
    SimFlight {
        records: f
            .records
            .iter()
            .filter(|r| !matches!(r.msg, MavMessage::PARAM_VALUE(_)))
            .cloned()
            .collect(),
        truth: f.truth.clone(),
    }
}

#[test]
fn no_capacity_is_said_and_never_another_pack() {
    let dir = tempfile::tempdir().expect("tempdir");
    let log = dir.path().join("quad.tlog");
    write(&log, &without_params(&flight()));
    let (out, err) = replay(&log, "max", &[]);
    let est = estimates(&out);
    let last = est.last().expect("an estimate");
    for e in &est {
        assert!(e["capacity_wh"].is_null(), "{e}");
        assert!(
            e["remaining_wh"].is_null() && e["time_to_empty_s"].is_null(),
            "{e}"
        );
        assert_eq!(e["remaining_source"], "capacity not known", "{e}");
    }
    assert!(
        last["capacity_source"]
            .as_str()
            .is_some_and(|s| s.starts_with("not known")),
        "{last}"
    );
    // What is known without it: the state of charge from the voltage, the energy used.
    let soc = last["soc_pct"].as_f64().expect("a state of charge");
    assert!((0.0..=100.0).contains(&soc), "{last}");
    assert!(
        last["energy_used_wh"].as_f64().unwrap_or(0.0) > 0.5,
        "{last}"
    );
    assert_eq!(last["cell_count"], 3, "{last}");
    assert_eq!(
        err.matches("capacity not known").count(),
        1,
        "said once: {err}"
    );
    // The flag gives the pack.
    let (out, _) = replay(&log, "max", &["--pack", "3S:3300mAh:lipo"]);
    let last = estimates(&out).pop().expect("an estimate");
    assert_eq!(last["capacity_source"], "--pack 3S:3300mAh:lipo", "{last}");
    assert!(last["remaining_wh"].as_f64().is_some(), "{last}");
    // A bad flag is an error that names it.
    let bad = dronewatt()
        .args(["replay", "--speed", "max", "-q", "--pack", "3S:0mAh"])
        .arg(&log)
        .out();
    assert!(!bad.status.success());
    assert!(
        String::from_utf8_lossy(&bad.stderr).contains("--pack 3S:0mAh"),
        "{}",
        String::from_utf8_lossy(&bad.stderr)
    );
}

#[test]
fn a_monitor_attached_in_flight_starts_load_compensated() {
    let dir = tempfile::tempdir().expect("tempdir");
    let log = dir.path().join("late.tlog");
    let mut f = flight();
    // Cut everything until 15 s after the log starts (the vehicle is in the air, no rest
    // is ever seen) but the first heartbeat and the parameter fetch, which a ground station
    // connecting then gets first: moved to the cut.
    let t_cut = f.records.first().map_or(0, |r| r.t_us) + 15_000_000;
    let mut heartbeat = false;
    f.records.retain(|r| {
        let first_heartbeat = matches!(r.msg, MavMessage::HEARTBEAT(_)) && !heartbeat;
        heartbeat |= first_heartbeat;
        r.t_us >= t_cut || first_heartbeat || matches!(r.msg, MavMessage::PARAM_VALUE(_))
    });
    for r in f.records.iter_mut() {
        r.t_us = r.t_us.max(t_cut);
    }
    f.records.sort_by_key(|r| r.t_us);
    write(&log, &f);
    let (out, err) = replay(&log, "max", &[]);
    let est = estimates(&out);
    let started = est
        .iter()
        .find(|e| e["pack_start"].is_string())
        .expect("the pack started");
    assert!(
        started["pack_start"]
            .as_str()
            .is_some_and(|s| s.starts_with("load-compensated")),
        "{started}"
    );
    assert!(
        started["soc_band_pct"].as_f64().unwrap_or(0.0) >= 10.0,
        "{started}"
    );
    // Never "assumed full": the autopilot's % (it sends one), else the load-compensated state.
    let last = est.last().expect("an estimate");
    assert_ne!(last["remaining_source"], "assumed full", "{last}");
    assert!(err.contains("load-compensated"), "{err}");
}

/// The flight with the voltage stuck at 12.6 V in SYS_STATUS and BATTERY_STATUS, whatever
/// the current: ArduCopter SITL's default battery.
fn never_sags(f: &SimFlight) -> SimFlight {
    let mut f = SimFlight {
        records: f.records.clone(),
        truth: f.truth.clone(),
    };
    for r in f.records.iter_mut() {
        match &mut r.msg {
            MavMessage::SYS_STATUS(s) => s.voltage_battery = 12_600,
            MavMessage::BATTERY_STATUS(b) => b.voltages[0] = 12_600,
            _ => {}
        }
    }
    f
}

#[test]
fn a_sitl_pack_that_never_sags_gives_no_impossible_voltage_and_says_so() {
    let dir = tempfile::tempdir().expect("tempdir");
    let log = dir.path().join("sitl.tlog");
    write(&log, &never_sags(&flight()));
    let (out, err) = replay(&log, "max", &[]);
    let est = estimates(&out);
    assert!(est.len() > 100);
    // 3S LiPo: 3 × 2.5 V loaded at the least, 3 × 4.25 V at the most.
    let (lo, hi) = (7.5, 12.75);
    for e in &est {
        for k in [
            "battery_v_model",
            "battery_ocv_v",
            "v_min_forecast_v",
            "battery_rest_v",
        ] {
            if let Some(v) = e[k].as_f64() {
                assert!((lo..=hi).contains(&v), "{k} = {v}: {e}");
            }
        }
        if let Some(r) = e["internal_r_ohm"].as_f64() {
            assert!((0.0..=1.5).contains(&r), "{e}");
        }
        if let Some(s) = e["soc_pct"].as_f64() {
            assert!((0.0..=100.0).contains(&s), "{e}");
        }
        if let Some(w) = e["remaining_wh"].as_f64() {
            assert!(w >= 0.0, "{e}");
        }
    }
    let last = est.last().expect("an estimate");
    assert!(
        last["pack_withheld"]
            .as_str()
            .is_some_and(|s| s.contains("does not sag")),
        "{last}"
    );
    assert!(
        last["time_to_low_v_s"].is_null() && last["v_min_forecast_v"].is_null(),
        "{last}"
    );
    // Energy is still counted.
    assert!(
        last["energy_used_wh"].as_f64().unwrap_or(0.0) > 0.5,
        "{last}"
    );
    assert_eq!(err.matches("does not sag").count(), 1, "said once: {err}");
}
