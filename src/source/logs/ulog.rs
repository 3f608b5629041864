//! PX4 ULog `.ulg` logs (the autopilot's own SD-card log), read with the `yule_log` crate
//! (streaming; every topic's layout comes from the file's own format definitions) and
//! turned into the same [`TimedMessage`]s a tlog gives, as [`super::dataflash`] does for
//! ArduPilot: `t_s` from each topic's `timestamp` (µs since boot) through a
//! [`crate::source::frame::timed::Clock`].
//!
//! | uORB topic (instance 0) | MAVLink | used for |
//! |---|---|---|
//! | `vehicle_attitude` q + the last `vehicle_angular_velocity` xyz | `ATTITUDE_QUATERNION` | attitude, rates |
//! | `sensor_combined` gyro_rad, accelerometer_m_s2 | `HIGHRES_IMU` | rates, acceleration |
//! | `vehicle_local_position` vx, vy, vz | `LOCAL_POSITION_NED` | velocity |
//! | `vehicle_global_position` lat, lon, alt (+ the last local velocity) | `GLOBAL_POSITION_INT` | position |
//! | `wind` / `wind_estimate` windspeed_north, windspeed_east | `WIND_COV` | wind |
//! | `battery_status` voltage_v, current_a, discharged_mah, remaining | `SYS_STATUS`, `BATTERY_STATUS` | measured power V·I, charge |
//! | parameters (`BAT1_CAPACITY`, …) | `PARAM_VALUE` (PX4's encoding: integers as the float's bits) | the vehicle reader |
//! | `vehicle_status` arming_state, nav_state | `HEARTBEAT` (1 Hz of log time; PX4, frame from `MAV_TYPE`) | the vehicle |
//! | `airspeed_validated` true_airspeed_m_s + the attitude's heading | `VFR_HUD` | airspeed (when there is no wind estimate) |
//! | `debug_key_value` key, value | `NAMED_VALUE_FLOAT` | mission hints (`cmd_speed`, …) |
//!
//! A missing topic or field leaves its signal to the other sources; a file that is not
//! ULog, or has no logged data, is an error.

use crate::features::units::{scaled, whole_degrees};
use yule_log::model::inst::{FieldValue as V, Format, ParameterValue};
use yule_log::model::msg::UlogMessage;

use super::synth::Synth;
use crate::dialect as d;
use crate::report::status::IngestStats;
use crate::source::TimedMessage;
use crate::MavMessage;

/// What is wrong with a file that is not a readable ULog.
#[derive(Debug, thiserror::Error)]
pub enum UlogError {
    #[error("no logged data (an empty or corrupt log)")]
    NoMessages,
    #[error("not a readable PX4 ULog: {0}")]
    Read(#[from] yule_log::errors::ULogError),
    #[error("not a readable PX4 ULog: the ULog parser (yule_log) gave up on it: {0}")]
    ParserPanicked(String),
    #[error("not a readable PX4 ULog: {0} (refused before parsing: the parser would crash on it)")]
    UnsafeFormats(String),
    #[error("cut short: its last record runs past the end of the file ({len} bytes; the records end at byte {at})")]
    CutShort { at: usize, len: usize },
}

/// Where the records of a log that ends in the middle of one end (the parser stops there
/// without a word): `None` when the records end with the file. A ULog is a 16-byte header,
/// then records of a 2-byte size, a type byte and the body.
fn cut_short(bytes: &[u8]) -> Option<UlogError> {
    let mut at = 16;
    while let Some(&[a, b, _]) = bytes.get(at..at + 3) {
        let next = at + 3 + usize::from(u16::from_le_bytes([a, b]));
        if next > bytes.len() {
            break;
        }
        at = next;
    }
    (at < bytes.len()).then_some(UlogError::CutShort {
        at,
        len: bytes.len(),
    })
}

/// Whether `path` names a ULog (`.ulg`, any case).
pub fn is_ulog(path: &std::path::Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("ulg"))
}

/// A field as numbers (a scalar is one).
fn nums(f: &Format, name: &str) -> Option<Vec<f64>> {
    let v = &f.fields.iter().find(|x| x.name.as_ref() == name)?.value;
    let one = |x: f64| Some(vec![x]);
    match v {
        V::ScalarU8(x) => one((*x).into()),
        V::ScalarU16(x) => one((*x).into()),
        V::ScalarU32(x) => one((*x).into()),
        V::ScalarU64(x) => one(*x as f64),
        V::ScalarI8(x) => one((*x).into()),
        V::ScalarI16(x) => one((*x).into()),
        V::ScalarI32(x) => one((*x).into()),
        V::ScalarI64(x) => one(*x as f64),
        V::ScalarF32(x) => one((*x).into()),
        V::ScalarF64(x) => one(*x),
        V::ScalarBool(x) => one(f64::from(u8::from(*x))),
        V::ArrayF32(a) => Some(a.iter().map(|&x| x.into()).collect()),
        V::ArrayF64(a) => Some(a.clone()),
        V::ArrayI32(a) => Some(a.iter().map(|&x| x.into()).collect()),
        V::ArrayU8(a) => Some(a.iter().map(|&x| x.into()).collect()),
        _ => None,
    }
    .filter(|v| v.iter().all(|x| x.is_finite()))
}

fn num(f: &Format, name: &str) -> Option<f64> {
    nums(f, name).and_then(|v| v.first().copied())
}

fn vec3(f: &Format, name: &str) -> Option<[f32; 3]> {
    let v = nums(f, name)?;
    (v.len() >= 3).then(|| [v[0] as f32, v[1] as f32, v[2] as f32])
}

fn text(f: &Format, name: &str) -> Option<String> {
    match &f.fields.iter().find(|x| x.name.as_ref() == name)?.value {
        V::ArrayChar(a) => Some(
            a.iter()
                .map(|c| c.as_char())
                .take_while(|&c| c != '\0')
                .collect(),
        ),
        _ => None,
    }
}

/// PX4's `MAV_TYPE` parameter as a MAVLink vehicle type (quadrotor when unknown).
fn mav_type(v: Option<i32>) -> d::MavType {
    use num_traits::FromPrimitive;
    v.and_then(d::MavType::from_i32)
        .filter(|t| *t != d::MavType::MAV_TYPE_GCS)
        .unwrap_or(d::MavType::MAV_TYPE_QUADROTOR)
}

#[derive(Default)]
struct State {
    syn: Synth,
    rates: [f32; 3],
    /// Heading of the last attitude, degrees 0–360.
    heading_deg: Option<f64>,
    vel: Option<[f32; 3]>,
}

impl State {
    fn param(&mut self, key: &str, value: &ParameterValue, out: &mut Vec<TimedMessage>) {
        use d::MavParamType as T;
        let (v, t) = match value {
            ParameterValue::FLOAT(x) => (*x, T::MAV_PARAM_TYPE_REAL32),
            ParameterValue::INT32(i) => (f32::from_bits(*i as u32), T::MAV_PARAM_TYPE_INT32),
        };
        self.syn.param(key, v, t, out);
    }

    fn data(
        &mut self,
        timestamp: u64,
        f: &Format,
        stats: &IngestStats,
        out: &mut Vec<TimedMessage>,
    ) {
        if f.multi_id_index.is_some_and(|i| i != 0) {
            return;
        }
        self.syn.at(timestamp, stats, out);
        let boot_ms = self.syn.boot_ms;
        match f.name.as_ref() {
            "vehicle_status" => {
                if let Some(a) = num(f, "arming_state") {
                    self.syn.armed = a == 2.0;
                }
                if let Some(n) = num(f, "nav_state") {
                    self.syn.custom_mode = n as u32;
                }
            }
            "vehicle_angular_velocity" => {
                if let Some(r) = vec3(f, "xyz") {
                    self.rates = r;
                }
            }
            "vehicle_attitude" => self.attitude(f, out),
            "sensor_combined" => {
                let (Some(gyro), Some(acc)) = (vec3(f, "gyro_rad"), vec3(f, "accelerometer_m_s2"))
                else {
                    return;
                };
                self.syn.imu(timestamp, acc, gyro, out);
            }
            "vehicle_local_position" => {
                let (Some(vx), Some(vy), Some(vz)) = (num(f, "vx"), num(f, "vy"), num(f, "vz"))
                else {
                    return;
                };
                let v = [vx, vy, vz].map(|x| x as f32);
                self.vel = Some(v);
                let p = ["x", "y", "z"].map(|k| num(f, k).unwrap_or(0.0) as f32);
                self.syn.local_ned(p, v, out);
            }
            "vehicle_global_position" => self.global_position(f, out),
            "wind" | "wind_estimate" => {
                let (Some(n), Some(e)) = (num(f, "windspeed_north"), num(f, "windspeed_east"))
                else {
                    return;
                };
                self.syn.wind(timestamp, n, e, out);
            }
            "battery_status" => {
                let Some(volt) = num(f, "voltage_v") else {
                    return;
                };
                let amps = num(f, "current_a").filter(|&c| c >= 0.0);
                let remaining = num(f, "remaining")
                    .filter(|r| (0.0..=1.0).contains(r))
                    .and_then(|r| scaled(r, 100.0))
                    .unwrap_or(-1);
                self.syn
                    .battery(volt, amps, remaining, num(f, "discharged_mah"), None, out);
            }
            "airspeed_validated" => {
                let (Some(air), Some(hdg)) = (num(f, "true_airspeed_m_s"), self.heading_deg) else {
                    return;
                };
                let ground = self.vel.map_or(0.0, |v| v[0].hypot(v[1]));
                let m = d::VFR_HUD_DATA {
                    airspeed: air as f32,
                    groundspeed: ground,
                    heading: whole_degrees(hdg).unwrap_or(0),
                    ..Default::default()
                };
                self.syn.push(MavMessage::VFR_HUD(m), out);
            }
            "debug_key_value" => {
                if let (Some(k), Some(v)) = (text(f, "key"), num(f, "value")) {
                    let m = d::NAMED_VALUE_FLOAT_DATA {
                        time_boot_ms: boot_ms,
                        value: v as f32,
                        name: k.as_str().into(),
                    };
                    self.syn.push(MavMessage::NAMED_VALUE_FLOAT(m), out);
                }
            }
            _ => {}
        }
    }

    /// vehicle_attitude: ATTITUDE_QUATERNION with the last angular rates; keeps the heading.
    fn attitude(&mut self, f: &Format, out: &mut Vec<TimedMessage>) {
        let boot_ms = self.syn.boot_ms;
        let Some(q) = nums(f, "q").filter(|q| q.len() == 4) else {
            return;
        };
        let [rollspeed, pitchspeed, yawspeed] = self.rates;
        let yaw =
            (2.0 * (q[0] * q[3] + q[1] * q[2])).atan2(1.0 - 2.0 * (q[2] * q[2] + q[3] * q[3]));
        self.heading_deg = Some(yaw.to_degrees().rem_euclid(360.0));
        let [q1, q2, q3, q4] = [q[0], q[1], q[2], q[3]].map(|x| x as f32);
        let m = d::ATTITUDE_QUATERNION_DATA {
            time_boot_ms: boot_ms,
            q1,
            q2,
            q3,
            q4,
            rollspeed,
            pitchspeed,
            yawspeed,
            ..Default::default()
        };
        self.syn.push(MavMessage::ATTITUDE_QUATERNION(m), out);
    }

    /// vehicle_global_position: GLOBAL_POSITION_INT with the last local velocity (none
    /// before a fix or a velocity).
    fn global_position(&mut self, f: &Format, out: &mut Vec<TimedMessage>) {
        let boot_ms = self.syn.boot_ms;
        let (Some(lat), Some(lon), Some(alt)) = (num(f, "lat"), num(f, "lon"), num(f, "alt"))
        else {
            return;
        };
        // NaN (no estimate yet) or (0, 0) is no fix: nothing to send on as a position.
        if !crate::features::frames::is_fix(lat, lon) || !alt.is_finite() {
            return;
        }
        let Some(v) = self.vel else { return };
        let [vx, vy, vz] = v.map(|x| scaled(f64::from(x), 100.0).unwrap_or(0));
        let m = d::GLOBAL_POSITION_INT_DATA {
            time_boot_ms: boot_ms,
            lat: scaled(lat, 1e7).unwrap_or(0),
            lon: scaled(lon, 1e7).unwrap_or(0),
            alt: scaled(alt, 1000.0).unwrap_or(0),
            relative_alt: 0,
            vx,
            vy,
            vz,
            hdg: u16::MAX,
        };
        self.syn.push(MavMessage::GLOBAL_POSITION_INT(m), out);
    }
}

/// Decode a whole in-memory ULog into MAVLink messages (see the module docs). Clock jumps
/// are counted in `stats`. A log that breaks after some data (see [`read_ulog`]) gives
/// what was read before the fault.
pub fn decode_ulog(bytes: &[u8], stats: &IngestStats) -> Result<Vec<TimedMessage>, UlogError> {
    read_ulog(bytes, stats).map(|(m, _)| m)
}

/// [`decode_ulog`], and the fault that ended the log early, if one did.
///
/// The `yule_log` parser panics on some malformed files (fuzzing found an `unwrap` on a
/// format definition's array length), returns an error on others and stops without one
/// at a record cut short by the end of the file ([`UlogError::CutShort`]):
/// the parse runs under `catch_unwind`, and either way the messages decoded before the
/// fault are kept, the fault is counted once in `stats.frames_bad` and returned beside
/// them. A file that breaks before its first logged data is an error
/// ([`UlogError::ParserPanicked`], [`UlogError::Read`] or [`UlogError::NoMessages`]), and
/// so is one whose formats would make the parser abort, which no `catch_unwind` contains
/// ([`UlogError::UnsafeFormats`]: a type that contains itself, an array without bound).
pub fn read_ulog(
    bytes: &[u8],
    stats: &IngestStats,
) -> Result<(Vec<TimedMessage>, Option<UlogError>), UlogError> {
    let mut s = State {
        syn: Synth::new(
            d::MavAutopilot::MAV_AUTOPILOT_PX4,
            d::MavType::MAV_TYPE_QUADROTOR,
        ),
        ..State::default()
    };
    if let Some(why) = super::ulog_formats::unsafe_formats(bytes) {
        return Err(UlogError::UnsafeFormats(why));
    }
    let mut out = Vec::with_capacity(bytes.len() / 60);
    let run = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        decode(bytes, stats, &mut s, &mut out)
    }));
    let fault = match run {
        Ok(r) => r.err().or_else(|| cut_short(bytes)),
        Err(p) => {
            let why = p
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| p.downcast_ref::<&str>().copied())
                .unwrap_or("a panic");
            Some(UlogError::ParserPanicked(why.to_string()))
        }
    };
    if !s.syn.timed {
        return Err(fault.unwrap_or(UlogError::NoMessages));
    }
    if fault.is_some() {
        stats
            .frames_bad
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }
    Ok((out, fault))
}

fn decode(
    bytes: &[u8],
    stats: &IngestStats,
    s: &mut State,
    out: &mut Vec<TimedMessage>,
) -> Result<(), UlogError> {
    let mut params = Vec::new();
    let mut mav_type_param = None;
    let parser = yule_log::builder::ULogParserBuilder::new(bytes).build()?;
    for m in parser {
        match m? {
            UlogMessage::Parameter(p) => {
                if p.key == "MAV_TYPE" {
                    if let ParameterValue::INT32(i) = p.value {
                        mav_type_param = Some(i);
                    }
                }
                params.push((p.key, p.value));
            }
            UlogMessage::LoggedData(ld) => {
                if !s.syn.timed {
                    // The definitions section is over: the vehicle, then its parameters.
                    s.syn.mavtype = mav_type(mav_type_param);
                    let t = ld.timestamp;
                    s.data(t, &ld.data, stats, out);
                    for (k, v) in std::mem::take(&mut params) {
                        s.param(&k, &v, out);
                    }
                } else {
                    s.data(ld.timestamp, &ld.data, stats, out);
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// One field of a ULog topic: its C type (`uint64_t`, `float`, `double`, `uint8_t`,
/// `char`, with `[n]` for an array) and name.
#[derive(Debug, Clone, Copy)]
pub struct Field {
    pub ty: &'static str,
    pub name: &'static str,
}

/// A topic the writer logs.
#[derive(Debug, Clone, Copy)]
pub struct Topic {
    pub id: u16,
    pub name: &'static str,
    /// The fields after `uint64_t timestamp`.
    pub fields: &'static [Field],
}

/// A field's value for [`Writer::data`]: numbers in the field's type, text for `char[n]`.
#[derive(Debug, Clone)]
pub enum Value<'a> {
    Nums(&'a [f64]),
    Text(&'a str),
}

/// Writes ULog files (the simulator's `.ulg` output), as PX4's logger lays them out: the
/// 16-byte header, the flag bits, each topic's format ('F') and subscription ('A'), the
/// parameters ('P'), then data ('D'), little-endian and packed.
#[derive(Debug)]
pub struct Writer {
    buf: Vec<u8>,
}

impl Writer {
    /// Header and flag bits, then the topics' formats and subscriptions and the parameters
    /// (`(name, value, is_int)`).
    pub fn new(topics: &[Topic], params: &[(String, f64, bool)]) -> Self {
        let mut buf = b"ULog\x01\x12\x35".to_vec();
        buf.push(1);
        buf.extend(0u64.to_le_bytes());
        let mut w = Self { buf };
        w.message(b'B', &[0u8; 40]);
        for t in topics {
            let mut fmt = format!("{}:uint64_t timestamp;", t.name);
            for f in t.fields {
                fmt.push_str(&format!("{} {};", f.ty, f.name));
            }
            w.message(b'F', fmt.as_bytes());
        }
        for (name, v, int) in params {
            let key = format!("{} {name}", if *int { "int32_t" } else { "float" });
            let mut p = vec![key.len() as u8];
            p.extend(key.as_bytes());
            if *int {
                p.extend((*v as i32).to_le_bytes());
            } else {
                p.extend((*v as f32).to_le_bytes());
            }
            w.message(b'P', &p);
        }
        for t in topics {
            let mut a = vec![0u8];
            a.extend(t.id.to_le_bytes());
            a.extend(t.name.as_bytes());
            w.message(b'A', &a);
        }
        w
    }

    fn message(&mut self, kind: u8, payload: &[u8]) {
        self.buf.extend((payload.len() as u16).to_le_bytes());
        self.buf.push(kind);
        self.buf.extend_from_slice(payload);
    }

    /// One sample of `topic` at `t_us` (µs since boot); `values` in the topic's field order.
    pub fn data(&mut self, topic: &Topic, t_us: u64, values: &[Value]) {
        let mut p = topic.id.to_le_bytes().to_vec();
        p.extend(t_us.to_le_bytes());
        for (f, v) in topic.fields.iter().zip(values) {
            let (base, n) = match f.ty.split_once('[') {
                Some((b, n)) => (b, n.trim_end_matches(']').parse::<usize>().unwrap_or(1)),
                None => (f.ty, 1),
            };
            match v {
                Value::Text(s) => {
                    let b = s.as_bytes();
                    p.extend((0..n).map(|i| b.get(i).copied().unwrap_or(0)));
                }
                Value::Nums(x) => {
                    for i in 0..n {
                        let x = x.get(i).copied().unwrap_or(0.0);
                        match base {
                            "float" => p.extend((x as f32).to_le_bytes()),
                            "double" => p.extend(x.to_le_bytes()),
                            "uint8_t" | "bool" => p.push(x as u8),
                            "int32_t" => p.extend((x as i32).to_le_bytes()),
                            "uint64_t" => p.extend((x as u64).to_le_bytes()),
                            _ => {}
                        }
                    }
                }
            }
        }
        self.message(b'D', &p);
    }

    /// The log's bytes.
    pub fn into_bytes(self) -> Vec<u8> {
        self.buf
    }
}

#[cfg(test)]
#[path = "ulog_tests.rs"]
mod tests;
