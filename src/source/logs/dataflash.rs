//! ArduPilot DataFlash `.bin` logs (the autopilot's own SD-card log), read record by record
//! (`dataflash_records`: every message's layout comes from the file's own FMT
//! records, so any ArduPilot version reads) and turned into the same [`TimedMessage`]s a
//! tlog gives: MAVLink messages synthesised from the log's entries, `t_s` from their
//! `TimeUS` through a [`crate::source::frame::timed::Clock`]. Everything downstream (telemetry, windows,
//! `learn`, `replay`) is the tlog path unchanged.
//!
//! | DataFlash | MAVLink | used for |
//! |---|---|---|
//! | `ATT` Roll, Pitch, Yaw (deg) + the last `IMU` gyro | `ATTITUDE` | attitude, rates |
//! | `IMU` (instance 0) GyrX–Z, AccX–Z | `HIGHRES_IMU` | rates, acceleration |
//! | `XKF1`/`NKF1` (core 0) VN, VE, VD, PN, PE, PD | `LOCAL_POSITION_NED` | velocity |
//! | `POS` Lat, Lng, Alt, RelHomeAlt (+ the last EKF or GPS velocity) | `GLOBAL_POSITION_INT` | position |
//! | `GPS` (instance 0) Status, Lat, Lng, Alt, Spd, GCrs, VZ | `GPS_RAW_INT` | position (fallback) |
//! | `XKF2`/`NKF2` (core 0) VWN, VWE | `WIND_COV` | wind |
//! | `BAT` (instance 0) Volt, Curr, CurrTot, EnrgTot, RemPct | `SYS_STATUS`, `BATTERY_STATUS` | measured power V·I, charge |
//! | `PARM` Name, Value | `PARAM_VALUE` | `BATT_CAPACITY` etc. for the vehicle reader |
//! | `MODE` ModeNum, `ARM` ArmState | `HEARTBEAT` (1 Hz of log time) | the vehicle's identity |
//! | `NVF` Name, Value | `NAMED_VALUE_FLOAT` | mission hints (`cmd_speed`, …) |
//!
//! The synthesised HEARTBEAT says ArduPilot, with the frame from `FRAME_CLASS` (quadrotor
//! when the log has none). A missing message or field leaves its signal to the other
//! sources, as a tlog without it would (the telemetry stage degrades and says so); a file
//! that is not DataFlash, or has no timestamped message, is an error.

use crate::features::units::{centidegrees, scaled};
use std::collections::HashMap;

use super::dataflash_records::{Entry, Reader};

use super::synth::Synth;
use crate::dialect as d;
use crate::report::status::IngestStats;
use crate::source::TimedMessage;
use crate::MavMessage;

/// A DataFlash message's first two bytes.
pub const MAGIC: [u8; 2] = [0xA3, 0x95];
/// The FMT message's type.
pub const FMT_TYPE: u8 = 128;

/// What is wrong with a file that is not a readable DataFlash log.
#[derive(Debug, thiserror::Error)]
pub enum DataflashError {
    #[error(
        "not an ArduPilot DataFlash log (it does not start with the 0xA3 0x95 message header)"
    )]
    NotDataflash,
    #[error("no timestamped message (no FMT-described entry with TimeUS or TimeMS): an empty or corrupt log")]
    NoMessages,
}

/// Whether `path` names a DataFlash log (`.bin`, any case).
pub fn is_dataflash(path: &std::path::Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("bin"))
}

/// Whether the file at `path` starts with a DataFlash message header (a `.bin` may also be
/// a raw MAVLink capture). False when it cannot be read (opening it later says why).
pub fn starts_as_dataflash(path: &std::path::Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; 2];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok()
        && head == MAGIC
}

/// Decode a whole in-memory DataFlash log into MAVLink messages (see the module docs).
/// Clock jumps are counted in `stats`.
pub fn decode_dataflash(
    bytes: &[u8],
    stats: &IngestStats,
) -> Result<Vec<TimedMessage>, DataflashError> {
    if !bytes.starts_with(&MAGIC) {
        return Err(DataflashError::NotDataflash);
    }
    // First pass: the frame, so the first HEARTBEAT already names it.
    let mut frame_class = None;
    for e in Reader::new(bytes) {
        if e.name == "PARM" && e.get_str("Name") == Some("FRAME_CLASS") {
            frame_class = e.get_f64("Value");
        }
    }
    let mut s = State {
        syn: Synth::new(
            d::MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
            mav_type(frame_class),
        ),
        ..State::default()
    };
    let mut out = Vec::with_capacity(bytes.len() / 60);
    let mut records = Reader::new(bytes);
    for e in &mut records {
        s.entry(&e, stats, &mut out);
    }
    IngestStats::add(&stats.junk_bytes, records.skipped as u64);
    if !s.syn.timed {
        return Err(DataflashError::NoMessages);
    }
    Ok(out)
}

/// ArduPilot's `FRAME_CLASS` as a MAVLink vehicle type (quadrotor when unknown).
fn mav_type(frame_class: Option<f64>) -> d::MavType {
    use d::MavType as T;
    match frame_class.map(|f| f.round() as i64) {
        Some(2 | 5) => T::MAV_TYPE_HEXAROTOR,
        Some(3 | 4) => T::MAV_TYPE_OCTOROTOR,
        Some(7) => T::MAV_TYPE_TRICOPTER,
        Some(6) => T::MAV_TYPE_HELICOPTER,
        Some(12) => T::MAV_TYPE_DODECAROTOR,
        Some(13) => T::MAV_TYPE_HEXAROTOR,
        _ => T::MAV_TYPE_QUADROTOR,
    }
}

#[derive(Default)]
struct State {
    syn: Synth,
    gyro: [f32; 3],
    /// The last EKF (core 0) and GPS NED velocities, m/s.
    ekf_vel: Option<[f64; 3]>,
    gps_vel: Option<[f64; 3]>,
    /// Labels a message was missing, warned once per (message, label).
    missing: HashMap<(String, &'static str), ()>,
}

impl State {
    /// A field, or None (warned once per message and field).
    fn f(&mut self, e: &Entry, label: &'static str) -> Option<f64> {
        let v = e.get_f64(label).filter(|v| v.is_finite());
        if v.is_none() && self.missing.insert((e.name.clone(), label), ()).is_none() {
            tracing::warn!(message = %e.name, field = label, "DataFlash message without this field: what it carries is not used");
        }
        v
    }

    /// Instance / core 0 (or a message without one).
    fn first(e: &Entry, label: &str) -> bool {
        e.get_f64(label).is_none_or(|i| i == 0.0)
    }

    fn entry(&mut self, e: &Entry, stats: &IngestStats, out: &mut Vec<TimedMessage>) {
        // TimeUS (TimeMS in logs before ArduPilot 3.3, scaled to µs by the reader).
        if let Some(us) = e.timestamp_usec.filter(|_| {
            e.labels()
                .first()
                .is_some_and(|l| l == "TimeUS" || l == "TimeMS")
        }) {
            self.syn.at(us, stats, out);
        }
        let (n, boot_ms) = (e.name.as_str(), self.syn.boot_ms);
        match n {
            "PARM" => {
                if let (Some(name), Some(v)) = (e.get_str("Name"), e.get_f64("Value")) {
                    let real = d::MavParamType::MAV_PARAM_TYPE_REAL32;
                    self.syn.param(name, v as f32, real, out);
                }
            }
            "MODE" => {
                if let Some(m) = e.get_f64("ModeNum").or_else(|| e.get_f64("Mode")) {
                    self.syn.custom_mode = m as u32;
                    self.syn.announce(out);
                }
            }
            "ARM" => {
                if let Some(a) = e.get_f64("ArmState") {
                    self.syn.armed = a != 0.0;
                    self.syn.announce(out);
                }
            }
            "IMU" if Self::first(e, "I") => {
                let g = ["GyrX", "GyrY", "GyrZ"].map(|l| self.f(e, l));
                let a = ["AccX", "AccY", "AccZ"].map(|l| self.f(e, l));
                let (Some(g), Some(a)) = (all(g), all(a)) else {
                    return;
                };
                self.gyro = g.map(|x| x as f32);
                let time_usec = u64::from(boot_ms) * 1000;
                self.syn.imu(time_usec, a.map(|x| x as f32), self.gyro, out);
            }
            "ATT" => {
                let Some([roll, pitch, yaw]) = all(["Roll", "Pitch", "Yaw"].map(|l| self.f(e, l)))
                else {
                    return;
                };
                let [rollspeed, pitchspeed, yawspeed] = self.gyro;
                let rad = |deg: f64| deg.to_radians() as f32;
                let m = d::ATTITUDE_DATA {
                    time_boot_ms: boot_ms,
                    roll: rad(roll),
                    pitch: rad(pitch),
                    yaw: rad(yaw),
                    rollspeed,
                    pitchspeed,
                    yawspeed,
                };
                self.syn.push(MavMessage::ATTITUDE(m), out);
            }
            "XKF1" | "NKF1" if Self::first(e, "C") => {
                let Some(v) = all(["VN", "VE", "VD"].map(|l| self.f(e, l))) else {
                    return;
                };
                self.ekf_vel = Some(v);
                let p = ["PN", "PE", "PD"].map(|l| e.get_f64(l).unwrap_or(0.0) as f32);
                self.syn.local_ned(p, v.map(|x| x as f32), out);
            }
            "XKF2" | "NKF2" if Self::first(e, "C") => {
                let Some([n, e_]) = all(["VWN", "VWE"].map(|l| self.f(e, l))) else {
                    return;
                };
                self.syn.wind(u64::from(boot_ms) * 1000, n, e_, out);
            }
            "GPS" if Self::first(e, "I") => self.gps(e, out),
            "POS" => self.pos(e, out),
            "BAT" if Self::first(e, "Inst") || Self::first(e, "Instance") => {
                let Some(volt) = self.f(e, "Volt") else {
                    return;
                };
                let amps = self.f(e, "Curr");
                let remaining = e
                    .get_f64("RemPct")
                    .and_then(|p| scaled::<i8>(p.clamp(0.0, 100.0), 1.0))
                    .unwrap_or(-1);
                self.syn.battery(
                    volt,
                    amps,
                    remaining,
                    e.get_f64("CurrTot"),
                    e.get_f64("EnrgTot"),
                    out,
                );
            }
            "NVF" => {
                if let (Some(name), Some(v)) = (e.get_str("Name"), e.get_f64("Value")) {
                    let m = d::NAMED_VALUE_FLOAT_DATA {
                        time_boot_ms: boot_ms,
                        value: v as f32,
                        name: name.into(),
                    };
                    self.syn.push(MavMessage::NAMED_VALUE_FLOAT(m), out);
                }
            }
            _ => {}
        }
    }

    /// GPS (instance 0): GPS_RAW_INT, and the GPS's velocity for POS when the EKF gives none.
    fn gps(&mut self, e: &Entry, out: &mut Vec<TimedMessage>) {
        let boot_ms = self.syn.boot_ms;
        let (Some(status), Some(lat), Some(lng)) =
            (self.f(e, "Status"), self.f(e, "Lat"), self.f(e, "Lng"))
        else {
            return;
        };
        let alt = e.get_f64("Alt").unwrap_or(0.0);
        let (spd, crs, vz) = (e.get_f64("Spd"), e.get_f64("GCrs"), e.get_f64("VZ"));
        if let (Some(s), Some(c)) = (spd, crs) {
            let c = c.to_radians();
            self.gps_vel = Some([s * c.cos(), s * c.sin(), vz.unwrap_or(0.0)]);
        }
        let fix = match status as i64 {
            0 => d::GpsFixType::GPS_FIX_TYPE_NO_GPS,
            1 => d::GpsFixType::GPS_FIX_TYPE_NO_FIX,
            2 => d::GpsFixType::GPS_FIX_TYPE_2D_FIX,
            3 => d::GpsFixType::GPS_FIX_TYPE_3D_FIX,
            4 => d::GpsFixType::GPS_FIX_TYPE_DGPS,
            5 => d::GpsFixType::GPS_FIX_TYPE_RTK_FLOAT,
            _ => d::GpsFixType::GPS_FIX_TYPE_RTK_FIXED,
        };
        let m = d::GPS_RAW_INT_DATA {
            time_usec: u64::from(boot_ms) * 1000,
            fix_type: fix,
            lat: scaled(lat, 1.0).unwrap_or(0),
            lon: scaled(lng, 1.0).unwrap_or(0),
            alt: scaled(alt, 1000.0).unwrap_or(0),
            vel: spd
                .and_then(|s| scaled::<u16>(s.max(0.0), 100.0))
                .map_or(u16::MAX, |v| v.min(65_534)),
            cog: crs.and_then(centidegrees).unwrap_or(u16::MAX),
            satellites_visible: e
                .get_f64("NSats")
                .and_then(|n| scaled(n, 1.0))
                .unwrap_or(u8::MAX),
            eph: u16::MAX,
            epv: u16::MAX,
            ..Default::default()
        };
        self.syn.push(MavMessage::GPS_RAW_INT(m), out);
    }

    /// POS: GLOBAL_POSITION_INT, with the EKF's velocity, else the GPS's.
    fn pos(&mut self, e: &Entry, out: &mut Vec<TimedMessage>) {
        let boot_ms = self.syn.boot_ms;
        let (Some(lat), Some(lng), Some(alt)) =
            (self.f(e, "Lat"), self.f(e, "Lng"), self.f(e, "Alt"))
        else {
            return;
        };
        // POS carries no velocity: the EKF's, else the GPS's (no velocity at all:
        // none is offered from here).
        let Some(v) = self.ekf_vel.or(self.gps_vel) else {
            return;
        };
        let [vx, vy, vz] = v.map(|x| scaled(x, 100.0).unwrap_or(0));
        let rel = e.get_f64("RelHomeAlt").unwrap_or(0.0);
        let m = d::GLOBAL_POSITION_INT_DATA {
            time_boot_ms: boot_ms,
            lat: scaled(lat, 1.0).unwrap_or(0),
            lon: scaled(lng, 1.0).unwrap_or(0),
            alt: scaled(alt, 1000.0).unwrap_or(0),
            relative_alt: scaled(rel, 1000.0).unwrap_or(0),
            vx,
            vy,
            vz,
            hdg: u16::MAX,
        };
        self.syn.push(MavMessage::GLOBAL_POSITION_INT(m), out);
    }
}

fn all<const N: usize>(v: [Option<f64>; N]) -> Option<[f64; N]> {
    v.iter()
        .all(Option::is_some)
        .then(|| v.map(|x| x.unwrap_or(0.0)))
}

/// A DataFlash field's value, written as its format character says.
#[derive(Debug, Clone, Copy)]
pub enum Value<'a> {
    Int(i64),
    Float(f64),
    Str(&'a str),
}

/// One message type: its id, name (≤ 4 characters), format characters and labels.
#[derive(Debug, Clone, Copy)]
pub struct MsgDef {
    pub id: u8,
    pub name: &'static str,
    pub format: &'static str,
    pub labels: &'static str,
}

/// Writes DataFlash logs (the simulator's `.bin` output): each message type's FMT before
/// its first message, then `0xA3 0x95 id payload` records, little-endian, as ArduPilot's
/// logger does (format characters: `bBhHiIqQfdnNZcCeELM`).
#[derive(Debug)]
pub struct Writer {
    buf: Vec<u8>,
    defined: [bool; 256],
}

impl Default for Writer {
    fn default() -> Self {
        Self::new()
    }
}

impl Writer {
    pub fn new() -> Self {
        Self {
            buf: Vec::new(),
            defined: [false; 256],
        }
    }

    /// The log's bytes.
    pub fn into_bytes(self) -> Vec<u8> {
        self.buf
    }

    /// Append one message of type `def` (its FMT first if not yet written). A value that
    /// does not fit its field is clamped; a string is cut to the field.
    pub fn write(&mut self, def: &MsgDef, values: &[Value]) {
        if !self.defined[def.id as usize] {
            self.defined[def.id as usize] = true;
            let len = 3 + def.format.chars().map(field_size).sum::<usize>();
            let fmt = MsgDef {
                id: FMT_TYPE,
                name: "FMT",
                format: "BBnNZ",
                labels: "Type,Length,Name,Format,Labels",
            };
            self.write(
                &fmt,
                &[
                    Value::Int(def.id.into()),
                    Value::Int(len as i64),
                    Value::Str(def.name),
                    Value::Str(def.format),
                    Value::Str(def.labels),
                ],
            );
        }
        self.buf.extend_from_slice(&MAGIC);
        self.buf.push(def.id);
        for (c, v) in def.format.chars().zip(
            values
                .iter()
                .copied()
                .chain(std::iter::repeat(Value::Int(0))),
        ) {
            let (i, f) = match v {
                Value::Int(i) => (i, i as f64),
                Value::Float(f) => (f.round() as i64, f),
                Value::Str(_) => (0, 0.0),
            };
            let b = &mut self.buf;
            match c {
                'b' => b.push(i.clamp(-128, 127) as i8 as u8),
                'B' | 'M' => b.push(i.clamp(0, 255) as u8),
                'h' => b.extend((i.clamp(-32768, 32767) as i16).to_le_bytes()),
                'H' => b.extend((i.clamp(0, 65535) as u16).to_le_bytes()),
                'i' | 'L' => {
                    b.extend((i.clamp(i32::MIN.into(), i32::MAX.into()) as i32).to_le_bytes())
                }
                'I' => b.extend((i.clamp(0, u32::MAX.into()) as u32).to_le_bytes()),
                'q' => b.extend(i.to_le_bytes()),
                'Q' => b.extend((i.max(0) as u64).to_le_bytes()),
                'f' => b.extend((f as f32).to_le_bytes()),
                'd' => b.extend(f.to_le_bytes()),
                'c' => b.extend(scaled::<i16>(f, 100.0).unwrap_or(0).to_le_bytes()),
                'C' => b.extend(scaled::<u16>(f, 100.0).unwrap_or(0).to_le_bytes()),
                'e' => b.extend(scaled::<i32>(f, 100.0).unwrap_or(0).to_le_bytes()),
                'E' => b.extend(scaled::<u32>(f, 100.0).unwrap_or(0).to_le_bytes()),
                'n' | 'N' | 'Z' => {
                    let n = field_size(c);
                    let s = if let Value::Str(s) = v {
                        s.as_bytes()
                    } else {
                        &[]
                    };
                    let s = &s[..s.len().min(n)];
                    b.extend_from_slice(s);
                    b.extend(std::iter::repeat_n(0u8, n - s.len()));
                }
                _ => {}
            }
        }
    }
}

/// Bytes of one field of format character `c` (0: a character the writer does not write).
fn field_size(c: char) -> usize {
    match c {
        'b' | 'B' | 'M' => 1,
        'h' | 'H' | 'c' | 'C' => 2,
        'i' | 'I' | 'f' | 'e' | 'E' | 'L' | 'n' => 4,
        'q' | 'Q' | 'd' => 8,
        'N' => 16,
        'Z' => 64,
        _ => 0,
    }
}

#[cfg(test)]
#[path = "dataflash_tests.rs"]
mod tests;
