//! PX4 ULog `.ulg` logs end to end, with real parts: the simulator logs a PX4-style flight
//! of a non-M100 airframe (X500) as a `.ulg` and as a `.tlog`; pyulog (an independent
//! reader, `tests/peers/ulog_dump.py`) reads the `.ulg` and agrees with the `.tlog` (read
//! by pymavlink's mavutil) on sample counts, stamps, values and parameters; dronewatt's
//! reader turns the `.ulg` into the MAVLink a tlog gives (measured V·I, a PX4 heartbeat,
//! PX4-encoded parameters); `learn` on three `.ulg` logs scores the same held-out MAPE as
//! on the same flights as `.tlog`; and `replay FILE.ulg` runs.

use crate::harness::{
    assert_sys_status_is_the_logs_battery, dronewatt, json_rows as rows, learn_scores_as_on_tlog,
    simulate_x500, RunExt,
};

use dronewatt::MavMessage;
use serde_json::Value;

#[test]
fn pyulog_reads_the_simulated_ulg_as_the_tlog_says() {
    let dir = tempfile::tempdir().unwrap();
    let (ulg, tlog) = (dir.path().join("x500.ulg"), dir.path().join("x500.tlog"));
    simulate_x500(&ulg, 1, &["--autopilot", "px4"]);
    simulate_x500(&tlog, 1, &["--autopilot", "px4"]);
    let stdout = crate::harness::peer("ulog_dump.py", [&ulg, &tlog]);
    let d: Value = serde_json::from_slice(&stdout).unwrap();
    let (u, t) = (&d["ulg"], &d["tlog"]);
    let n = |v: &Value, k: &str| v["counts"][k].as_u64().unwrap_or(0);
    for (topic, mav) in [
        ("battery_status", "BATTERY_STATUS"),
        ("vehicle_attitude", "ATTITUDE_QUATERNION"),
        ("sensor_combined", "HIGHRES_IMU"),
        ("vehicle_global_position", "GLOBAL_POSITION_INT"),
        ("airspeed_validated", "VFR_HUD"),
        ("debug_key_value", "NAMED_VALUE_FLOAT"),
    ] {
        assert!(
            n(u, topic) > 0 && n(u, topic) == n(t, mav),
            "{topic} {} vs {mav} {}",
            n(u, topic),
            n(t, mav)
        );
    }
    // Parameters: the float ones as sent, the integer one as its value (PX4 sends the bits).
    assert_eq!(u["parm"]["BAT1_CAPACITY"], t["parm"]["BAT1_CAPACITY"]);
    assert_eq!(u["parm"]["BAT1_CAPACITY"].as_f64(), Some(5000.0));
    assert_eq!(u["parm"]["BAT1_N_CELLS"].as_f64(), Some(4.0));
    for k in ["bat", "att"] {
        let (ru, rt) = (rows(&u[k]), rows(&t[k]));
        assert_eq!(ru.len(), rt.len());
        for (x, y) in ru.iter().zip(&rt) {
            assert_eq!(x[0], y[0], "{k} stamps");
            for i in 1..x.len() {
                assert!(
                    (x[i] - y[i]).abs() <= 1e-5 * y[i].abs().max(1.0),
                    "{k} {x:?} vs {y:?}"
                );
            }
        }
    }

    // dronewatt's reader: the MAVLink a tlog gives.
    let stats = dronewatt::report::status::IngestStats::default();
    let msgs =
        dronewatt::source::logs::ulog::decode_ulog(&std::fs::read(&ulg).unwrap(), &stats).unwrap();
    let MavMessage::HEARTBEAT(hb) = &msgs[0].msg else {
        panic!("{:?}", msgs[0])
    };
    assert_eq!(
        (hb.autopilot, hb.mavtype),
        (
            dronewatt::dialect::MavAutopilot::MAV_AUTOPILOT_PX4,
            dronewatt::dialect::MavType::MAV_TYPE_QUADROTOR
        )
    );
    assert_sys_status_is_the_logs_battery(&msgs, &rows(&u["bat"]));
    let cells = msgs.iter().find_map(|m| match &m.msg {
        MavMessage::PARAM_VALUE(p)
            if p.param_id
                .to_str()
                .unwrap_or("")
                .starts_with("BAT1_N_CELLS") =>
        {
            Some((p.param_value.to_bits(), p.param_type))
        }
        _ => None,
    });
    assert_eq!(
        cells,
        Some((4, dronewatt::dialect::MavParamType::MAV_PARAM_TYPE_INT32))
    );
    assert_eq!(stats.snapshot().clock_jumps, 0);
}

#[test]
fn learn_on_ulg_logs_scores_as_on_the_same_flights_as_tlog() {
    learn_scores_as_on_tlog("ulg", &["--autopilot", "px4"]);
}

#[test]
fn an_autopilots_own_log_is_of_that_autopilot() {
    let dir = tempfile::tempdir().unwrap();
    for (autopilot, file, says) in [
        ("ardupilot", "a.ulg", "--autopilot px4"),
        ("px4", "b.bin", "--autopilot ardupilot"),
    ] {
        let path = dir.path().join(file);
        let out = dronewatt()
            .args([
                "simulate",
                "--autopilot",
                autopilot,
                "--out",
                path.to_str().unwrap(),
            ])
            .out();
        let said = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && said.contains(file) && said.contains(says),
            "{said}"
        );
        assert!(!path.exists());
    }
}
