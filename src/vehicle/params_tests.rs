//! Tests of `src/vehicle/params.rs` (a file of their own: the module stays under 600 lines).

use super::*;
use MavParamType::{MAV_PARAM_TYPE_INT32 as INT32, MAV_PARAM_TYPE_REAL32 as REAL32};

fn msg(t_s: f64, sys: u32, comp: u8, msg: MavMessage) -> TimedMessage {
    let header = mavlink::MavHeader {
        system_id: sys,
        component_id: comp,
        sequence: 0,
    };
    TimedMessage::new(t_s, header, msg)
}

fn heartbeat(autopilot: MavAutopilot) -> MavMessage {
    MavMessage::HEARTBEAT(dialect::HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot,
        base_mode: dialect::MavModeFlag::empty(),
        system_status: dialect::MavState::MAV_STATE_STANDBY,
        mavlink_version: 3,
    })
}

fn value(name: &str, v: f32, t: MavParamType) -> MavMessage {
    MavMessage::PARAM_VALUE(dialect::PARAM_VALUE_DATA {
        param_value: v,
        param_count: 1000,
        param_index: 0,
        param_id: name.into(),
        param_type: t,
    })
}

/// A PARAM_VALUE from component 1 of system `sys`.
fn param(t_s: f64, sys: u32, name: &str, v: f32, ty: MavParamType) -> TimedMessage {
    msg(t_s, sys, 1, value(name, v, ty))
}

fn names(reqs: &[MavMessage]) -> Vec<String> {
    reqs.iter()
        .map(|r| match r {
            MavMessage::PARAM_REQUEST_READ(p) => p.param_id.to_str().unwrap().to_string(),
            MavMessage::COMMAND_LONG(_) => VERSION_KEY.to_string(),
            other => panic!("unexpected request {other:?}"),
        })
        .collect()
}

#[test]
fn decodes_ardupilot_casts_and_px4_bits() {
    let cast = RawParam {
        value: 3300.0,
        param_type: INT32,
    };
    assert_eq!(decode(Autopilot::ArduPilot, cast), 3300.0);
    let packed = RawParam {
        value: f32::from_bits(4),
        param_type: INT32,
    };
    assert_eq!(decode(Autopilot::Px4, packed), 4.0);
    let neg = RawParam {
        value: f32::from_bits((-1i32) as u32),
        param_type: INT32,
    };
    assert_eq!(decode(Autopilot::Px4, neg), -1.0);
    // Floats are floats on both.
    let f = RawParam {
        value: 3.5,
        param_type: REAL32,
    };
    assert_eq!(
        (decode(Autopilot::Px4, f), decode(Autopilot::ArduPilot, f)),
        (3.5, 3.5)
    );
}

#[test]
fn asks_after_the_heartbeat_resends_then_gives_up() {
    let mut r = ParamReader::live();
    let mut gave_up = Vec::new();
    assert!(
        r.poll(0.0, &mut gave_up).is_empty(),
        "nothing before the vehicle is known"
    );
    // A ground station's heartbeat is not the vehicle.
    r.on_message(&msg(
        0.0,
        255,
        190,
        heartbeat(MavAutopilot::MAV_AUTOPILOT_INVALID),
    ));
    assert!(r.poll(0.1, &mut gave_up).is_empty());
    r.on_message(&msg(
        0.2,
        1,
        1,
        heartbeat(MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA),
    ));
    let first = names(&r.poll(0.2, &mut gave_up));
    assert_eq!(first.len(), ARDUPILOT_PARAMS.len() + 1, "{first:?}");
    assert!(
        first.contains(&"BATT_CAPACITY".to_string()) && first.contains(&VERSION_KEY.to_string())
    );
    // Nothing new until RESEND_S has passed.
    assert!(r.poll(1.0, &mut gave_up).is_empty());
    // The vehicle answers all but BATT_CRT_MAH (dropped) and the version request.
    for n in ARDUPILOT_PARAMS.iter().filter(|n| **n != "BATT_CRT_MAH") {
        r.on_message(&param(1.2, 1, n, 1.0, REAL32));
    }
    assert!(r.take_changed());
    assert_eq!(
        names(&r.poll(1.8, &mut gave_up)),
        ["BATT_CRT_MAH", VERSION_KEY]
    );
    assert!(!r.settled());
    assert_eq!(
        names(&r.poll(3.4, &mut gave_up)),
        ["BATT_CRT_MAH", VERSION_KEY]
    );
    // Third try was the last: the next due time gives up, once.
    assert!(r.poll(5.0, &mut gave_up).is_empty());
    assert_eq!(gave_up, ["BATT_CRT_MAH", VERSION_KEY]);
    assert!(r.settled());
    assert!(r.poll(100.0, &mut gave_up).is_empty());
    assert_eq!(gave_up.len(), 2);
    let p = r.params();
    assert_eq!(p.absent, ["AUTOPILOT_VERSION", "BATT_CRT_MAH"]);
    assert_eq!(p.get("BATT_CAPACITY"), Some(1.0));
    assert_eq!(p.identity.unwrap().autopilot, Autopilot::ArduPilot);
}

#[test]
fn px4_values_decode_by_the_heartbeat_and_uid_is_kept() {
    let mut r = ParamReader::live();
    r.on_message(&msg(0.0, 7, 1, heartbeat(MavAutopilot::MAV_AUTOPILOT_PX4)));
    let mut gave_up = Vec::new();
    assert_eq!(
        names(&r.poll(0.0, &mut gave_up)).len(),
        PX4_PARAMS.len() + 1
    );
    r.on_message(&param(0.5, 7, "BAT1_N_CELLS", f32::from_bits(4), INT32));
    // Another system's value is not ours.
    r.on_message(&param(0.5, 8, "BAT1_CAPACITY", 9999.0, REAL32));
    r.on_message(&param(0.5, 7, "BAT1_CAPACITY", 5000.0, REAL32));
    let v = dialect::AUTOPILOT_VERSION_DATA {
        uid: 0xDEAD_BEEF,
        ..Default::default()
    };
    r.on_message(&msg(0.6, 7, 1, MavMessage::AUTOPILOT_VERSION(v)));
    let p = r.params();
    assert_eq!(
        (p.get("BAT1_N_CELLS"), p.get("BAT1_CAPACITY")),
        (Some(4.0), Some(5000.0))
    );
    assert_eq!(p.identity.unwrap().uid, Some(0xDEAD_BEEF));
}

#[test]
fn a_passive_reader_listens_only() {
    let mut r = ParamReader::passive();
    // A logged fetch may come before the first heartbeat.
    r.on_message(&param(0.0, 1, "BATT_CAPACITY", 3300.0, INT32));
    r.on_message(&param(0.1, 1, "SOME_OTHER", 1.0, REAL32));
    r.on_message(&msg(
        0.2,
        1,
        1,
        heartbeat(MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA),
    ));
    assert!(r.poll(10.0, &mut Vec::new()).is_empty());
    assert!(r.settled());
    let p = r.params();
    assert_eq!(p.values.len(), 1);
    assert_eq!(p.get("BATT_CAPACITY"), Some(3300.0));
}
