//! One vehicle is one vehicle: which stored vehicle a flight belongs to.
//!
//! AUTOPILOT_VERSION's board uid names the vehicle where it is sent. Without it, the key
//! (system id, autopilot, HEARTBEAT type; the type also fixes the class) is weak: two
//! quadrotors left at system id 1 share it. So the store also keeps the pack each vehicle
//! reported of itself ([`PackSig`]: cells in series and rated capacity, from its
//! parameters, BATTERY_STATUS or BATTERY_INFO; never the config's or a guess), and a vehicle
//! whose pack differs from every remembered vehicle's under that key is a **new vehicle**,
//! stored as `KEY#2`, `KEY#3`, …, with a warning that names the difference. A figure the
//! vehicle did not report contradicts nothing (a match by the key alone, said as such).
//!
//! Each flight keeps why it was matched ([`Matched::reason`]): `uid`, `key + pack (4S,
//! 5000 mAh)`, `key only (pack not reported)`, `first flight` or `new: …`; `dronewatt
//! vehicles` lists it.

use rusqlite::{params, Connection};

use super::{Store, VehicleKey};
use crate::vehicle::params::{Identity, VehicleParams};

/// Capacities closer than this (relative) are the same pack's rating.
const CAPACITY_TOLERANCE: f64 = 0.05;

/// The pack a vehicle reported of itself: what tells two vehicles under one key apart.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct PackSig {
    /// Cells in series (`BAT1_N_CELLS`, BATTERY_STATUS's cell voltages, BATTERY_INFO,
    /// ArduCopter's `MOT_BAT_VOLT_MAX` at 4.2 or 4.35 V a cell).
    pub cells: Option<u32>,
    /// Rated capacity, mAh (`BATT_CAPACITY`, `BAT1_CAPACITY`, BATTERY_INFO).
    pub capacity_mah: Option<f64>,
}

impl PackSig {
    /// What `p` says of the pack; out-of-range or "unset" values say nothing.
    pub fn of(p: &VehicleParams) -> Self {
        let cells = p
            .get("BAT1_N_CELLS")
            .filter(|v| (1.0..=24.0).contains(v))
            .map(|v| v.round() as u32)
            .or(p.battery_cells.filter(|n| (2..=24).contains(n)))
            .or(p
                .battery_info
                .and_then(|(_, n)| n)
                .filter(|n| (1..=24).contains(n)))
            .or(p
                .get("MOT_BAT_VOLT_MAX")
                .filter(|v| v.is_finite() && *v > 0.0)
                .and_then(|v| {
                    crate::vehicle::cells_from(v, 4.2, 0.03)
                        .or_else(|| crate::vehicle::cells_from(v, 4.35, 0.03))
                }));
        let capacity_mah = ["BATT_CAPACITY", "BAT1_CAPACITY"]
            .iter()
            .find_map(|n| p.get(n).filter(|v| (50.0..1_000_000.0).contains(v)))
            .or(p
                .battery_info
                .and_then(|(ah, _)| ah)
                .map(|ah| ah * 1000.0)
                .filter(|v| (50.0..1_000_000.0).contains(v)));
        Self {
            cells,
            capacity_mah,
        }
    }

    /// Whether it says anything.
    pub fn is_known(&self) -> bool {
        self.cells.is_some() || self.capacity_mah.is_some()
    }

    /// `4S, 5000 mAh`; `?` for what was not reported.
    pub fn describe(&self) -> String {
        format!(
            "{}, {}",
            self.cells.map_or("?S".to_string(), |n| format!("{n}S")),
            self.capacity_mah
                .map_or("? mAh".to_string(), |c| format!("{c:.0} mAh"))
        )
    }

    /// The differences from `other` (both known and unequal), named; empty when none.
    fn differences(&self, other: &PackSig) -> Vec<String> {
        let mut d = Vec::new();
        if let (Some(a), Some(b)) = (self.cells, other.cells) {
            if a != b {
                d.push(format!("{a} cells, not {b}"));
            }
        }
        if let (Some(a), Some(b)) = (self.capacity_mah, other.capacity_mah) {
            if (a - b).abs() > CAPACITY_TOLERANCE * a.max(b) {
                d.push(format!("{a:.0} mAh, not {b:.0}"));
            }
        }
        d
    }

    /// How many figures both know and agree on.
    fn agreement(&self, other: &PackSig) -> usize {
        let cells = matches!((self.cells, other.cells), (Some(a), Some(b)) if a == b);
        let cap = matches!((self.capacity_mah, other.capacity_mah), (Some(a), Some(b))
            if (a - b).abs() <= CAPACITY_TOLERANCE * a.max(b));
        usize::from(cells) + usize::from(cap)
    }
}

/// The stored vehicle a flight belongs to, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct Matched {
    pub key: VehicleKey,
    /// Why this vehicle (module docs): kept with each flight.
    pub reason: String,
    /// A new vehicle because its pack differs from every one remembered under its key.
    pub new_by_pack: bool,
}

/// The `vehicles` columns schema 5 adds: the pack each vehicle reported.
pub(super) const VEHICLE_COLUMNS: [(&str, &str); 2] =
    [("cells", "INTEGER"), ("capacity_mah", "REAL")];

/// The `flights` column schema 5 adds: why the flight was matched to its vehicle.
pub(super) const FLIGHT_COLUMN: &str = "matched";

/// The `ALTER TABLE`s schema 5 needs on `conn` (the columns not there yet).
pub(super) fn migration(conn: &Connection) -> rusqlite::Result<String> {
    let have = |table: &str| -> rusqlite::Result<Vec<String>> {
        conn.prepare(&format!("SELECT name FROM pragma_table_info('{table}')"))?
            .query_map([], |r| r.get(0))?
            .collect()
    };
    let (vehicles, flights) = (have("vehicles")?, have("flights")?);
    let mut sql = String::new();
    for (c, ty) in VEHICLE_COLUMNS {
        if !vehicles.iter().any(|h| h == c) {
            sql.push_str(&format!("ALTER TABLE vehicles ADD COLUMN {c} {ty};"));
        }
    }
    if !flights.iter().any(|h| h == FLIGHT_COLUMN) {
        sql.push_str(&format!(
            "ALTER TABLE flights ADD COLUMN {FLIGHT_COLUMN} TEXT;"
        ));
    }
    Ok(sql)
}

impl Store {
    /// The stored vehicle `id` with pack `sig` is (module docs). Reads only.
    pub fn resolve(&self, id: &Identity, sig: &PackSig) -> anyhow::Result<Matched> {
        let base = VehicleKey::of(id);
        if id.uid.is_some() {
            return Ok(Matched {
                key: base,
                reason: "uid".into(),
                new_by_pack: false,
            });
        }
        let mut st = self.conn.prepare(
            "SELECT key, cells, capacity_mah FROM vehicles
             WHERE key = ?1 OR substr(key, 1, length(?1) + 1) = ?1 || '#'
             ORDER BY last_seen DESC, key",
        )?;
        let known: Vec<(String, PackSig)> = st
            .query_map(params![base.key], |r| {
                Ok((
                    r.get::<_, String>(0)?,
                    PackSig {
                        cells: r.get(1)?,
                        capacity_mah: r.get(2)?,
                    },
                ))
            })?
            .collect::<rusqlite::Result<_>>()?;
        if known.is_empty() {
            return Ok(Matched {
                key: base,
                reason: "first flight".into(),
                new_by_pack: false,
            });
        }
        // The remembered vehicle whose pack agrees most (the most recent on a tie).
        let best = known
            .iter()
            .filter(|(_, k)| sig.differences(k).is_empty())
            .max_by_key(|(_, k)| sig.agreement(k));
        if let Some((key, k)) = best {
            let reason = if sig.agreement(k) > 0 {
                format!("key + pack ({})", sig.describe())
            } else if sig.is_known() {
                format!("key only (pack {}: nothing to compare)", sig.describe())
            } else {
                "key only (pack not reported)".to_string()
            };
            return Ok(Matched {
                key: VehicleKey {
                    key: key.clone(),
                    kind: base.kind,
                },
                reason,
                new_by_pack: false,
            });
        }
        let (nearest, theirs) = &known[0];
        let mut n = known.len() + 1;
        let key = loop {
            let k = format!("{}#{n}", base.key);
            if !known.iter().any(|(have, _)| *have == k) {
                break k;
            }
            n += 1;
        };
        Ok(Matched {
            reason: format!(
                "new: pack {} differs from {nearest}'s ({})",
                sig.describe(),
                sig.differences(theirs).join(", ")
            ),
            key: VehicleKey {
                key,
                kind: base.kind,
            },
            new_by_pack: true,
        })
    }

    /// Record a run of the vehicle `m` names: as `Store::record_key`, then the pack it
    /// reported (what it did not report keeps the remembered value) and why the flight was
    /// matched.
    pub fn record_matched(
        &mut self,
        id: &Identity,
        m: &Matched,
        sig: &PackSig,
        fits: Option<&[(String, crate::model::adapt::ModelFit)]>,
        flight: Option<&super::FlightSummary>,
    ) -> anyhow::Result<()> {
        self.record_key(id, &m.key, fits, flight)?;
        let flight_id = flight.map(|_| self.conn.last_insert_rowid());
        self.conn.execute(
            "UPDATE vehicles SET cells = COALESCE(?2, cells), capacity_mah = COALESCE(?3, capacity_mah) WHERE key = ?1",
            params![m.key.key, sig.cells, sig.capacity_mah],
        )?;
        if let Some(fid) = flight_id {
            self.conn.execute(
                "UPDATE flights SET matched = ?1 WHERE id = ?2",
                params![m.reason, fid],
            )?;
        }
        Ok(())
    }

    /// The pack each vehicle reported and why each flight was matched, into `vehicles`.
    pub(super) fn annotate(&self, vehicles: &mut [super::VehicleRecord]) -> anyhow::Result<()> {
        let mut pack = self
            .conn
            .prepare("SELECT cells, capacity_mah FROM vehicles WHERE key = ?1")?;
        let mut why = self
            .conn
            .prepare("SELECT matched FROM flights WHERE vehicle = ?1 ORDER BY ended_at, id")?;
        for v in vehicles {
            v.pack = pack.query_row(params![v.key], |r| {
                Ok(PackSig {
                    cells: r.get(0)?,
                    capacity_mah: r.get(1)?,
                })
            })?;
            let reasons: Vec<Option<String>> = why
                .query_map(params![v.key], |r| r.get(0))?
                .collect::<rusqlite::Result<_>>()?;
            for (f, r) in v.flights.iter_mut().zip(reasons) {
                f.matched = r;
            }
        }
        Ok(())
    }
}

/// How long the lookup waits (source time) for a vehicle it asks to report its pack.
pub const PACK_WAIT_S: f64 = 5.0;
/// How long it waits for a vehicle it only overhears (a replayed log, `--listen-only`): a
/// log carries the parameters it has near its start.
pub const LOG_WAIT_S: f64 = 2.0;

/// The vehicle and its pack, once it is time to look it up (`heard`: when its identity was
/// first heard, s, and its latest parameters; `asks`: dronewatt asks the vehicle for its
/// parameters; `settled`: every one asked answered or given up). At once when its uid or
/// any figure of its pack is heard, or when it was asked everything; else [`PACK_WAIT_S`]
/// (asked) or [`LOG_WAIT_S`] (overheard) after it was first heard. The sooner the lookup,
/// the sooner the warm start; a pack reported later still decides the vehicle the flight is
/// kept under at the end ([`Store::resolve`] again).
pub fn lookup_due(
    heard: Option<&(f64, VehicleParams)>,
    t_s: f64,
    asks: bool,
    settled: bool,
) -> Option<(Identity, PackSig)> {
    let (first, params) = heard?;
    let id = params.identity.clone()?;
    let sig = PackSig::of(params);
    let wait = if asks { PACK_WAIT_S } else { LOG_WAIT_S };
    let told = id.uid.is_some() || sig.is_known() || (asks && settled);
    (told || t_s - first >= wait).then_some((id, sig))
}

/// Say which vehicle it is when that is news: a new vehicle under a known key (WARN, the
/// difference named), or a match by the key alone (INFO: the pack did not tell).
pub fn say(id: &Identity, m: &Matched) {
    let base = VehicleKey::of(id).key;
    if m.new_by_pack {
        tracing::warn!(
            "vehicle {base}: not the vehicle remembered under this key ({}); a new vehicle, {}: nothing learned of the other is used",
            m.reason.trim_start_matches("new: "),
            m.key.key
        );
    } else if m.reason.starts_with("key only") {
        tracing::info!(
            "vehicle {}: matched by system id, autopilot and type only (no uid; {})",
            m.key.key,
            m.reason
                .trim_start_matches("key only (")
                .trim_end_matches(')')
        );
    }
}

#[cfg(test)]
#[path = "matching_tests.rs"]
mod tests;
