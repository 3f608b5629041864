//! A simulated PX4 flight as the autopilot's own ULog `.ulg` (what `simulate --autopilot px4
//! --out FILE.ulg` writes): the flight's MAVLink turned into the uORB topics PX4 logs (their
//! names and the fields dronewatt reads), timestamps in µs from the first record.
//!
//! | MAVLink | ULog |
//! |---|---|
//! | HEARTBEAT (on change) | `vehicle_status` arming_state, nav_state |
//! | PARAM_VALUE | parameters (`int32_t`/`float`) |
//! | ATTITUDE_QUATERNION | `vehicle_angular_velocity` xyz, then `vehicle_attitude` q |
//! | HIGHRES_IMU | `sensor_combined` gyro_rad, accelerometer_m_s2 |
//! | GLOBAL_POSITION_INT | `vehicle_local_position` vx, vy, vz, then `vehicle_global_position` lat, lon, alt |
//! | BATTERY_STATUS | `battery_status` voltage_v, current_a, discharged_mah, remaining |
//! | VFR_HUD | `airspeed_validated` true_airspeed_m_s |
//! | NAMED_VALUE_FLOAT | `debug_key_value` key, value |

use super::ulog::{Field, Topic, Value, Writer};
use crate::dialect as d;
use crate::MavMessage;

const fn f(ty: &'static str, name: &'static str) -> Field {
    Field { ty, name }
}

const fn topic(id: u16, name: &'static str, fields: &'static [Field]) -> Topic {
    Topic { id, name, fields }
}

const STATUS: Topic = topic(
    0,
    "vehicle_status",
    &[f("uint8_t", "arming_state"), f("uint8_t", "nav_state")],
);
const RATES: Topic = topic(1, "vehicle_angular_velocity", &[f("float[3]", "xyz")]);
const ATT: Topic = topic(2, "vehicle_attitude", &[f("float[4]", "q")]);
const IMU: Topic = topic(
    3,
    "sensor_combined",
    &[
        f("float[3]", "gyro_rad"),
        f("float[3]", "accelerometer_m_s2"),
    ],
);
const LPOS: Topic = topic(
    4,
    "vehicle_local_position",
    &[
        f("float", "x"),
        f("float", "y"),
        f("float", "z"),
        f("float", "vx"),
        f("float", "vy"),
        f("float", "vz"),
    ],
);
const GPOS: Topic = topic(
    5,
    "vehicle_global_position",
    &[f("double", "lat"), f("double", "lon"), f("float", "alt")],
);
const BAT: Topic = topic(
    6,
    "battery_status",
    &[
        f("float", "voltage_v"),
        f("float", "current_a"),
        f("float", "discharged_mah"),
        f("float", "remaining"),
    ],
);
const AIR: Topic = topic(8, "airspeed_validated", &[f("float", "true_airspeed_m_s")]);
const KV: Topic = topic(
    7,
    "debug_key_value",
    &[f("char[10]", "key"), f("float", "value")],
);

/// MAVLink `records` (µs since the Unix epoch, the message), in time order, as ULog `.ulg`
/// bytes (module docs).
pub fn from_mavlink(records: &[(u64, &MavMessage)]) -> Vec<u8> {
    use Value::{Nums as N, Text};
    let params: Vec<(String, f64, bool)> = records
        .iter()
        .filter_map(|&(_, msg)| match msg {
            MavMessage::PARAM_VALUE(p) => {
                let name = crate::source::messages::name_text(&p.param_id);
                let int = p.param_type == d::MavParamType::MAV_PARAM_TYPE_INT32;
                // PX4 sends an integer parameter as the float's bits.
                let v = if int {
                    f64::from(p.param_value.to_bits() as i32)
                } else {
                    f64::from(p.param_value)
                };
                Some((name, v, int))
            }
            _ => None,
        })
        .collect();
    let mut w = Writer::new(
        &[STATUS, RATES, ATT, IMU, LPOS, GPOS, BAT, KV, AIR],
        &params,
    );
    let t0 = records.first().map_or(0, |r| r.0);
    let mut last_status = None;
    for &(t_us, msg) in records {
        let t = t_us - t0;
        match msg {
            MavMessage::HEARTBEAT(h) => {
                let armed = h
                    .base_mode
                    .contains(d::MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
                let s = (if armed { 2.0 } else { 1.0 }, f64::from(h.custom_mode));
                if last_status != Some(s) {
                    last_status = Some(s);
                    w.data(&STATUS, t, &[N(&[s.0]), N(&[s.1])]);
                }
            }
            MavMessage::ATTITUDE_QUATERNION(a) => {
                w.data(
                    &RATES,
                    t,
                    &[N(&[a.rollspeed, a.pitchspeed, a.yawspeed].map(f64::from))],
                );
                w.data(&ATT, t, &[N(&[a.q1, a.q2, a.q3, a.q4].map(f64::from))]);
            }
            MavMessage::HIGHRES_IMU(m) => {
                w.data(
                    &IMU,
                    t,
                    &[
                        N(&[m.xgyro, m.ygyro, m.zgyro].map(f64::from)),
                        N(&[m.xacc, m.yacc, m.zacc].map(f64::from)),
                    ],
                );
            }
            MavMessage::GLOBAL_POSITION_INT(m) => {
                let v = [m.vx, m.vy, m.vz].map(|x| f64::from(x) * 0.01);
                w.data(
                    &LPOS,
                    t,
                    &[
                        N(&[0.0]),
                        N(&[0.0]),
                        N(&[-f64::from(m.relative_alt) * 1e-3]),
                        N(&v[..1]),
                        N(&v[1..2]),
                        N(&v[2..]),
                    ],
                );
                w.data(
                    &GPOS,
                    t,
                    &[
                        N(&[f64::from(m.lat) * 1e-7]),
                        N(&[f64::from(m.lon) * 1e-7]),
                        N(&[f64::from(m.alt) * 1e-3]),
                    ],
                );
            }
            MavMessage::BATTERY_STATUS(b) if b.id == 0 => {
                let volt = if b.voltages[0] == u16::MAX {
                    0.0
                } else {
                    f64::from(b.voltages[0]) * 1e-3
                };
                let rem = if b.battery_remaining < 0 {
                    -1.0
                } else {
                    f64::from(b.battery_remaining) * 0.01
                };
                w.data(
                    &BAT,
                    t,
                    &[
                        N(&[volt]),
                        N(&[f64::from(b.current_battery) * 0.01]),
                        N(&[f64::from(b.current_consumed)]),
                        N(&[rem]),
                    ],
                );
            }
            MavMessage::VFR_HUD(h) => w.data(&AIR, t, &[N(&[f64::from(h.airspeed)])]),
            MavMessage::NAMED_VALUE_FLOAT(n) => {
                let key = crate::source::messages::name_text(&n.name);
                w.data(&KV, t, &[Text(&key), N(&[f64::from(n.value)])]);
            }
            _ => {}
        }
    }
    w.into_bytes()
}
