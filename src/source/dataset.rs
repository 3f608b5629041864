//! The M100 data set as a MAVLink source: each CSV row encoded as the messages an
//! autopilot would send, so replay, evaluation and training walk the live ingest path.
//!
//! ## Reading
//!
//! [`read_flights`] reads the official `flights.csv` as it is: plain or gzip (told apart by
//! the gzip magic bytes, not the name), columns found by header name (any order, extra
//! columns ignored, a missing one is an error naming it), CRLF or LF. A row that cannot be
//! used (wrong field count, a sensor cell that is not a finite number, a time that does
//! not increase within its flight) is **skipped and counted**, with its file, line and
//! column in [`DataSet::skipped`] and a warning: the house rule for corrupt input, and one
//! bad row in 247,308 should not stop a training run. The caller sees the count and
//! decides (the official file has none).
//!
//! ## Encoding (one row → one burst of messages, all stamped with the row's time)
//!
//! | data-set columns | MAVLink message(s) |
//! |---|---|
//! | `orientation_*` (body right-forward-up → ENU) | ATTITUDE (ZYX Euler of the FRD→NED attitude) and ATTITUDE_QUATERNION (FRD→NED) |
//! | `angular_*` (FRD) | the rates of ATTITUDE/ATTITUDE_QUATERNION, and HIGHRES_IMU gyro |
//! | `linear_acceleration_*` (FRD specific force) | HIGHRES_IMU acc, m/s² |
//! | `velocity_*` (right, forward, up; heading frame) | rotated to NED by the heading: LOCAL_POSITION_NED (float m/s), GLOBAL_POSITION_INT vx/vy/vz (cm/s) |
//! | `position_*` | GLOBAL_POSITION_INT (1e-7 deg, mm MSL), LOCAL_POSITION_NED x/y/z from home; HOME_POSITION once at the first non-zero fix |
//! | `wind_speed`, `wind_angle` (apparent wind, from-direction) | WIND = the true wind (apparent + ground velocity), VFR_HUD.airspeed = `wind_speed` |
//! | `battery_voltage`, `battery_current` | SYS_STATUS and BATTERY_STATUS (id 0, total in cell 0): mV and cA |
//! | `speed`, `payload`, `altitude` | NAMED_VALUE_FLOAT `cmd_speed` (m/s), `payload_g` (g), `cmd_alt` (m), at 1 Hz with HEARTBEAT |
//!
//! Resolution is MAVLink's: the float messages carry f32 (what the live path prefers); the
//! integer ones 1e-7 deg, 1 mm, 1 cm/s, 1 mV, 10 mA. A current that rounds to −1 cA (the
//! "not measured" sentinel) is sent as 0 cA. With `wind_speed` = 0 the anemometer angle
//! cannot be carried by a wind vector and is lost (546 rows of the data set).
//!
//! **Clock.** A record's tlog stamp is `base + time`, `base` the flight's `date` and
//! `time_day` read as UTC (the data set gives no zone), µs since the Unix epoch; if they
//! do not parse, `base` is the epoch itself. Messages come from system 1, component 1,
//! as MAVLink 2.
//!
//! Multi-stage `altitude` text such as `25-50-100-25` (flights 278 and 279) is taken as
//! its highest stage, the altitude the mission climbs to.

use crate::features::units::{centidegrees, scaled, whole_degrees};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use mavlink::{MavHeader, MavlinkVersion};

use crate::dialect::*;
use crate::features::frames;
use crate::MavMessage;

/// Columns read from the file, in [`Row`] order after `flight` and `time`.
const SENSOR_COLUMNS: [&str; 20] = [
    "wind_speed",
    "wind_angle",
    "battery_voltage",
    "battery_current",
    "position_x",
    "position_y",
    "position_z",
    "orientation_x",
    "orientation_y",
    "orientation_z",
    "orientation_w",
    "velocity_x",
    "velocity_y",
    "velocity_z",
    "angular_x",
    "angular_y",
    "angular_z",
    "linear_acceleration_x",
    "linear_acceleration_y",
    "linear_acceleration_z",
];
const META_COLUMNS: [&str; 6] = ["speed", "payload", "altitude", "date", "time_day", "route"];

/// One row of the data set, in its own units and frames (see SOURCE.md).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row {
    /// s since the start of the recording.
    pub time_s: f64,
    /// Anemometer airspeed, m/s.
    pub wind_speed: f64,
    /// Direction the apparent wind blows from, degrees clockwise from north.
    pub wind_angle: f64,
    /// Battery voltage, V.
    pub voltage_v: f64,
    /// Battery current, A.
    pub current_a: f64,
    /// Longitude, deg.
    pub lon_deg: f64,
    /// Latitude, deg.
    pub lat_deg: f64,
    /// Altitude above sea level, m.
    pub alt_m: f64,
    /// Quaternion `[x, y, z, w]` as in the file (body right-forward-up → ENU).
    pub q_xyzw: [f64; 4],
    /// Ground velocity in the heading frame (right, forward, up), m/s.
    pub vel: [f64; 3],
    /// Body rates (FRD), rad/s.
    pub ang: [f64; 3],
    /// Specific force (FRD), m/s².
    pub acc: [f64; 3],
}

impl Row {
    fn from_values(time_s: f64, v: &[f64; 20]) -> Self {
        Row {
            time_s,
            wind_speed: v[0],
            wind_angle: v[1],
            voltage_v: v[2],
            current_a: v[3],
            lon_deg: v[4],
            lat_deg: v[5],
            alt_m: v[6],
            q_xyzw: [v[7], v[8], v[9], v[10]],
            vel: [v[11], v[12], v[13]],
            ang: [v[14], v[15], v[16]],
            acc: [v[17], v[18], v[19]],
        }
    }
    /// The data-set quaternion as `[w, x, y, z]`.
    pub fn q_wxyz(&self) -> frames::Quat {
        [
            self.q_xyzw[3],
            self.q_xyzw[0],
            self.q_xyzw[1],
            self.q_xyzw[2],
        ]
    }
}

/// One flight: its mission facts and rows, in file order.
#[derive(Debug, Clone)]
pub struct Flight {
    /// Flight number.
    pub flight: u32,
    /// Route label (`R1`…`R7`, `A1`…`A3`, `H`).
    pub route: String,
    /// Commanded cruise ground speed, m/s.
    pub speed_m_s: f64,
    /// Payload, g.
    pub payload_g: f64,
    /// Commanded cruise altitude, m (highest stage of a multi-stage text).
    pub altitude_m: f64,
    /// The `altitude` cell as written.
    pub altitude_text: String,
    /// Local start date (`YYYY-MM-DD`) and time (`H:MM`), as written.
    pub date: String,
    /// See `date`.
    pub time_day: String,
    /// The rows, time increasing.
    pub rows: Vec<Row>,
}

/// A row that was skipped, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct SkippedRow {
    /// 1-based line number in the (decompressed) file.
    pub line: usize,
    /// What was wrong, naming the column.
    pub reason: String,
}

/// What [`read_flights`] read.
#[derive(Debug, Clone)]
pub struct DataSet {
    /// Flights in increasing number.
    pub flights: Vec<Flight>,
    /// Rows that could not be used.
    pub skipped: Vec<SkippedRow>,
    /// Every flight number in the file, read or not, increasing.
    pub all_flights: Vec<u32>,
}

/// `1-5, 7, 9-12`: a sorted list of numbers as ranges.
fn summarise(v: &[u32]) -> String {
    let mut parts = Vec::new();
    let mut i = 0;
    while i < v.len() {
        let mut j = i;
        while j + 1 < v.len() && v[j + 1] == v[j] + 1 {
            j += 1;
        }
        parts.push(if j > i {
            format!("{}-{}", v[i], v[j])
        } else {
            v[i].to_string()
        });
        i = j + 1;
    }
    parts.join(", ")
}

/// The file's bytes, gunzipped when they start with the gzip magic.
fn read_maybe_gz(path: &Path) -> Result<Vec<u8>> {
    use std::io::Read;
    if !path.exists() {
        bail!(
            "{}: no such file. The M100 data set (flights.csv or flights.csv.gz) is read from the \
             path given, else from the environment variable DRONEWATT_DATA, else from \
             ../shared/data/m100/flights.csv.gz beside the project",
            path.display()
        );
    }
    let raw = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    if raw.starts_with(&[0x1f, 0x8b]) {
        let mut out = Vec::with_capacity(raw.len() * 4);
        flate2::read::MultiGzDecoder::new(&raw[..])
            .read_to_end(&mut out)
            .with_context(|| format!("{}: not a valid gzip file", path.display()))?;
        Ok(out)
    } else {
        Ok(raw)
    }
}

fn parse_altitude(s: &str) -> Option<f64> {
    s.split('-')
        .map(|p| p.trim().parse::<f64>().ok().filter(|x| x.is_finite()))
        .try_fold(f64::NEG_INFINITY, |m, x| x.map(|x| m.max(x)))
}

/// Read the flights of an official `flights.csv[.gz]` (those in `want`, or all). See the
/// module docs for what is checked and what is skipped.
pub fn read_flights(path: &Path, want: Option<&[u32]>) -> Result<DataSet> {
    let bytes = read_maybe_gz(path)?;
    parse_flights(&bytes, &path.display().to_string(), want)
}

/// [`read_flights`] on the file's (decompressed) bytes; `origin` names the file in errors
/// and warnings. Separate so the fuzz targets can feed it bytes without a file.
pub fn parse_flights(bytes: &[u8], origin: &str, want: Option<&[u32]>) -> Result<DataSet> {
    let path = std::path::Path::new(origin);
    let text = std::str::from_utf8(bytes)
        .with_context(|| format!("{}: not UTF-8 text", path.display()))?;
    let mut lines = text.split('\n').map(|l| l.strip_suffix('\r').unwrap_or(l));
    let header = lines.next().unwrap_or("");
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let col = |name: &str| -> Result<usize> {
        names.iter().position(|n| *n == name).with_context(|| {
            format!(
                "{}: line 1: no '{name}' column in the header (is this the M100 flights.csv?)",
                path.display()
            )
        })
    };
    let c_flight = col("flight")?;
    let c_time = col("time")?;
    let c_sensor: Vec<usize> = SENSOR_COLUMNS
        .iter()
        .map(|n| col(n))
        .collect::<Result<_>>()?;
    let c_meta: Vec<usize> = META_COLUMNS.iter().map(|n| col(n)).collect::<Result<_>>()?;

    let mut flights: std::collections::BTreeMap<u32, Flight> = Default::default();
    let mut skipped = Vec::new();
    let mut all: Vec<u32> = Vec::new();
    let mut fields: Vec<&str> = Vec::with_capacity(names.len());
    for (i, line) in lines.enumerate() {
        let lineno = i + 2;
        if line.trim().is_empty() {
            continue;
        }
        fields.clear();
        fields.extend(line.split(','));
        let mut skip = |reason: String| {
            skipped.push(SkippedRow {
                line: lineno,
                reason,
            })
        };
        if fields.len() != names.len() {
            skip(format!(
                "{} fields, the header has {}",
                fields.len(),
                names.len()
            ));
            continue;
        }
        let Ok(flight) = fields[c_flight].trim().parse::<u32>() else {
            skip(format!(
                "column 'flight': '{}' is not a flight number",
                fields[c_flight]
            ));
            continue;
        };
        if all.last() != Some(&flight) {
            all.push(flight);
        }
        if want.is_some_and(|w| !w.contains(&flight)) {
            continue;
        }
        let num = |c: usize, name: &str| -> std::result::Result<f64, String> {
            match fields[c].trim().parse::<f64>() {
                Ok(x) if x.is_finite() => Ok(x),
                _ => Err(format!(
                    "column '{name}': '{}' is not a finite number",
                    fields[c]
                )),
            }
        };
        let time = match num(c_time, "time") {
            Ok(t) => t,
            Err(e) => {
                skip(e);
                continue;
            }
        };
        let mut v = [0f64; 20];
        let mut bad = None;
        for (k, &c) in c_sensor.iter().enumerate() {
            match num(c, SENSOR_COLUMNS[k]) {
                Ok(x) => v[k] = x,
                Err(e) => {
                    bad = Some(e);
                    break;
                }
            }
        }
        if let Some(e) = bad {
            skip(e);
            continue;
        }
        let f = match flights.entry(flight) {
            std::collections::btree_map::Entry::Occupied(o) => o.into_mut(),
            std::collections::btree_map::Entry::Vacant(e) => {
                let (speed, payload) = match (num(c_meta[0], "speed"), num(c_meta[1], "payload")) {
                    (Ok(s), Ok(p)) => (s, p),
                    (Err(e), _) | (_, Err(e)) => {
                        skip(e);
                        continue;
                    }
                };
                let alt_text = fields[c_meta[2]].trim();
                let Some(altitude) = parse_altitude(alt_text) else {
                    skip(format!(
                        "column 'altitude': '{alt_text}' is not an altitude"
                    ));
                    continue;
                };
                e.insert(Flight {
                    flight,
                    route: fields[c_meta[5]].trim().to_string(),
                    speed_m_s: speed,
                    payload_g: payload,
                    altitude_m: altitude,
                    altitude_text: alt_text.to_string(),
                    date: fields[c_meta[3]].trim().to_string(),
                    time_day: fields[c_meta[4]].trim().to_string(),
                    rows: Vec::new(),
                })
            }
        };
        if f.rows.last().is_some_and(|r| r.time_s >= time) {
            skip(format!(
                "column 'time': {time} does not increase within flight {flight}"
            ));
            continue;
        }
        f.rows.push(Row::from_values(time, &v));
    }
    for s in skipped.iter().take(5) {
        tracing::warn!(
            "{}: line {}: row skipped: {}",
            path.display(),
            s.line,
            s.reason
        );
    }
    if skipped.len() > 5 {
        tracing::warn!("{}: {} rows skipped in all", path.display(), skipped.len());
    }
    all.sort_unstable();
    all.dedup();
    Ok(DataSet {
        flights: flights.into_values().collect(),
        skipped,
        all_flights: all,
    })
}

/// Days from 1970-01-01 to a civil date (H. Hinnant's algorithm).
fn days_from_civil(y: i64, m: i64, d: i64) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let doy = (153 * (m + if m > 2 { -3 } else { 9 }) + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// The flight's tlog clock base, µs since the Unix epoch (see the module docs).
pub fn epoch_base_us(f: &Flight) -> u64 {
    let d: Vec<i64> = f.date.split('-').filter_map(|x| x.parse().ok()).collect();
    let t: Vec<i64> = f
        .time_day
        .split(':')
        .filter_map(|x| x.parse().ok())
        .collect();
    match (d.as_slice(), t.as_slice()) {
        ([y, m, dd], [hh, mm, ..])
            if (1..=12).contains(m)
                && (1..=31).contains(dd)
                && (1970..=9999).contains(y)
                && (0..24).contains(hh)
                && (0..60).contains(mm) =>
        {
            let s = days_from_civil(*y, *m, *dd) * 86_400 + hh * 3600 + mm * 60;
            (s.max(0) as u64) * 1_000_000
        }
        _ => 0,
    }
}

/// Encode one flight as tlog bytes (see the module docs for the mapping).
pub fn encode_flight(f: &Flight) -> Vec<u8> {
    let mut enc = Encoder {
        buf: Vec::with_capacity(f.rows.len() * 500),
        seq: 0,
        t_us: 0,
        boot_ms: 0,
    };
    let base = epoch_base_us(f);
    let mut last_hb: Option<f64> = None;
    let mut home: Option<[f64; 3]> = None;
    for r in &f.rows {
        // Saturating: a CSV may hold any finite time (found by fuzzing: 1e300 s overflowed).
        enc.t_us = base.saturating_add((r.time_s * 1e6).round().max(0.0) as u64);
        enc.boot_ms = (r.time_s * 1e3).round().max(0.0) as u32;
        if last_hb.is_none_or(|t| r.time_s - t >= 1.0) {
            last_hb = Some(r.time_s);
            enc.heartbeat();
            enc.named("cmd_speed", f.speed_m_s);
            enc.named("payload_g", f.payload_g);
            enc.named("cmd_alt", f.altitude_m);
        }
        if home.is_none() && (r.lat_deg != 0.0 || r.lon_deg != 0.0) {
            let h = [r.lat_deg, r.lon_deg, r.alt_m];
            home = Some(h);
            enc.send(MavMessage::HOME_POSITION(HOME_POSITION_DATA {
                latitude: deg_e7(h[0]),
                longitude: deg_e7(h[1]),
                altitude: mm(h[2]),
                q: [1.0, 0.0, 0.0, 0.0],
                time_usec: enc.t_us,
                ..Default::default()
            }));
        }
        enc.row(r, home);
    }
    enc.buf
}

fn deg_e7(x: f64) -> i32 {
    scaled(x, 1e7).unwrap_or(0)
}
fn mm(x: f64) -> i32 {
    scaled(x, 1e3).unwrap_or(0)
}
fn i16_scaled(x: f64, k: f64) -> i16 {
    scaled(x, k).unwrap_or(0)
}

struct Encoder {
    buf: Vec<u8>,
    seq: u8,
    t_us: u64,
    boot_ms: u32,
}

impl Encoder {
    fn send(&mut self, msg: MavMessage) {
        let h = MavHeader {
            system_id: 1,
            component_id: 1,
            sequence: self.seq,
        };
        self.seq = self.seq.wrapping_add(1);
        crate::source::tlog::write_record(&mut self.buf, self.t_us, h, &msg, MavlinkVersion::V2);
    }

    fn heartbeat(&mut self) {
        self.send(MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: 0,
            mavtype: MavType::MAV_TYPE_QUADROTOR,
            autopilot: MavAutopilot::MAV_AUTOPILOT_GENERIC,
            base_mode: MavModeFlag::empty(),
            system_status: MavState::MAV_STATE_ACTIVE,
            mavlink_version: 3,
        }));
    }

    fn named(&mut self, name: &str, value: f64) {
        self.send(MavMessage::NAMED_VALUE_FLOAT(NAMED_VALUE_FLOAT_DATA {
            time_boot_ms: self.boot_ms,
            value: value as f32,
            name: name.into(),
        }));
    }

    fn row(&mut self, r: &Row, home: Option<[f64; 3]>) {
        let t = self.boot_ms;
        let q = frames::ds_to_ned(r.q_wxyz());
        let [roll, pitch, yaw] = frames::euler_ned(q);
        let [p, qq, rr] = r.ang.map(|x| x as f32);
        self.send(MavMessage::ATTITUDE(ATTITUDE_DATA {
            time_boot_ms: t,
            roll: roll as f32,
            pitch: pitch as f32,
            yaw: yaw as f32,
            rollspeed: p,
            pitchspeed: qq,
            yawspeed: rr,
        }));
        self.send(MavMessage::ATTITUDE_QUATERNION(ATTITUDE_QUATERNION_DATA {
            time_boot_ms: t,
            q1: q[0] as f32,
            q2: q[1] as f32,
            q3: q[2] as f32,
            q4: q[3] as f32,
            rollspeed: p,
            pitchspeed: qq,
            yawspeed: rr,
            repr_offset_q: [0.0; 4],
        }));
        let a = r.acc.map(|x| x as f32);
        self.send(MavMessage::HIGHRES_IMU(HIGHRES_IMU_DATA {
            time_usec: self.t_us,
            xacc: a[0],
            yacc: a[1],
            zacc: a[2],
            xgyro: p,
            ygyro: qq,
            zgyro: rr,
            fields_updated: HighresImuUpdatedFlags::HIGHRES_IMU_UPDATED_XACC
                | HighresImuUpdatedFlags::HIGHRES_IMU_UPDATED_YACC
                | HighresImuUpdatedFlags::HIGHRES_IMU_UPDATED_ZACC
                | HighresImuUpdatedFlags::HIGHRES_IMU_UPDATED_XGYRO
                | HighresImuUpdatedFlags::HIGHRES_IMU_UPDATED_YGYRO
                | HighresImuUpdatedFlags::HIGHRES_IMU_UPDATED_ZGYRO,
            ..Default::default()
        }));
        let v = frames::body_to_ned_vel(r.vel, yaw);
        let (n, e) = home.map_or((0.0, 0.0), |h| {
            frames::ne_offset_m(h[0], h[1], r.lat_deg, r.lon_deg)
        });
        let home_alt = home.map_or(r.alt_m, |h| h[2]);
        self.send(MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
            time_boot_ms: t,
            x: n as f32,
            y: e as f32,
            z: -(r.alt_m - home_alt) as f32,
            vx: v[0] as f32,
            vy: v[1] as f32,
            vz: v[2] as f32,
        }));
        let hdg = yaw.to_degrees().rem_euclid(360.0);
        self.send(MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
            time_boot_ms: t,
            lat: deg_e7(r.lat_deg),
            lon: deg_e7(r.lon_deg),
            alt: mm(r.alt_m),
            relative_alt: mm(r.alt_m - home_alt),
            vx: i16_scaled(v[0], 100.0),
            vy: i16_scaled(v[1], 100.0),
            vz: i16_scaled(v[2], 100.0),
            hdg: centidegrees(hdg).unwrap_or(u16::MAX),
        }));
        let apparent = frames::wind_from_to_vec(r.wind_speed, r.wind_angle);
        let [ws, wd] = frames::wind_vec_to_from([apparent[0] + v[0], apparent[1] + v[1]]);
        self.send(MavMessage::WIND(WIND_DATA {
            direction: wd as f32,
            speed: ws as f32,
            speed_z: 0.0,
        }));
        self.send(MavMessage::VFR_HUD(VFR_HUD_DATA {
            airspeed: r.wind_speed as f32,
            groundspeed: v[0].hypot(v[1]) as f32,
            alt: r.alt_m as f32,
            climb: r.vel[2] as f32,
            heading: whole_degrees(hdg).unwrap_or(0),
            throttle: 0,
        }));
        let mv = scaled::<u16>(r.voltage_v.max(0.0), 1e3).map_or(0, |v| v.min(65_534));
        let ca = match i16_scaled(r.current_a, 100.0) {
            -1 => 0,
            c => c,
        };
        self.send(MavMessage::SYS_STATUS(SYS_STATUS_DATA {
            voltage_battery: mv,
            current_battery: ca,
            battery_remaining: -1,
            ..Default::default()
        }));
        let mut cells = [u16::MAX; 10];
        cells[0] = mv;
        self.send(MavMessage::BATTERY_STATUS(BATTERY_STATUS_DATA {
            current_consumed: -1,
            energy_consumed: -1,
            temperature: i16::MAX,
            voltages: cells,
            current_battery: ca,
            id: 0,
            battery_function: MavBatteryFunction::MAV_BATTERY_FUNCTION_ALL,
            mavtype: MavBatteryType::MAV_BATTERY_TYPE_LIPO,
            battery_remaining: -1,
            ..Default::default()
        }));
    }
}

/// One flight of the official `flights.csv[.gz]` encoded as an in-memory `.tlog`: every row
/// becomes the MAVLink messages an autopilot would send, stamped with the row's time.
/// (Used by the `Dataset` source, `convert` and `offline::data`.)
pub fn flight_tlog(path: &Path, flight: u32) -> Result<Vec<u8>> {
    let ds = read_flights(path, Some(&[flight]))?;
    match ds.flights.first() {
        Some(f) if !f.rows.is_empty() => Ok(encode_flight(f)),
        _ => bail!(
            "{}: flight {flight} is not in this file (it holds {} flights: {})",
            path.display(),
            ds.all_flights.len(),
            summarise(&ds.all_flights)
        ),
    }
}

/// Arguments of `dronewatt convert`.
#[derive(Debug, Clone, clap::Args)]
pub struct ConvertArgs {
    /// The official data set, `flights.csv` or `flights.csv.gz`.
    pub file: PathBuf,
    /// Which flight to write.
    #[arg(long)]
    pub flight: u32,
    /// The `.tlog` to write.
    #[arg(long, short = 'o', value_name = "OUT.tlog")]
    pub output: PathBuf,
}

/// Run `dronewatt convert`: write one data-set flight as a `.tlog`.
pub fn run(args: ConvertArgs) -> Result<()> {
    let bytes = flight_tlog(&args.file, args.flight)?;
    std::fs::write(&args.output, &bytes)
        .with_context(|| format!("{}: cannot write", args.output.display()))?;
    eprintln!(
        "flight {} → {} ({} bytes)",
        args.flight,
        args.output.display(),
        bytes.len()
    );
    Ok(())
}
