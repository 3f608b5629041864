//! Checkpoints of the vehicles' chain state in the key-value bucket [`super::CHECKPOINTS`],
//! so that a worker taking a partition goes on from where its previous holder was instead
//! of from "unknown", and replays only the stream's last seconds.
//!
//! - **What is kept** (the pipeline's vehicle state, `src/pipeline/checkpoint.rs`; opaque bytes here):
//!   the energy stage's whole state, which is the energy used, the pack's state and
//!   history, the mission's progress as last accounted (the energy tracker, serialised as
//!   it is). It also keeps where each alert rule stands, what the vehicle said of itself,
//!   and the source time `t_s` of the last estimate it reflects. The energy stage hands it
//!   over about once a second of source time ([`record`]); the model code does no I/O.
//! - **Keys.** `v<part>.<net>.<sys>`: one vehicle's state (CBOR, which keeps non-finite
//!   numbers that JSON cannot). `c<part>`: the partition's [`PartitionCheckpoint`] (JSON).
//!   It holds the layout version, the card of the chain that wrote it, the writer, the
//!   last stream sequence handed on and its time (how far the writer's reports went out),
//!   the sequence to replay from, and the vehicles. The vehicles are written first. A
//!   header is never ahead of them: a vehicle state is only ever newer than the header
//!   reckons, and the replay skips what a state already reflects.
//! - **Replay from.** The telemetry stage's resampler and window hold the last seconds of
//!   messages, so the replay starts [`LEAD_S`] before the oldest state's time. That stream
//!   sequence is kept as the worker reads ([`Marks`]).
//! - **Restore** ([`restore`], [`take_restore`]): the worker taking a partition reads the
//!   header and its vehicles. A header of another layout version, or written by a chain of
//!   another card (models, vehicle profile, energy, alert, telemetry or mission tables, or
//!   dronewatt version), or a vehicle state that does not read, is said. The partition is
//!   then rebuilt from the stream's first frame. Otherwise each vehicle's energy stage
//!   takes its state at its first estimate and skips the estimates the state already
//!   reflects.
//!
//! Not kept: the LSTM's online adaptation (the vehicle store's warm start brings it back
//! where there is one), the mission download (a live link asks the vehicle again), and the
//! flight log summary the vehicle store writes at the end.

use std::collections::{HashMap, VecDeque};
use std::sync::Mutex;

use async_nats::jetstream::kv::Store;
use serde::{Deserialize, Serialize};

use crate::report::VehicleId;

/// The layout version of the checkpoints; another is rebuilt from the stream.
pub const LAYOUT: u32 = 1;
/// How far before a state's time the replay starts, s: the telemetry stage's resampler
/// (a signal's stale limit, at most 5 s) and window fill again before the first estimate
/// that counts.
pub const LEAD_S: f64 = 10.0;
/// How often (source time, s) the energy stage hands its state over.
pub const EVERY_S: f64 = 1.0;

/// One vehicle's state as the energy stage handed it over: the source time of the last
/// estimate it reflects, and its bytes (CBOR).
#[derive(Debug, Clone)]
pub struct Saved {
    pub t_s: f64,
    pub bytes: Vec<u8>,
}

/// A partition's checkpoint header (`c<part>`).
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct PartitionCheckpoint {
    #[serde(default)]
    pub layout: u32,
    /// The card of the chains that wrote it (`crate::pipeline::checkpoint::card`).
    #[serde(default)]
    pub card: String,
    pub worker: String,
    /// The last stream sequence the writer handed on, and its source time: its reports
    /// went out up to there.
    pub seq: u64,
    pub t_s: f64,
    /// Replay from this stream sequence (0: no vehicle state; from the first frame).
    #[serde(default)]
    pub from_seq: u64,
    /// The vehicles with a state, `(network, system id)`.
    #[serde(default)]
    pub vehicles: Vec<(u8, u8)>,
}

/// What the chains hand over and what a takeover hands them.
#[derive(Default)]
struct Registry {
    /// This process's chain card ([`set_card`]); None: not a fleet worker (no states).
    card: Option<String>,
    /// Whether a state's bytes read as this process's chains' state.
    check: Option<Check>,
    /// The latest state of each vehicle whose chain runs here.
    states: HashMap<VehicleId, Saved>,
    /// States restored from a checkpoint, taken by each vehicle's energy stage.
    restore: HashMap<VehicleId, Vec<u8>>,
}

static REG: Mutex<Option<Registry>> = Mutex::new(None);

fn with<R>(f: impl FnOnce(&mut Registry) -> R) -> Option<R> {
    REG.lock()
        .ok()
        .map(|mut g| f(g.get_or_insert_with(Registry::default)))
}

/// Whether a vehicle state's bytes read (the chains' own decoder).
pub type Check = fn(&[u8]) -> Result<(), String>;

/// Turn checkpoints on in this process (a fleet worker), for chains of this card, whose
/// states `check` reads.
pub fn set_card(card: String, check: Check) {
    with(|r| {
        r.card = Some(card);
        r.check = Some(check);
    });
}

/// This process's chain card, when it is a fleet worker.
pub fn my_card() -> Option<String> {
    with(|r| r.card.clone()).flatten()
}

/// Whether the energy stages hand their state over (a fleet worker).
pub fn enabled() -> bool {
    with(|r| r.card.is_some()).unwrap_or(false)
}

/// The energy stage's state of `vehicle` now (called about every [`EVERY_S`]).
pub fn record(vehicle: VehicleId, state: Saved) {
    with(|r| r.states.insert(vehicle, state));
}

/// The restored state of `vehicle`, once (its energy stage's first estimate).
pub fn take_restore(vehicle: VehicleId) -> Option<Vec<u8>> {
    with(|r| r.restore.remove(&vehicle)).flatten()
}

/// The latest states of partition `part`'s vehicles.
fn states_of(part: u32) -> Vec<(VehicleId, Saved)> {
    with(|r| {
        r.states
            .iter()
            .filter(|(v, _)| super::partition(v.network, v.system_id) == part)
            .map(|(v, s)| (*v, s.clone()))
            .collect()
    })
    .unwrap_or_default()
}

/// The stream sequences a partition's reading passed, about every half second of source
/// time, for the last two minutes: where a replay [`LEAD_S`] before a time starts.
#[derive(Debug, Clone, Default)]
pub struct Marks(VecDeque<(u64, f64)>);

impl Marks {
    /// Frame `seq` at source time `t_s` was handed on.
    pub fn passed(&mut self, seq: u64, t_s: f64) {
        if self.0.back().is_none_or(|&(_, t)| t_s - t >= 0.5) {
            self.0.push_back((seq, t_s));
        }
        while self.0.front().is_some_and(|&(_, t)| t_s - t > 120.0) {
            self.0.pop_front();
        }
    }

    /// The last sequence marked at or before `t_s` (the oldest kept when none is).
    pub fn at_or_before(&self, t_s: f64) -> u64 {
        self.0
            .iter()
            .rev()
            .find(|&&(_, t)| t <= t_s)
            .or(self.0.front())
            .map_or(1, |&(s, _)| s)
    }
}

/// Write partition `part`'s checkpoint: its vehicles' states, then the header. `seq`/`t_s`:
/// the last frame handed on.
pub async fn write(kv: &Store, part: u32, me: &str, seq: u64, t_s: f64, marks: &Marks) {
    let states = states_of(part);
    let mut vehicles = Vec::with_capacity(states.len());
    // A vehicle silent for a minute does not hold the replay back (its frames are old).
    let oldest = states
        .iter()
        .map(|(_, s)| s.t_s)
        .filter(|t| *t >= t_s - 60.0)
        .fold(f64::INFINITY, f64::min);
    for (v, s) in states {
        let body = s.bytes;
        let key = format!("v{part}.{}.{}", v.network, v.system_id);
        match kv.put(key, body.into()).await {
            Ok(_) => vehicles.push((v.network, v.system_id)),
            Err(e) => tracing::warn!("NATS: checkpoint of vehicle {v}: {e}"),
        }
    }
    let from_seq = if vehicles.is_empty() {
        0
    } else if oldest.is_finite() {
        marks.at_or_before(oldest - LEAD_S)
    } else {
        seq
    };
    let c = PartitionCheckpoint {
        layout: LAYOUT,
        card: my_card().unwrap_or_default(),
        worker: me.to_string(),
        seq,
        t_s,
        from_seq,
        vehicles,
    };
    if let Ok(body) = serde_json::to_vec(&c) {
        if let Err(e) = kv.put(format!("c{part}"), body.into()).await {
            tracing::warn!("NATS: checkpoint of partition {part}: {e}");
        }
    }
}

/// Read partition `part`'s checkpoint header (None: none, or unreadable).
pub async fn header(kv: &Store, part: u32) -> Option<PartitionCheckpoint> {
    match kv.entry(format!("c{part}")).await {
        Ok(Some(e)) => serde_json::from_slice(&e.value).ok(),
        _ => None,
    }
}

/// Restore partition `part`'s vehicles from checkpoint `c` for their energy stages: the
/// stream sequence to replay from, or None (said why) when the partition must be rebuilt
/// from the stream's first frame.
pub async fn restore(kv: &Store, part: u32, c: &PartitionCheckpoint) -> Option<u64> {
    if c.from_seq == 0 || c.vehicles.is_empty() {
        return None;
    }
    let (mine, check) = with(|r| (r.card.clone().unwrap_or_default(), r.check)).unwrap_or_default();
    if c.layout != LAYOUT || c.card != mine {
        tracing::warn!(
            "NATS: partition {part}: its checkpoint was written by a chain of another card \
             ({:?}, layout {}; this worker's: {mine:?}, layout {LAYOUT}): not restored, the \
             vehicles are rebuilt from the stream",
            c.card,
            c.layout
        );
        return None;
    }
    let mut got = Vec::with_capacity(c.vehicles.len());
    for &(network, system_id) in &c.vehicles {
        let v = VehicleId { network, system_id };
        let key = format!("v{part}.{network}.{system_id}");
        let state = match kv.entry(key).await {
            Ok(Some(e)) => check
                .map_or(Ok(()), |c| c(&e.value))
                .map(|()| e.value.to_vec()),
            Ok(None) => Err("missing".to_string()),
            Err(e) => Err(e.to_string()),
        };
        match state {
            Ok(s) => got.push((v, s)),
            Err(e) => {
                tracing::warn!(
                    "NATS: partition {part}: the checkpoint of vehicle {v} does not read \
                     ({e}): the partition is rebuilt from the stream"
                );
                return None;
            }
        }
    }
    tracing::info!(
        "NATS: partition {part}: restored {} vehicle(s) from the checkpoint of worker {} \
         (energy, pack, mission, alerts); replaying from stream sequence {}",
        got.len(),
        c.worker,
        c.from_seq
    );
    with(|r| r.restore.extend(got));
    Some(c.from_seq)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn marks_find_the_sequence_a_lead_before() {
        let mut m = Marks::default();
        for i in 0..400u64 {
            m.passed(i + 1, i as f64 * 0.1);
        }
        // Marked about every 0.5 s: the one at or before 20 s is sequence 201 (t = 20.0).
        assert_eq!(m.at_or_before(20.0), 201);
        assert!(m.at_or_before(-5.0) >= 1);
        let mut empty = Marks::default();
        assert_eq!(empty.at_or_before(3.0), 1);
        empty.passed(7, 1.0);
        assert_eq!(empty.at_or_before(0.0), 7);
    }
}
