//! The simulated `.tlog` as others read it: pymavlink (the independent peer,
//! `tests/peers/sim_check.py`) and rust-mavlink decode every frame, the message mix and
//! rates are an ArduPilot's or a PX4's, and a seed gives the same bytes every time.

use crate::harness::{dronewatt, RunExt};
use std::collections::BTreeMap;
use std::path::Path;

use dronewatt::sim::guidance::Triangle;
use dronewatt::sim::{simulate, Autopilot, SimOptions, EPOCH_START_US};
use dronewatt::MavMessage;

fn short() -> SimOptions {
    SimOptions {
        route: Triangle {
            leg_m: 120.0,
            altitude_m: 25.0,
            speed_mps: 10.0,
            hover_s: 8.0,
        }
        .route(),
        ..Default::default()
    }
}

/// Run the pymavlink peer on a tlog and parse its JSON line.
fn peer(tlog: &Path) -> serde_json::Value {
    serde_json::from_slice(&crate::harness::peer("sim_check.py", [tlog])).expect("peer JSON")
}

/// Split a tlog into (µs timestamp, frame bytes) and decode each frame with rust-mavlink.
fn decode_rust(bytes: &[u8]) -> Vec<(u64, mavlink::MavHeader, MavMessage)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        assert!(i + 8 + 12 <= bytes.len(), "truncated record at byte {i}");
        let t = u64::from_be_bytes(bytes[i..i + 8].try_into().expect("8 bytes"));
        let f = &bytes[i + 8..];
        assert_eq!(f[0], 0xFD, "MAVLink 2 magic expected at byte {}", i + 8);
        let len = 12 + f[1] as usize + if f[2] & 1 != 0 { 13 } else { 0 };
        let mut r = mavlink::MavlinkReader::new(&f[..len]);
        let (h, m) = r
            .read_any_message::<MavMessage>()
            .expect("rust-mavlink decodes the frame");
        out.push((t, h, m));
        i += 8 + len;
    }
    out
}

fn name(m: &MavMessage) -> String {
    format!("{m:?}").split('(').next().unwrap_or("").to_string()
}

#[test]
fn cli_tlog_decodes_with_pymavlink_as_ardupilot_telemetry() {
    let dir = tempfile::tempdir().expect("tempdir");
    let tlog = dir.path().join("flight.tlog");
    let _out = dronewatt()
        .args(["simulate", "--out"])
        .arg(&tlog)
        .args(["--leg-m", "120", "--hover-s", "8", "--seed", "7"])
        .ok();
    let v = peer(&tlog);
    assert_eq!(v["bad"], 0, "pymavlink found bad frames");
    let counts = v["counts"].as_object().expect("counts");
    let rate = |k: &str| v["rates_hz"][k].as_f64().unwrap_or(0.0);
    for k in [
        "HEARTBEAT",
        "SYS_STATUS",
        "BATTERY_STATUS",
        "GLOBAL_POSITION_INT",
        "ATTITUDE",
        "RAW_IMU",
        "VFR_HUD",
        "WIND",
        "HOME_POSITION",
        "NAMED_VALUE_FLOAT",
    ] {
        assert!(
            counts.contains_key(k),
            "{k} missing from an ArduPilot-style log: {counts:?}"
        );
    }
    for k in [
        "ATTITUDE_QUATERNION",
        "HIGHRES_IMU",
        "ALTITUDE",
        "EXTENDED_SYS_STATE",
    ] {
        assert!(
            !counts.contains_key(k),
            "ArduPilot does not send {k} by default"
        );
    }
    assert!((0.9..=1.3).contains(&rate("HEARTBEAT")));
    assert!((2.0..=5.0).contains(&rate("SYS_STATUS")));
    assert!((5.0..=10.0).contains(&rate("GLOBAL_POSITION_INT")));
    assert!((9.5..=10.5).contains(&rate("ATTITUDE")));
    assert!((0.15..=0.3).contains(&rate("HOME_POSITION")));
    // The tlog clock is a real epoch: the start of flight 276's day.
    assert_eq!(
        v["start_epoch_s"].as_f64(),
        Some(EPOCH_START_US as f64 / 1e6)
    );
    // pymavlink's V·I in hover and cruise: the physics through the wire.
    let hover = v["hover_w"].as_f64().expect("hover rows");
    let cruise = v["cruise_w"].as_f64().expect("cruise rows");
    assert!((430.0..=600.0).contains(&hover), "hover {hover} W");
    assert!((380.0..=600.0).contains(&cruise), "cruise {cruise} W");
}

#[test]
fn px4_style_sends_quaternion_highres_imu_and_no_wind() {
    let dir = tempfile::tempdir().expect("tempdir");
    let tlog = dir.path().join("px4.tlog");
    let flight = simulate(&SimOptions {
        autopilot: Autopilot::Px4,
        ..short()
    })
    .expect("simulate");
    std::fs::write(&tlog, flight.to_tlog()).expect("write");
    let v = peer(&tlog);
    let counts = v["counts"].as_object().expect("counts");
    for k in [
        "ATTITUDE_QUATERNION",
        "HIGHRES_IMU",
        "ALTITUDE",
        "EXTENDED_SYS_STATE",
        "GLOBAL_POSITION_INT",
        "BATTERY_STATUS",
        "HOME_POSITION",
    ] {
        assert!(
            counts.contains_key(k),
            "{k} missing from a PX4-style log: {counts:?}"
        );
    }
    for k in ["WIND", "RAW_IMU"] {
        assert!(!counts.contains_key(k), "PX4 does not send {k}");
    }
    // HEARTBEAT says PX4.
    let px4 = flight.records.iter().any(|r| matches!(&r.msg, MavMessage::HEARTBEAT(h) if h.autopilot == dronewatt::dialect::MavAutopilot::MAV_AUTOPILOT_PX4));
    assert!(px4);
}

#[test]
fn rust_mavlink_decodes_every_frame_with_mavlink_units() {
    let flight = simulate(&short()).expect("simulate");
    let decoded = decode_rust(&flight.to_tlog());
    assert_eq!(decoded.len(), flight.records.len());
    let mut kinds: BTreeMap<String, usize> = BTreeMap::new();
    let mut prev_seq: Option<u8> = None;
    let mut prev_t = 0;
    for ((t, h, m), r) in decoded.iter().zip(&flight.records) {
        assert_eq!(*t, r.t_us);
        assert!(*t >= prev_t, "timestamps must not go backwards");
        prev_t = *t;
        assert_eq!((h.system_id, h.component_id), (1, 1));
        if let Some(p) = prev_seq {
            assert_eq!(
                h.sequence,
                p.wrapping_add(1),
                "sequence numbers run without gaps"
            );
        }
        prev_seq = Some(h.sequence);
        assert_eq!(name(m), name(&r.msg));
        *kinds.entry(name(m)).or_default() += 1;
        match m {
            MavMessage::GLOBAL_POSITION_INT(g) => {
                // Near the data set's site, altitude in mm above sea level.
                assert!(
                    (404_000_000..=405_000_000).contains(&g.lat),
                    "lat {}",
                    g.lat
                );
                assert!(
                    (-798_500_000..=-797_000_000).contains(&g.lon),
                    "lon {}",
                    g.lon
                );
                assert!(
                    (g.alt - g.relative_alt - 268_700).abs() < 5_000,
                    "alt {} rel {}",
                    g.alt,
                    g.relative_alt
                );
                // cm/s, NED: never faster than 12 m/s here, and climbing is negative vz.
                assert!(((g.vx as f64).hypot(g.vy as f64)) < 1200.0);
            }
            MavMessage::RAW_IMU(i) => {
                assert!((-1300..=-700).contains(&i.zacc), "zacc {} mG", i.zacc)
            }
            MavMessage::SYS_STATUS(s) => {
                assert!(
                    (18_000..=26_200).contains(&s.voltage_battery),
                    "{} mV",
                    s.voltage_battery
                );
                assert!(s.current_battery < 4_500, "{} cA", s.current_battery);
            }
            MavMessage::NAMED_VALUE_FLOAT(n) => {
                let want = match n.name.to_str().unwrap_or("") {
                    "cmd_speed" => 10.0,
                    "payload_g" => 500.0,
                    "cmd_alt" => 25.0,
                    other => panic!("unexpected NAMED_VALUE_FLOAT {other}"),
                };
                assert_eq!(n.value, want);
            }
            _ => {}
        }
    }
    // The climb shows as negative vz (NED) in GLOBAL_POSITION_INT.
    assert!(decoded
        .iter()
        .any(|(_, _, m)| matches!(m, MavMessage::GLOBAL_POSITION_INT(g) if g.vz < -200)));
    assert!(kinds["ATTITUDE"] > 5 * kinds["HEARTBEAT"], "{kinds:?}");
}

#[test]
fn same_seed_same_bytes_other_seed_other_noise() {
    let a = simulate(&short()).expect("simulate").to_tlog();
    let b = simulate(&short()).expect("simulate").to_tlog();
    let c = simulate(&SimOptions { seed: 2, ..short() })
        .expect("simulate")
        .to_tlog();
    assert!(a == b, "same seed must give identical tlogs");
    assert!(a != c, "another seed must change the noise");
}

#[test]
fn bad_arguments_are_refused_with_a_reason() {
    let out = dronewatt()
        .args([
            "simulate",
            "--out",
            "/nonexistent-dir/x.tlog",
            "--payload-g",
            "5000",
        ])
        .output()
        .expect("run dronewatt simulate");
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("--payload-g"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = dronewatt()
        .args(["simulate", "--out", "/nonexistent-dir/x.tlog"])
        .output()
        .expect("run dronewatt simulate");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent-dir/x.tlog"));
}

#[test]
fn the_demo_tlog_is_what_the_command_in_its_readme_makes() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = tempfile::tempdir().expect("tempdir");
    let tlog = dir.path().join("demo.tlog");
    let _out = dronewatt()
        .current_dir(root)
        .args(["simulate", "--plan", "replay/demo.plan", "--out"])
        .arg(&tlog)
        .args([
            "--payload-g",
            "500",
            "--wind-mps",
            "4",
            "--wind-dir-deg",
            "250",
            "--seed",
            "42",
            "--battery-v",
            "23.95",
        ])
        .ok();
    let readme = std::fs::read_to_string(root.join("replay/README.md")).expect("replay/README.md");
    assert!(
        readme.contains("--plan replay/demo.plan --out replay/demo.tlog --payload-g 500")
            && readme.contains("--wind-mps 4 --wind-dir-deg 250 --seed 42 --battery-v 23.95"),
        "the README's command changed: update this test"
    );
    let (made, shipped) = (
        std::fs::read(&tlog).expect("made"),
        std::fs::read(root.join("replay/demo.tlog")).expect("shipped"),
    );
    assert!(
        made == shipped,
        "replay/demo.tlog is not what its README's command makes ({} vs {} bytes): regenerate it",
        made.len(),
        shipped.len()
    );
}
