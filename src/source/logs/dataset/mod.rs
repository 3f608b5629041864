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

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use crate::features::frames;

mod encode;
pub use encode::{encode_flight, epoch_base_us};

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

/// The data set's CSV header line as its files have it (without the newline): `flight,time`,
/// the sensor columns, then the flight's metadata. Tests and tools that write a flight in the
/// data set's own format start from it.
pub fn csv_header() -> String {
    format!(
        "flight,time,{},{}",
        SENSOR_COLUMNS.join(","),
        META_COLUMNS.join(",")
    )
}

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

/// The header's columns that [`parse_flights`] reads, by position.
struct Columns {
    n: usize,
    flight: usize,
    time: usize,
    sensor: Vec<usize>,
    meta: Vec<usize>,
}

impl Columns {
    /// Every column this reader needs, or the first missing one named.
    fn of(header: &str, path: &Path) -> Result<Self> {
        let names: Vec<&str> = header.split(',').map(str::trim).collect();
        let col = |name: &str| -> Result<usize> {
            names.iter().position(|n| *n == name).with_context(|| {
                format!(
                    "{}: line 1: no '{name}' column in the header (is this the M100 flights.csv?)",
                    path.display()
                )
            })
        };
        Ok(Self {
            n: names.len(),
            flight: col("flight")?,
            time: col("time")?,
            sensor: SENSOR_COLUMNS
                .iter()
                .map(|n| col(n))
                .collect::<Result<_>>()?,
            meta: META_COLUMNS.iter().map(|n| col(n)).collect::<Result<_>>()?,
        })
    }
}

/// Field `c` (column `name`) as a finite number, else why not.
fn field_num(fields: &[&str], c: usize, name: &str) -> std::result::Result<f64, String> {
    match fields[c].trim().parse::<f64>() {
        Ok(x) if x.is_finite() => Ok(x),
        _ => Err(format!(
            "column '{name}': '{}' is not a finite number",
            fields[c]
        )),
    }
}

/// The row's 20 sensor values, else why the row is skipped.
fn sensor_values(fields: &[&str], cols: &Columns) -> std::result::Result<[f64; 20], String> {
    let mut v = [0f64; 20];
    for (k, &c) in cols.sensor.iter().enumerate() {
        v[k] = field_num(fields, c, SENSOR_COLUMNS[k])?;
    }
    Ok(v)
}

/// A flight's metadata from its first row (no rows yet), else why the row is skipped.
fn new_flight(fields: &[&str], cols: &Columns, flight: u32) -> std::result::Result<Flight, String> {
    let c_meta = &cols.meta;
    let (speed, payload) = match (
        field_num(fields, c_meta[0], "speed"),
        field_num(fields, c_meta[1], "payload"),
    ) {
        (Ok(s), Ok(p)) => (s, p),
        (Err(e), _) | (_, Err(e)) => return Err(e),
    };
    let alt_text = fields[c_meta[2]].trim();
    let Some(altitude) = parse_altitude(alt_text) else {
        return Err(format!(
            "column 'altitude': '{alt_text}' is not an altitude"
        ));
    };
    Ok(Flight {
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

/// [`read_flights`] on the file's (decompressed) bytes; `origin` names the file in errors
/// and warnings. Separate so the fuzz targets can feed it bytes without a file.
pub fn parse_flights(bytes: &[u8], origin: &str, want: Option<&[u32]>) -> Result<DataSet> {
    let path = std::path::Path::new(origin);
    let text = std::str::from_utf8(bytes)
        .with_context(|| format!("{}: not UTF-8 text", path.display()))?;
    let mut lines = text.split('\n').map(|l| l.strip_suffix('\r').unwrap_or(l));
    let cols = Columns::of(lines.next().unwrap_or(""), path)?;

    let mut flights: std::collections::BTreeMap<u32, Flight> = Default::default();
    let mut skipped = Vec::new();
    let mut all: Vec<u32> = Vec::new();
    let mut fields: Vec<&str> = Vec::with_capacity(cols.n);
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
        if fields.len() != cols.n {
            skip(format!(
                "{} fields, the header has {}",
                fields.len(),
                cols.n
            ));
            continue;
        }
        let Ok(flight) = fields[cols.flight].trim().parse::<u32>() else {
            skip(format!(
                "column 'flight': '{}' is not a flight number",
                fields[cols.flight]
            ));
            continue;
        };
        if all.last() != Some(&flight) {
            all.push(flight);
        }
        if want.is_some_and(|w| !w.contains(&flight)) {
            continue;
        }
        let (time, v) = match field_num(&fields, cols.time, "time")
            .and_then(|t| Ok((t, sensor_values(&fields, &cols)?)))
        {
            Ok(tv) => tv,
            Err(e) => {
                skip(e);
                continue;
            }
        };
        let f = match flights.entry(flight) {
            std::collections::btree_map::Entry::Occupied(o) => o.into_mut(),
            std::collections::btree_map::Entry::Vacant(e) => {
                match new_flight(&fields, &cols, flight) {
                    Ok(f) => e.insert(f),
                    Err(why) => {
                        skip(why);
                        continue;
                    }
                }
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
    warn_skipped(path, &skipped);
    all.sort_unstable();
    all.dedup();
    Ok(DataSet {
        flights: flights.into_values().collect(),
        skipped,
        all_flights: all,
    })
}

/// The first five skipped rows, each with its reason, then how many in all.
fn warn_skipped(path: &Path, skipped: &[SkippedRow]) {
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

/// Arguments of `dronewatt-lab convert`.
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

/// Run `dronewatt-lab convert`: write one data-set flight as a `.tlog`.
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
