//! The vehicle store: what dronewatt learned about each vehicle it watched, kept between
//! runs in an embedded SQLite database, so the next flight of the same vehicle starts from
//! it.
//!
//! ## Where
//!
//! `dronewatt.sqlite` in the data directory: `--data-dir DIR`, else `$DRONEWATT_HOME`, else
//! `$XDG_DATA_HOME/dronewatt`, else `~/.local/share/dronewatt` ([`data_dir`]).
//! `DRONEWATT_HOME=off` (or `--data-dir off`) turns the store off; the project's
//! `.cargo/config.toml` sets that for `cargo test` and `cargo run`, so the test suite never
//! writes to a home directory and runs never learn from each other by accident.
//!
//! ## Which vehicle
//!
//! Keyed by the vehicle's identity ([`VehicleKey`]): AUTOPILOT_VERSION's board uid where the
//! autopilot sends one (`uid:00000000deadbeef`, the same airframe whatever its system id),
//! else its system id, autopilot and type from HEARTBEAT (`sys1-ardupilot-MAV_TYPE_QUADROTOR`,
//! weaker: two quadrotors both left at system id 1 share it, so a pack that differs from the
//! remembered one makes a new vehicle: `matching`). The listing says which, and why each
//! flight was matched.
//!
//! ## What
//!
//! | table | one row per | holds |
//! |---|---|---|
//! | `vehicles` | vehicle | its key and identity, first and last seen, the adaptation fits learned so far (JSON) |
//! | `flights` | run of the chain with power seen | end time, seconds with the motors turning, energy used (Wh), the autopilot's battery % at start and end, effective capacity, the rated capacity and where it came from, the pack (resting voltages, resistance, heat, health) and its id where the vehicle identified it (BATTERY_INFO's serial) |
//!
//! **Effective capacity** = energy used ÷ (battery % drop / 100): what the pack delivered
//! per the autopilot's own gauge. The next flight of the vehicle takes the posterior over the
//! last [`CAPACITY_FLIGHTS`] (each weighed by how far the gauge fell, against the rated
//! capacity: [`posterior`]) as its capacity unless the config sets one (it then beats the
//! vehicle's rated `BATT_CAPACITY`: remaining = capacity × the gauge's % is then right for
//! a pack that has aged). Kept only when the gauge fell by at least
//! [`MIN_PCT_DROP`] % (a smaller drop is mostly the gauge's rounding). Beside the rated
//! capacity it is the pack's health: a pack that delivers 85 % of its rating is one a pilot
//! wants to know about.
//!
//! ## Never in the way
//!
//! Nothing here runs on a stage of the live chain: the pipeline reads the store on a
//! blocking thread once the vehicle is known, and writes once at the end of the run
//! ([`crate::pipeline`]). A database that cannot be opened (corrupt, locked by another run,
//! a read-only folder) is a warning and the run goes on without it.
mod dir;
mod flight;
pub mod hover;
mod learned;
mod list;
mod matching;
pub mod posterior;

pub use dir::{data_dir, data_dir_from_env, DB_FILE, HOME_ENV, MIN_PCT_DROP};
pub use flight::{FlightLog, FlightSummary, VehicleKey, MIN_SOC_DROP_PCT};
pub use learned::{lookup, remember, remember_profile, Learned, CAPACITY_FLIGHTS};
pub use list::list;
pub use matching::{lookup_due, Matched, PackSig, LOG_WAIT_S, PACK_WAIT_S};

use crate::features::units::unix_clock;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use rusqlite::{params, Connection, OptionalExtension};

use crate::model::adapt::ModelFit;
use crate::vehicle::params::Identity;
use dir::BUSY_WAIT;

/// What the store knows of one vehicle (for `dronewatt vehicles`).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct VehicleRecord {
    pub key: String,
    /// `uid` or `heartbeat`: how the vehicle was told apart.
    pub key_kind: String,
    pub autopilot: String,
    pub vehicle_type: String,
    /// The class its HEARTBEAT type says (`multirotor`, `fixed_wing`, `vtol`, `other`).
    pub vehicle_class: crate::features::VehicleClass,
    pub system_id: u8,
    /// Unix seconds.
    pub first_seen: i64,
    pub last_seen: i64,
    /// Models with learned fits.
    pub learned_models: usize,
    /// The profile `dronewatt learn` wrote for this vehicle, if any.
    pub profile: Option<LearnedProfile>,
    /// The pack it reported of itself (what tells vehicles under one key apart).
    pub pack: PackSig,
    pub flights: Vec<FlightRecord>,
}

/// A vehicle profile learned from the vehicle's logs (`dronewatt learn`): the next run of
/// the vehicle starts from it unless a profile is configured.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LearnedProfile {
    /// The profile file (absolute, as `learn` wrote it).
    pub path: PathBuf,
    /// The forecast model `learn` picked on held-out logs, when it did.
    pub forecast_model: Option<String>,
    /// Unix seconds.
    pub learned_at: i64,
}

/// One stored flight.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct FlightRecord {
    /// Unix seconds at the end of the run.
    pub ended_at: i64,
    /// Why the flight was matched to its vehicle (`matching`; None: an older store).
    pub matched: Option<String>,
    #[serde(flatten)]
    pub summary: FlightSummary,
}

impl VehicleRecord {
    /// Energy per airborne minute over every flight, Wh/min.
    pub fn wh_per_min(&self) -> Option<f64> {
        let (wh, s) = self.flights.iter().fold((0.0, 0.0), |(wh, s), f| {
            (wh + f.summary.energy_wh, s + f.summary.airborne_s)
        });
        (s > 0.0).then(|| wh / (s / 60.0))
    }

    /// Effective capacity over rated, %, of the flights that have one, oldest first.
    pub fn capacity_trend_pct(&self) -> Vec<f64> {
        self.flights
            .iter()
            .filter_map(|f| {
                Some(100.0 * f.summary.effective_capacity_wh? / f.summary.rated_capacity_wh)
                    .filter(|v| v.is_finite())
            })
            .collect()
    }
}

/// The open database.
pub struct Store {
    conn: Connection,
    path: PathBuf,
}

const SCHEMA: &str = "
CREATE TABLE IF NOT EXISTS vehicles (
    key          TEXT PRIMARY KEY,
    key_kind     TEXT NOT NULL,
    system_id    INTEGER NOT NULL,
    autopilot    TEXT NOT NULL,
    vehicle_type TEXT NOT NULL,
    first_seen   INTEGER NOT NULL,
    last_seen    INTEGER NOT NULL,
    fits         TEXT
);
CREATE TABLE IF NOT EXISTS flights (
    id                    INTEGER PRIMARY KEY,
    vehicle               TEXT NOT NULL REFERENCES vehicles(key),
    ended_at              INTEGER NOT NULL,
    airborne_s            REAL NOT NULL,
    energy_wh             REAL NOT NULL,
    pct_start             REAL,
    pct_end               REAL,
    effective_capacity_wh REAL,
    rated_capacity_wh     REAL NOT NULL,
    capacity_source       TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS flights_by_vehicle ON flights(vehicle, ended_at);
CREATE TABLE IF NOT EXISTS profiles (
    vehicle        TEXT PRIMARY KEY REFERENCES vehicles(key),
    path           TEXT NOT NULL,
    forecast_model TEXT,
    learned_at     INTEGER NOT NULL
);
";

/// The schema this build writes (`PRAGMA user_version`): 1 the first stores (no version
/// set, read as 0), 2 adds each flight's pack (resting voltages, resistance, heat, health),
/// 3 the flight's end on the log's own clock (`ended_log_s`, a replay's), 4 the pack's
/// identity (`pack_id`, BATTERY_INFO's serial; `NULL` when the vehicle sent none), 5 the
/// pack each vehicle reported and why each flight was matched (`matching`), 6 the slope of
/// the pack's deeper sag as it empties (`deep_slope`, [`crate::battery::deep`]).
pub const SCHEMA_VERSION: i64 = 6;

/// The columns schemas 2, 3 and 6 add to `flights` (all `REAL`).
const ADDED_COLUMNS: [&str; 8] = [
    "rest_v_start",
    "rest_v_end",
    "r_scale",
    "internal_r_ohm",
    "heat_a2s",
    "pack_health_pct",
    "ended_log_s",
    "deep_slope",
];

/// The `TEXT` columns schema 4 adds to `flights`.
const ADDED_TEXT_COLUMNS: [&str; 1] = ["pack_id"];

/// Bring an older store up to [`SCHEMA_VERSION`] in one transaction; refuse a newer one (a
/// later dronewatt wrote it: reading it could lose what that one keeps).
fn migrate(conn: &Connection) -> Result<()> {
    let version: i64 = conn.query_row("PRAGMA user_version", [], |r| r.get(0))?;
    if version > SCHEMA_VERSION {
        anyhow::bail!("written by a newer dronewatt (schema {version}; this one reads up to {SCHEMA_VERSION})");
    }
    if version == SCHEMA_VERSION {
        return Ok(());
    }
    let have: Vec<String> = conn
        .prepare("SELECT name FROM pragma_table_info('flights')")?
        .query_map([], |r| r.get(0))?
        .collect::<rusqlite::Result<_>>()?;
    let mut sql = String::from("BEGIN;");
    for c in ADDED_COLUMNS
        .iter()
        .filter(|c| !have.iter().any(|h| h == *c))
    {
        sql.push_str(&format!("ALTER TABLE flights ADD COLUMN {c} REAL;"));
    }
    for c in ADDED_TEXT_COLUMNS
        .iter()
        .filter(|c| !have.iter().any(|h| h == *c))
    {
        sql.push_str(&format!("ALTER TABLE flights ADD COLUMN {c} TEXT;"));
    }
    sql.push_str(&matching::migration(conn)?);
    sql.push_str(&format!("PRAGMA user_version = {SCHEMA_VERSION}; COMMIT;"));
    conn.execute_batch(&sql)?;
    Ok(())
}

fn now_s() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() as i64)
}

impl Store {
    /// Open (creating the folder and the tables when new) the store in `dir`. A file that
    /// is not a database, or one another run holds locked past `BUSY_WAIT`, fails here
    /// with the path in the message.
    pub fn open(dir: &Path) -> Result<Self> {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create the data directory", dir.display()))?;
        let path = dir.join(DB_FILE);
        let conn = Connection::open(&path)
            .with_context(|| format!("{}: cannot open the vehicle store", path.display()))?;
        conn.busy_timeout(BUSY_WAIT)?;
        conn.execute_batch(SCHEMA).with_context(|| {
            format!(
                "{}: not a dronewatt vehicle store (corrupt?)",
                path.display()
            )
        })?;
        migrate(&conn).with_context(|| {
            format!(
                "{}: cannot bring the vehicle store to schema {SCHEMA_VERSION}",
                path.display()
            )
        })?;
        Ok(Self { conn, path })
    }

    /// The database file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The fits learned on earlier flights of this vehicle, if any. Fits that do not parse
    /// (another version wrote them) are no fits, with a warning.
    pub fn learned_fits(&self, key: &VehicleKey) -> Result<Option<Vec<(String, ModelFit)>>> {
        let text: Option<Option<String>> = self
            .conn
            .query_row(
                "SELECT fits FROM vehicles WHERE key = ?1",
                params![key.key],
                |r| r.get(0),
            )
            .optional()?;
        let Some(Some(text)) = text else {
            return Ok(None);
        };
        match serde_json::from_str(&text) {
            Ok(f) => Ok(Some(f)),
            Err(e) => {
                tracing::warn!(
                    "{}: the learned fits of {} do not parse ({e}); starting afresh",
                    self.path.display(),
                    key.key
                );
                Ok(None)
            }
        }
    }

    /// The pack's capacity learned over its last [`CAPACITY_FLIGHTS`] flights that measured
    /// one, Wh (the posterior mean, [`posterior::capacity`]: each flight weighs by how far the
    /// gauge fell, against the rated capacity), and how many there were.
    pub fn learned_capacity(&self, key: &VehicleKey) -> Result<Option<(f64, usize)>> {
        let mut st = self.conn.prepare(
            "SELECT effective_capacity_wh, pct_start - pct_end, rated_capacity_wh FROM flights WHERE vehicle = ?1 AND effective_capacity_wh > 0 ORDER BY ended_at DESC, id DESC LIMIT ?2",
        )?;
        let rows: Vec<(f64, Option<f64>, f64)> = st
            .query_map(params![key.key, CAPACITY_FLIGHTS as i64], |r| {
                Ok((r.get(0)?, r.get(1)?, r.get(2)?))
            })?
            .collect::<rusqlite::Result<_>>()?;
        Ok(posterior::learned(&rows))
    }

    /// What the vehicle's last flight left of its pack, for the next flight on it: the last
    /// flight of pack `pack_id` when given (identified: [`crate::battery::PackHistory`]),
    /// else the vehicle's last flight whatever its pack. The gap since that flight is
    /// measured on the logs' clock when both runs had one (`now_log_s`, this run's source
    /// time, and the last flight's end, both Unix times: replays of recorded flights), else
    /// on the wall clock (a live run).
    pub fn pack_history(
        &self,
        key: &VehicleKey,
        pack_id: Option<&str>,
        now_log_s: Option<f64>,
    ) -> Result<Option<crate::battery::PackHistory>> {
        let row = self
            .conn
            .query_row(
                "SELECT id, ended_at, r_scale, heat_a2s, rest_v_end, ended_log_s, deep_slope FROM flights WHERE vehicle = ?1 AND (?2 IS NULL OR pack_id = ?2) ORDER BY id DESC LIMIT 1",
                params![key.key, pack_id],
                |r| Ok(((r.get::<_, i64>(1)?, r.get::<_, Option<f64>>(2)?, r.get::<_, Option<f64>>(3)?, r.get::<_, Option<f64>>(4)?, r.get::<_, Option<f64>>(5)?), r.get::<_, Option<f64>>(6)?)),
            )
            .optional()?;
        Ok(row.map(
            |((ended, r_scale, heat, end_rest_v, ended_log), deep_slope)| {
                crate::battery::PackHistory {
                    identified: pack_id.is_some(),
                    gap_s: match (
                        ended_log.and_then(unix_clock),
                        now_log_s.and_then(unix_clock),
                    ) {
                        (Some(end), Some(now)) => now - end,
                        _ => (now_s() - ended) as f64,
                    },
                    r_scale,
                    heat: heat.filter(|h| h.is_finite() && *h >= 0.0).unwrap_or(0.0),
                    end_rest_v,
                    deep_slope,
                }
            },
        ))
    }

    /// What the vehicle's last flight left of its pack, and the last flight of each pack it
    /// identified (the vehicle's pack is known only once its BATTERY_INFO comes, after the
    /// lookup: the energy stage picks, [`crate::battery::PackHistories::pick`]).
    pub fn pack_histories(
        &self,
        key: &VehicleKey,
        now_log_s: Option<f64>,
    ) -> Result<crate::battery::PackHistories> {
        let mut st = self.conn.prepare(
            "SELECT DISTINCT pack_id FROM flights WHERE vehicle = ?1 AND pack_id IS NOT NULL",
        )?;
        let ids: Vec<String> = st
            .query_map(params![key.key], |r| r.get(0))?
            .collect::<rusqlite::Result<_>>()?;
        let mut by_pack = Vec::with_capacity(ids.len());
        for id in ids {
            if let Some(h) = self.pack_history(key, Some(&id), now_log_s)? {
                by_pack.push((id, h));
            }
        }
        Ok(crate::battery::PackHistories {
            last: self.pack_history(key, None, now_log_s)?,
            by_pack,
        })
    }

    /// Record a run of this vehicle, matched with no pack reported ([`Store::resolve`]).
    pub fn record(
        &mut self,
        id: &Identity,
        fits: Option<&[(String, ModelFit)]>,
        flight: Option<&FlightSummary>,
    ) -> Result<()> {
        let m = self.resolve(id, &PackSig::default())?;
        self.record_matched(id, &m, &PackSig::default(), fits, flight)
    }

    /// Record a run of vehicle `key`: the vehicle (created or updated, with the fits learned
    /// when given) and, when it flew, its flight. One transaction.
    fn record_key(
        &mut self,
        id: &Identity,
        key: &VehicleKey,
        fits: Option<&[(String, ModelFit)]>,
        flight: Option<&FlightSummary>,
    ) -> Result<()> {
        let now = now_s();
        let fits = fits.map(serde_json::to_string).transpose()?;
        let tx = self.conn.transaction()?;
        tx.execute(
            "INSERT INTO vehicles (key, key_kind, system_id, autopilot, vehicle_type, first_seen, last_seen, fits)
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?6, ?7)
             ON CONFLICT(key) DO UPDATE SET last_seen = ?6, system_id = ?3, fits = COALESCE(?7, fits)",
            params![key.key, key.kind, id.system_id, id.autopilot.to_string(), id.vehicle_type, now, fits],
        )?;
        if let Some(f) = flight {
            tx.execute(
                "INSERT INTO flights (vehicle, ended_at, airborne_s, energy_wh, pct_start, pct_end, effective_capacity_wh, rated_capacity_wh, capacity_source,
                                      rest_v_start, rest_v_end, r_scale, internal_r_ohm, heat_a2s, pack_health_pct, ended_log_s, pack_id, deep_slope)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, ?18)",
                params![
                    key.key,
                    now,
                    f.airborne_s,
                    f.energy_wh,
                    f.pct_start,
                    f.pct_end,
                    f.effective_capacity_wh,
                    f.rated_capacity_wh,
                    f.capacity_source,
                    f.rest_v_start,
                    f.rest_v_end,
                    f.r_scale,
                    f.internal_r_ohm,
                    f.heat_a2s,
                    f.pack_health_pct,
                    f.ended_log_s,
                    f.pack_id,
                    f.deep_slope
                ],
            )?;
        }
        tx.commit()?;
        Ok(())
    }

    /// Keep the profile `dronewatt learn` wrote for this vehicle (replacing an earlier one).
    pub fn record_profile(
        &mut self,
        id: &Identity,
        path: &Path,
        forecast_model: Option<&str>,
    ) -> Result<()> {
        let m = self.resolve(id, &PackSig::default())?;
        self.record_matched(id, &m, &PackSig::default(), None, None)?;
        self.conn.execute(
            "INSERT INTO profiles (vehicle, path, forecast_model, learned_at) VALUES (?1, ?2, ?3, ?4)
             ON CONFLICT(vehicle) DO UPDATE SET path = ?2, forecast_model = ?3, learned_at = ?4",
            params![m.key.key, path.to_string_lossy(), forecast_model, now_s()],
        )?;
        Ok(())
    }

    /// The profile learned for this vehicle, if any.
    pub fn learned_profile(&self, key: &str) -> Result<Option<LearnedProfile>> {
        Ok(self
            .conn
            .query_row(
                "SELECT path, forecast_model, learned_at FROM profiles WHERE vehicle = ?1",
                params![key],
                |r| {
                    Ok(LearnedProfile {
                        path: PathBuf::from(r.get::<_, String>(0)?),
                        forecast_model: r.get(1)?,
                        learned_at: r.get(2)?,
                    })
                },
            )
            .optional()?)
    }

    /// Every vehicle with its flights, most recently seen first.
    pub fn vehicles(&self) -> Result<Vec<VehicleRecord>> {
        let mut st = self.conn.prepare(
            "SELECT key, key_kind, system_id, autopilot, vehicle_type, first_seen, last_seen, fits FROM vehicles ORDER BY last_seen DESC, key",
        )?;
        let rows = st.query_map([], |r| {
            let fits: Option<String> = r.get(7)?;
            let learned_models = fits
                .and_then(|f| serde_json::from_str::<Vec<(String, ModelFit)>>(&f).ok())
                .map_or(0, |f| {
                    f.iter().filter(|(_, m)| m.adapted.taught > 0).count()
                });
            Ok(VehicleRecord {
                key: r.get(0)?,
                key_kind: r.get(1)?,
                system_id: r.get(2)?,
                autopilot: r.get(3)?,
                vehicle_type: r.get(4)?,
                vehicle_class: crate::features::class::class_of_mav_type_name(
                    &r.get::<_, String>(4)?,
                ),
                first_seen: r.get(5)?,
                last_seen: r.get(6)?,
                learned_models,
                profile: None,
                pack: PackSig::default(),
                flights: Vec::new(),
            })
        })?;
        let mut out = rows.collect::<rusqlite::Result<Vec<_>>>()?;
        let mut fl = self.conn.prepare(
            "SELECT ended_at, airborne_s, energy_wh, pct_start, pct_end, effective_capacity_wh, rated_capacity_wh, capacity_source,
                    rest_v_start, rest_v_end, r_scale, internal_r_ohm, heat_a2s, pack_health_pct, ended_log_s, pack_id, deep_slope
             FROM flights WHERE vehicle = ?1 ORDER BY ended_at, id",
        )?;
        for v in &mut out {
            let rows = fl.query_map(params![v.key], |r| {
                Ok(FlightRecord {
                    ended_at: r.get(0)?,
                    matched: None,
                    summary: FlightSummary {
                        airborne_s: r.get(1)?,
                        energy_wh: r.get(2)?,
                        pct_start: r.get(3)?,
                        pct_end: r.get(4)?,
                        effective_capacity_wh: r.get(5)?,
                        rated_capacity_wh: r.get(6)?,
                        capacity_source: r.get(7)?,
                        rest_v_start: r.get(8)?,
                        rest_v_end: r.get(9)?,
                        r_scale: r.get(10)?,
                        internal_r_ohm: r.get(11)?,
                        heat_a2s: r.get(12)?,
                        pack_health_pct: r.get(13)?,
                        ended_log_s: r.get(14)?,
                        pack_id: r.get(15)?,
                        deep_slope: r.get(16)?,
                    },
                })
            })?;
            v.flights = rows.collect::<rusqlite::Result<Vec<_>>>()?;
            v.profile = self.learned_profile(&v.key)?;
        }
        self.annotate(&mut out)?;
        Ok(out)
    }
}

#[cfg(test)]
mod tests;
