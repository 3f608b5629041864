//! Tests of `src/source/logs/dataflash.rs` (a file of their own: the module stays under 600 lines).

use super::super::synth::testutil::{first_heartbeat, sys_status};
use super::*;
use Value::{Float as F, Int as I, Str as S};

const BAT: MsgDef = MsgDef {
    id: 80,
    name: "BAT",
    format: "QBff",
    labels: "TimeUS,Inst,Volt,Curr",
};
const PARM: MsgDef = MsgDef {
    id: 81,
    name: "PARM",
    format: "QNf",
    labels: "TimeUS,Name,Value",
};
/// ATT without Yaw: a log from a version whose fields differ.
const ATT: MsgDef = MsgDef {
    id: 82,
    name: "ATT",
    format: "Qcc",
    labels: "TimeUS,Roll,Pitch",
};

fn decode(bytes: &[u8]) -> Result<Vec<TimedMessage>, DataflashError> {
    decode_dataflash(bytes, &IngestStats::default())
}

#[test]
fn frame_class_names_the_vehicle_and_battery_without_current_degrades() {
    let mut w = Writer::new();
    w.write(&PARM, &[I(0), S("FRAME_CLASS"), F(2.0)]);
    w.write(&BAT, &[I(1_000_000), I(0), F(22.2)]);
    w.write(&ATT, &[I(1_100_000), F(5.0), F(-3.0)]);
    w.write(&BAT, &[I(2_000_000), I(0), F(22.1), F(12.5)]);
    let m = decode(&w.into_bytes()).unwrap();
    assert_eq!(
        first_heartbeat(&m),
        (
            d::MavType::MAV_TYPE_HEXAROTOR,
            d::MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA
        )
    );
    let sys = sys_status(&m);
    // The writer pads a value left out (Curr 0 A); stamps are seconds from the first.
    assert_eq!(sys, [(1.0, 22200, 0), (2.0, 22100, 1250)]);
    // No Yaw: no ATTITUDE (said once), no panic.
    assert!(!m.iter().any(|m| matches!(m.msg, MavMessage::ATTITUDE(_))));
}

#[test]
fn old_logs_stamped_in_milliseconds_are_timed() {
    const OLD: MsgDef = MsgDef {
        id: 84,
        name: "BAT",
        format: "Iff",
        labels: "TimeMS,Volt,Curr",
    };
    let mut w = Writer::new();
    w.write(&OLD, &[I(2000), F(12.0), F(5.0)]);
    w.write(&OLD, &[I(2250), F(11.9), F(5.5)]);
    let m = decode(&w.into_bytes()).unwrap();
    let t: Vec<f64> = m
        .iter()
        .filter(|m| matches!(m.msg, MavMessage::SYS_STATUS(_)))
        .map(|m| m.t_s)
        .collect();
    assert_eq!(t, [0.0, 0.25]);
}

#[test]
fn a_field_the_format_lacks_is_unknown_not_zero() {
    const BAT2: MsgDef = MsgDef {
        id: 83,
        name: "BAT",
        format: "QBf",
        labels: "TimeUS,Inst,Volt",
    };
    let mut w = Writer::new();
    w.write(&BAT2, &[I(5), I(0), F(11.1)]);
    let m = decode(&w.into_bytes()).unwrap();
    let s = m
        .iter()
        .find_map(|m| {
            if let MavMessage::SYS_STATUS(s) = &m.msg {
                Some(s.clone())
            } else {
                None
            }
        })
        .unwrap();
    assert_eq!(
        (s.voltage_battery, s.current_battery, s.battery_remaining),
        (11100, -1, -1)
    );
}

#[test]
fn gps_course_wraps_below_360_and_scaling_rounds_never_truncates() {
    const GPS: MsgDef = MsgDef {
        id: 85,
        name: "GPS",
        format: "QBBLLffff",
        labels: "TimeUS,I,Status,Lat,Lng,Alt,Spd,GCrs,VZ",
    };
    let mut w = Writer::new();
    // A course a hair below north: rem_euclid(360) of -1e-20 is 360.0 exactly, and
    // 359.9999° rounds to 360.00; both are north, cog 0. An altitude of 0.29 m (as
    // f32, 0.2899999916…) is 290 mm.
    for (k, crs) in [-1e-20, 359.9999, 90.004, 359.994].into_iter().enumerate() {
        let t = 1_000_000 * (k as i64 + 1);
        let fix = [I(t), I(0), I(3), I(473_977_421), I(85_455_940)];
        w.write(
            &GPS,
            &[fix.as_slice(), &[F(0.29), F(5.0), F(crs), F(0.0)]].concat(),
        );
    }
    let m = decode(&w.into_bytes()).unwrap();
    let gps: Vec<(u16, i32, u16)> = m
        .iter()
        .filter_map(|m| match &m.msg {
            MavMessage::GPS_RAW_INT(g) => Some((g.cog, g.alt, g.vel)),
            _ => None,
        })
        .collect();
    assert_eq!(
        gps,
        [
            (0, 290, 500),
            (0, 290, 500),
            (9000, 290, 500),
            (35999, 290, 500)
        ]
    );
}

#[test]
fn corrupt_or_foreign_files_are_errors_and_never_panic() {
    assert!(matches!(decode(b""), Err(DataflashError::NotDataflash)));
    assert!(matches!(
        decode(&[0xFD, 9, 0, 0]),
        Err(DataflashError::NotDataflash)
    ));
    // Only FMT records: nothing timed.
    let mut w = Writer::new();
    w.write(&PARM, &[I(0), S("X"), F(1.0)]);
    let only_fmt: Vec<u8> = w.into_bytes()[..89].to_vec();
    assert!(matches!(decode(&only_fmt), Err(DataflashError::NoMessages)));
    // Cut short anywhere, or bytes flipped: whatever is whole is read.
    let mut w = Writer::new();
    for i in 0..50 {
        w.write(&BAT, &[I(i * 100_000), I(0), F(16.0), F(3.0)]);
    }
    let good = w.into_bytes();
    for cut in [3, 90, 100, good.len() / 2, good.len() - 1] {
        let _ = decode(&good[..cut]);
    }
    let mut bad = good.clone();
    for i in (95..bad.len()).step_by(7) {
        bad[i] ^= 0x5A;
    }
    let _ = decode(&bad);
    let n = decode(&good)
        .unwrap()
        .iter()
        .filter(|m| matches!(m.msg, MavMessage::SYS_STATUS(_)))
        .count();
    assert_eq!(n, 50);
}
