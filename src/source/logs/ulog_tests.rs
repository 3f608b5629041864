//! Tests of `src/source/logs/ulog.rs` (a file of their own: the module stays under 600 lines).

use super::super::synth::testutil::{first_heartbeat, sys_status};
use super::*;
use Value::Nums as N;

const BAT: Topic = Topic {
    id: 0,
    name: "battery_status",
    fields: &[
        Field {
            ty: "float",
            name: "voltage_v",
        },
        Field {
            ty: "float",
            name: "current_a",
        },
    ],
};
/// battery_status without current_a: a log of a version whose fields differ.
const BAT_V: Topic = Topic {
    id: 0,
    name: "battery_status",
    fields: &[Field {
        ty: "float",
        name: "voltage_v",
    }],
};

fn decode(bytes: &[u8]) -> Result<Vec<TimedMessage>, UlogError> {
    decode_ulog(bytes, &IngestStats::default())
}

#[test]
fn mav_type_names_the_vehicle_and_a_missing_current_degrades() {
    let mut w = Writer::new(
        &[BAT_V],
        &[
            ("MAV_TYPE".into(), 13.0, true),
            ("BAT1_CAPACITY".into(), 2200.0, false),
        ],
    );
    w.data(&BAT_V, 1_000_000, &[N(&[11.1])]);
    w.data(&BAT_V, 1_500_000, &[N(&[11.0])]);
    let m = decode(&w.into_bytes()).unwrap();
    assert_eq!(
        first_heartbeat(&m),
        (
            d::MavType::MAV_TYPE_HEXAROTOR,
            d::MavAutopilot::MAV_AUTOPILOT_PX4
        )
    );
    assert_eq!(sys_status(&m), [(0.0, 11100, -1), (0.5, 11000, -1)]);
    assert!(m
        .iter()
        .any(|m| matches!(&m.msg, MavMessage::PARAM_VALUE(p) if p.param_value == 2200.0)));
}

#[test]
fn corrupt_or_foreign_files_are_errors_and_never_panic() {
    assert!(decode(b"").is_err());
    assert!(decode(b"\xA3\x95not ulog at all").is_err());
    assert!(matches!(
        decode(&Writer::new(&[BAT], &[]).into_bytes()),
        Err(UlogError::NoMessages)
    ));
    let mut w = Writer::new(&[BAT], &[]);
    for i in 0..50 {
        w.data(&BAT, i * 100_000, &[N(&[16.0]), N(&[3.0])]);
    }
    let good = w.into_bytes();
    assert_eq!(sys_status(&decode(&good).unwrap()).len(), 50);
    for cut in [10, 16, 60, good.len() / 2, good.len() - 1] {
        let _ = decode(&good[..cut]);
    }
    let mut bad = good.clone();
    for i in (20..bad.len()).step_by(7) {
        bad[i] ^= 0x5A;
    }
    let _ = decode(&bad);
}

#[test]
fn a_position_without_a_fix_is_never_sent_on_as_one() {
    const LOCAL: Topic = Topic {
        id: 0,
        name: "vehicle_local_position",
        fields: &[
            Field {
                ty: "float",
                name: "vx",
            },
            Field {
                ty: "float",
                name: "vy",
            },
            Field {
                ty: "float",
                name: "vz",
            },
        ],
    };
    const GLOBAL: Topic = Topic {
        id: 1,
        name: "vehicle_global_position",
        fields: &[
            Field {
                ty: "double",
                name: "lat",
            },
            Field {
                ty: "double",
                name: "lon",
            },
            Field {
                ty: "float",
                name: "alt",
            },
        ],
    };
    let mut w = Writer::new(&[LOCAL, GLOBAL], &[]);
    w.data(&LOCAL, 1_000_000, &[N(&[1.0]), N(&[0.0]), N(&[0.0])]);
    // PX4 before its estimator has a global position: NaN; then (0, 0); then a fix.
    w.data(
        &GLOBAL,
        1_100_000,
        &[N(&[f64::NAN]), N(&[f64::NAN]), N(&[f64::NAN])],
    );
    w.data(&GLOBAL, 1_200_000, &[N(&[0.0]), N(&[0.0]), N(&[0.0])]);
    w.data(
        &GLOBAL,
        1_300_000,
        &[N(&[47.397_742_1]), N(&[8.545_594]), N(&[488.0])],
    );
    let m = decode(&w.into_bytes()).unwrap();
    let fixes: Vec<(i32, i32, i32)> = m
        .iter()
        .filter_map(|m| match &m.msg {
            MavMessage::GLOBAL_POSITION_INT(p) => Some((p.lat, p.lon, p.alt)),
            _ => None,
        })
        .collect();
    assert_eq!(fixes, [(473_977_421, 85_455_940, 488_000)]);
}
