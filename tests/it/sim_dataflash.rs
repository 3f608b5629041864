//! ArduPilot DataFlash `.bin` logs end to end, with real parts: the simulator logs a
//! flight of a non-M100 airframe (X500) as a `.bin` and as a `.tlog`; pymavlink's DFReader
//! (an independent reader, `tests/peers/dataflash_dump.py`) reads the `.bin` and agrees with
//! the `.tlog` (read by pymavlink's mavutil) on message counts and values; dronewatt's
//! reader turns the `.bin` into the MAVLink a tlog gives (measured V·I, attitude,
//! parameters, an ArduPilot heartbeat); and `learn` on three `.bin` logs scores the same
//! held-out MAPE as on the same flights as `.tlog`, and `replay FILE.bin` runs.

use crate::harness::{
    assert_sys_status_is_the_logs_battery, json_rows as rows, learn_scores_as_on_tlog,
    simulate_x500,
};

use dronewatt::MavMessage;
use serde_json::Value;

#[test]
fn pymavlink_reads_the_simulated_bin_as_the_tlog_says() {
    let dir = tempfile::tempdir().unwrap();
    let (bin, tlog) = (dir.path().join("x500.bin"), dir.path().join("x500.tlog"));
    simulate_x500(&bin, 1, &[]);
    simulate_x500(&tlog, 1, &[]);
    let stdout = crate::harness::peer("dataflash_dump.py", [&bin, &tlog]);
    let d: Value = serde_json::from_slice(&stdout).unwrap();
    let (b, t) = (&d["bin"], &d["tlog"]);
    let n = |v: &Value, k: &str| v["counts"][k].as_u64().unwrap_or(0);
    for (df, mav) in [
        ("BAT", "BATTERY_STATUS"),
        ("ATT", "ATTITUDE"),
        ("IMU", "RAW_IMU"),
        ("POS", "GLOBAL_POSITION_INT"),
        ("GPS", "GPS_RAW_INT"),
        ("XKF2", "WIND"),
        ("PARM", "PARAM_VALUE"),
    ] {
        assert!(
            n(b, df) > 0 && n(b, df) == n(t, mav),
            "{df} {} vs {mav} {}",
            n(b, df),
            n(t, mav)
        );
    }
    assert_eq!(b["parm"], t["parm"]);
    assert_eq!(
        b["parm"]["BATT_CAPACITY"].as_f64(),
        Some(5000.0),
        "{}",
        b["parm"]
    );
    // Same stamps (µs from the first record) and values, to the fields' resolution.
    for (k, tol) in [
        ("bat", [0.0, 1e-5, 1e-5, 0.0]),
        ("pos", [0.0, 1e-9, 1e-9, 1e-4]),
    ] {
        let (rb, rt) = (rows(&b[k]), rows(&t[k]));
        assert_eq!(rb.len(), rt.len());
        for (x, y) in rb.iter().zip(&rt) {
            for i in 0..4 {
                assert!(
                    (x[i] - y[i]).abs() <= tol[i] * y[i].abs().max(1.0),
                    "{k} {x:?} vs {y:?}"
                );
            }
        }
    }
    for (x, y) in rows(&b["att"]).iter().zip(&rows(&t["att"])) {
        assert_eq!(x[0], y[0]);
        let yaw = y[3].to_degrees().rem_euclid(360.0);
        assert!(
            (x[1] - y[1].to_degrees()).abs() < 0.006 && (x[2] - y[2].to_degrees()).abs() < 0.006,
            "{x:?} vs {y:?}"
        );
        assert!(
            (x[3] - yaw).abs() < 0.006 || (x[3] - yaw).abs() > 359.99,
            "{x:?} vs {y:?}"
        );
    }

    // dronewatt's reader: the MAVLink a tlog gives.
    let stats = dronewatt::report::status::IngestStats::default();
    let msgs =
        dronewatt::source::logs::dataflash::decode_dataflash(&std::fs::read(&bin).unwrap(), &stats)
            .unwrap();
    let hb = msgs
        .iter()
        .find_map(|m| {
            if let MavMessage::HEARTBEAT(h) = &m.msg {
                Some(h.clone())
            } else {
                None
            }
        })
        .unwrap();
    assert_eq!(
        hb.autopilot,
        dronewatt::dialect::MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA
    );
    assert_eq!(hb.mavtype, dronewatt::dialect::MavType::MAV_TYPE_QUADROTOR);
    assert_sys_status_is_the_logs_battery(&msgs, &rows(&b["bat"]));
    let att = msgs
        .iter()
        .filter(|m| matches!(m.msg, MavMessage::ATTITUDE(_)))
        .count();
    assert_eq!(att as u64, n(b, "ATT"));
    let cap = msgs.iter().any(|m| matches!(&m.msg, MavMessage::PARAM_VALUE(p) if p.param_id.to_str().unwrap_or("").starts_with("BATT_CAPACITY") && p.param_value == 5000.0));
    assert!(cap);
    assert_eq!(stats.snapshot().clock_jumps, 0);
}

#[test]
fn learn_on_bin_logs_scores_as_on_the_same_flights_as_tlog() {
    learn_scores_as_on_tlog("bin", &[]);
}
