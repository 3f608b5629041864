//! Many vehicles on one link: which senders are vehicles, which vehicle a message is
//! about, which vehicles this instance watches (`--vehicles`), and when a vehicle counts
//! as lost and when it is dropped. Pure: no I/O, no clocks (the caller passes the time).
//! [`crate::pipeline`] puts a [`Demux`] in front of one vehicle chain per vehicle: per system
//! id, or per network and system id where the links are separate networks
//! ([`VehicleId`]; `crate::source::links`).
//!
//! A vehicle appears with its first HEARTBEAT from a vehicle: not a ground station
//! (`MAV_TYPE_GCS`), not a companion or other onboard component (`MAV_TYPE_ONBOARD_CONTROLLER`,
//! `MAV_AUTOPILOT_INVALID`: dronewatt's own heartbeat is one). So that a log that begins
//! between two heartbeats loses nothing, a telemetry message the chain reads (ATTITUDE,
//! GLOBAL_POSITION_INT, BATTERY_STATUS … — never sent by a ground station) also opens a
//! vehicle, unless that system id has only ever sent a non-vehicle heartbeat.
//!
//! A vehicle with no message for `lost_after_s` is reported lost (alert `vehicle_lost`,
//! cleared when it is heard again); after `drop_after_s` it is dropped: its chain ends
//! (alert `vehicle_dropped`), and a later message makes it a new vehicle.
//!
//! Below, [`Fleet`] runs it: it routes every message to its vehicle's chain, starts a chain
//! for a vehicle newly heard, and ends the chains of vehicles dropped.

use std::sync::Arc;

use anyhow::Result;
use tokio::sync::mpsc;
use tokio::time::Instant;

use crate::config::Config;
use std::collections::BTreeMap;

use super::batches::{self, Batch, Spares};
use super::mission::{MissionOn, Resolved};
use super::{ChainTasks, Inference, VehicleChain, CHANNEL_DEPTH, SILENT_TICK};
use crate::report::status::ChainStatus;
use crate::report::VehicleId;
use crate::sink::Fanout;
use crate::source::messages::fleet::{
    is_vehicle_heartbeat, is_vehicle_telemetry, FleetConfig, VehicleFilter,
};
use crate::source::TimedMessage;
use crate::MavMessage;

/// The demultiplexer and what it starts chains with.
pub(super) struct Fleet {
    pub(super) config: Config,
    /// What the config names, read at start: every chain is built from it.
    pub(super) resolved: Resolved,
    /// How each vehicle's chain forecasts its mission (None: no mission to follow).
    pub(super) mission: Option<MissionOn>,
    pub(super) demux: Demux,
    /// The chain built (and checked) before the run: the first vehicle's.
    pub(super) first: Option<VehicleChain>,
    pub(super) inference: Inference,
    pub(super) fanout: Fanout,
    pub(super) status: ChainStatus,
    pub(super) live: bool,
    /// The vehicle store's folder ([`crate::vehicle::store`]); `None`: nothing remembered.
    pub(super) data_dir: Option<std::path::PathBuf>,
}

/// Most messages the demultiplexer takes off its queue at once before it hands each
/// vehicle its share as one batch (one channel send and one wake-up of the vehicle's chain
/// per burst, not per message). Only what is already queued is taken: nothing waits.
const BURST: usize = 512;

/// A replay's batches queued per vehicle (a live link's: [`CHANNEL_DEPTH`]). A replay
/// waits on its slowest chain anyway; a deeper queue only let a flat-out replay run ahead
/// into memory (1,024 batches a vehicle: the kernel zeroing the pages of that backlog was
/// ~8 % of a 250-vehicle flat-out replay's CPU). The reports are the same at any depth.
const REPLAY_DEPTH: usize = 32;

/// One vehicle's running chain, as the demultiplexer holds it.
struct Vehicle {
    msgs: mpsc::Sender<Batch>,
    /// The empty batches its chain handed back, filled again (no allocation per burst).
    spares: Spares,
    events: mpsc::UnboundedSender<FleetEvent>,
    tasks: ChainTasks,
    /// Its messages of the burst being routed, in order, not yet handed over (no room
    /// between bursts: a spare is taken at the burst's first message).
    pending: Batch,
}

impl Vehicle {
    /// Hand the chain what the burst had for it.
    async fn flush(&mut self, status: &ChainStatus) {
        if self.pending.is_empty() {
            return;
        }
        // A chain that ended early (it cannot) would only lose these messages.
        let _ = self.msgs.send(std::mem::take(&mut self.pending)).await;
        status.stats.queues.observe(&self.msgs);
    }

    /// Queue `m` on the burst's batch (a spare one at the burst's first message).
    fn push(&mut self, m: TimedMessage) {
        if self.pending.capacity() == 0 {
            self.pending = self.spares.take();
        }
        self.pending.push(m);
    }
}

/// foldhash, not std's SipHash: one look-up per message, and the keys are bounded (no flood).
type Chains = std::collections::HashMap<VehicleId, Vehicle, foldhash::fast::RandomState>;

impl Fleet {
    /// Route every message to its vehicle's chain (starting one for a vehicle newly heard),
    /// report vehicles gone silent, and end dropped vehicles' chains. Ends when the source
    /// does, after every chain and the inference stage have drained.
    pub(super) async fn run(mut self, mut msgs: mpsc::Receiver<TimedMessage>) -> Result<()> {
        let mut chains = Chains::default();
        let mut ended = Vec::new();
        let mut events = Vec::new();
        // The source's clock: its newest time, and (live) the wall-clock instant it came.
        let mut clock: Option<(f64, Instant)> = None;
        let mut tick = tokio::time::interval(SILENT_TICK);
        let (mut burst, mut touched) = (Vec::with_capacity(BURST), Vec::new());
        loop {
            tokio::select! {
                n = msgs.recv_many(&mut burst, BURST) => {
                    if n == 0 { break }
                    for m in burst.drain(..) {
                        if m.t_s.is_finite() && clock.is_none_or(|(t, _)| m.t_s >= t) {
                            clock = Some((m.t_s, Instant::now()));
                        }
                        if let Some(id) = self.take(m, &mut chains) {
                            touched.push(id);
                        }
                        if !self.live {
                            if let Some((t, _)) = clock { self.demux.advance(t, &mut events); }
                            Self::on_events(&self.status, &mut events, &mut chains, &mut ended).await;
                        }
                    }
                    for id in touched.drain(..) {
                        if let Some(v) = chains.get_mut(&id) {
                            v.flush(&self.status).await;
                        }
                    }
                }
                _ = tick.tick(), if self.live => {
                    if let Some((t, at)) = clock { self.demux.advance(t + at.elapsed().as_secs_f64(), &mut events); }
                }
            }
            Self::on_events(&self.status, &mut events, &mut chains, &mut ended).await;
        }
        let filtered = self.demux.filtered();
        if filtered > 0 {
            tracing::info!("{filtered} messages from vehicles outside fleet.vehicles ignored");
        }
        ended.extend(chains.into_iter().map(|(id, v)| (id, v.tasks)));
        drop(self.fanout);
        let mut ends = Vec::with_capacity(ended.len());
        for (id, t) in ended {
            ends.push((id, t.join().await?));
        }
        let mut fits = self.inference.join().await?;
        // The flight is over: remember each vehicle, off the reactor (a slow or locked
        // database delays nothing but this write, and a failure is a warning).
        if let Some(dir) = self.data_dir {
            for (id, end) in ends {
                let (dir, fits) = (dir.clone(), fits.remove(&id));
                let profile = self.resolved.vehicle.profile.clone();
                tokio::task::spawn_blocking(move || {
                    crate::vehicle::store::remember(
                        &dir,
                        end.identity.as_ref(),
                        &end.pack,
                        fits.as_deref(),
                        &end.flight,
                    );
                    // the first hover's calibration, as the vehicle's profile
                    crate::vehicle::store::hover::remember_hover(
                        &dir,
                        end.identity.as_ref(),
                        &profile,
                        end.flight.hover(),
                    );
                })
                .await?;
            }
        }
        Ok(())
    }

    /// Route message `m`: onto its vehicle's pending batch (a chain started first for a
    /// vehicle newly heard). The vehicle it went to.
    fn take(&mut self, m: TimedMessage, chains: &mut Chains) -> Option<VehicleId> {
        let Route::Vehicle { id, new, back } = self.demux.route(&m) else {
            return None;
        };
        if new {
            match self.start(id) {
                Ok(v) => {
                    chains.insert(id, v);
                }
                Err(e) => {
                    tracing::error!(vehicle = %id, "cannot start a chain for this vehicle: {e:#}")
                }
            }
        }
        let v = chains.get_mut(&id)?;
        if back {
            tracing::info!(vehicle = %id, "vehicle heard again");
            let _ = v.events.send(FleetEvent::Back { id, t_s: m.t_s });
        }
        v.push(m);
        // The first message of this burst for it: the caller hands the batch over.
        (v.pending.len() == 1).then_some(id)
    }

    /// Tell the chains what the demultiplexer noticed; a dropped vehicle's chain gets what
    /// it still had pending, then its input closes (it drains, its relay says it was dropped).
    async fn on_events(
        status: &ChainStatus,
        events: &mut Vec<FleetEvent>,
        chains: &mut Chains,
        ended: &mut Vec<(VehicleId, ChainTasks)>,
    ) {
        for ev in events.drain(..) {
            match ev {
                FleetEvent::Lost { id, silent_s, .. } => {
                    tracing::warn!(vehicle = %id, "vehicle lost: nothing heard for {silent_s:.1} s");
                    if let Some(v) = chains.get(&id) {
                        let _ = v.events.send(ev);
                    }
                }
                FleetEvent::Back { .. } => {}
                FleetEvent::Dropped { id, silent_s, .. } => {
                    tracing::warn!(vehicle = %id, "vehicle dropped: nothing heard for {silent_s:.1} s");
                    if let Some(mut v) = chains.remove(&id) {
                        v.flush(status).await;
                        let _ = v.events.send(ev);
                        ended.push((id, v.tasks));
                    }
                }
            }
        }
    }

    /// Start vehicle `id`'s chain: the chain built before the run for the first vehicle
    /// (it reports the signal health the terminal shows), a fresh one for the others. It
    /// sends on its own network's links.
    fn start(&mut self, id: VehicleId) -> Result<Vehicle> {
        let (chain, mut status) = match self.first.take() {
            Some(c) => (c, self.status.clone()),
            None => (
                VehicleChain::another(&self.config, &self.resolved)?,
                ChainStatus {
                    health: Default::default(),
                    ..self.status.clone()
                },
            ),
        };
        // Each vehicle forecasts its own mission (the first's was built before the run).
        let mut chain = chain;
        if chain.mission.is_none() {
            if let Some(m) = &self.mission {
                chain.mission = Some(m.setup(&self.config, &self.resolved)?);
            }
        }
        status.system_id = Arc::new(std::sync::atomic::AtomicU8::new(id.system_id));
        status.network = id.network;
        status.link = status.link.network(id.network);
        tracing::info!(vehicle = %id, "vehicle heard: following it");
        let (tx, spares, rx) = batches::channel(if self.live {
            CHANNEL_DEPTH
        } else {
            REPLAY_DEPTH
        });
        let chain = chain.with_memory(self.data_dir.clone());
        let (events, tasks) =
            chain.spawn(rx, &self.inference, self.fanout.clone(), &status, self.live);
        Ok(Vehicle {
            msgs: tx,
            spares,
            events,
            tasks,
            pending: Vec::new(),
        })
    }
}

/// Where one message goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Route {
    /// Not about a vehicle this instance watches.
    Ignore,
    /// To vehicle `id`'s chain; `new`: start that chain first; `back`: it had been lost.
    Vehicle {
        id: VehicleId,
        new: bool,
        back: bool,
    },
}

/// What the demultiplexer noticed as time went by.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FleetEvent {
    /// Nothing heard from vehicle `id` for `silent_s` (≥ `lost_after_s`), at time `t_s`.
    Lost {
        id: VehicleId,
        t_s: f64,
        silent_s: f64,
    },
    /// A lost vehicle was heard again at `t_s` ([`Route::Vehicle`]'s `back`).
    Back { id: VehicleId, t_s: f64 },
    /// Nothing heard for `silent_s` (≥ `drop_after_s`): its chain ends.
    Dropped {
        id: VehicleId,
        t_s: f64,
        silent_s: f64,
    },
}

#[derive(Debug)]
struct Seen {
    last_t: f64,
    lost: bool,
}

/// Which vehicle each message is about, and which vehicles went silent (module docs).
#[derive(Debug)]
pub struct Demux {
    lost_after_s: f64,
    drop_after_s: f64,
    filter: VehicleFilter,
    vehicles: BTreeMap<VehicleId, Seen>,
    not_vehicles: std::collections::HashSet<VehicleId>,
    filtered: u64,
    /// No vehicle can go lost or be dropped before this time (a bound a little early, see
    /// [`Demux::advance`]): until then `advance` looks at no vehicle. A replay calls it on
    /// every message, and a walk over every vehicle a message was ~3 % of a flat-out
    /// 250-vehicle replay's CPU.
    next_due_s: f64,
}

/// How much earlier than its exact time a vehicle's next deadline is kept: `now - last >=
/// after` is checked by the walk itself, so a bound this far early cannot skip a walk that
/// would have reported something (rounding in `last + after` is far below it).
const DUE_SLACK_S: f64 = 1e-3;

impl Demux {
    /// A demultiplexer for this configuration (checked: [`FleetConfig::validate`]);
    /// `filter` overrides the configured `vehicles`.
    pub fn new(cfg: &FleetConfig, filter: Option<VehicleFilter>) -> Result<Self, String> {
        cfg.validate()?;
        let filter = match (filter, &cfg.vehicles) {
            (Some(f), _) => f,
            (None, Some(s)) => VehicleFilter::parse(s)?,
            (None, None) => VehicleFilter::default(),
        };
        Ok(Self {
            lost_after_s: cfg.lost_after_s,
            drop_after_s: cfg.drop_after_s,
            filter,
            vehicles: BTreeMap::new(),
            not_vehicles: Default::default(),
            filtered: 0,
            next_due_s: f64::INFINITY,
        })
    }

    /// Where message `m` goes (and note when its vehicle was last heard).
    pub fn route(&mut self, m: &TimedMessage) -> Route {
        let sys = m.header.system_id;
        let Ok(system_id) = u8::try_from(sys) else {
            return Route::Ignore;
        };
        if system_id == 0 {
            return Route::Ignore;
        }
        let id = VehicleId {
            network: m.network,
            system_id,
        };
        // A ground station's mission messages to a vehicle (a logged upload or download)
        // go to that vehicle's chain, for its mission forecast; they keep it alive no longer.
        if !self.vehicles.contains_key(&id) {
            if let Some(to) = mission_target(&m.msg).filter(|&t| t != 0) {
                let to = VehicleId {
                    network: m.network,
                    system_id: to,
                };
                if self.vehicles.contains_key(&to) {
                    return Route::Vehicle {
                        id: to,
                        new: false,
                        back: false,
                    };
                }
            }
        }
        if !self.filter.contains(sys) {
            self.filtered += 1;
            return Route::Ignore;
        }
        if let Some(v) = self.vehicles.get_mut(&id) {
            v.last_t = v.last_t.max(m.t_s);
            let back = std::mem::take(&mut v.lost);
            if back {
                // Lost, its next deadline was the drop; now it is the loss again.
                self.next_due_s = self
                    .next_due_s
                    .min(v.last_t + self.lost_after_s - DUE_SLACK_S);
            }
            return Route::Vehicle {
                id,
                new: false,
                back,
            };
        }
        let opens = match &m.msg {
            MavMessage::HEARTBEAT(h) if is_vehicle_heartbeat(h) => true,
            MavMessage::HEARTBEAT(_) => {
                self.not_vehicles.insert(id);
                false
            }
            msg => is_vehicle_telemetry(msg) && !self.not_vehicles.contains(&id),
        };
        if !opens || !m.t_s.is_finite() {
            return Route::Ignore;
        }
        self.vehicles.insert(
            id,
            Seen {
                last_t: m.t_s,
                lost: false,
            },
        );
        self.next_due_s = self.next_due_s.min(m.t_s + self.lost_after_s - DUE_SLACK_S);
        Route::Vehicle {
            id,
            new: true,
            back: false,
        }
    }

    /// Time is now `now_s` (the source's clock): push the vehicles that went lost or must be
    /// dropped onto `out`. A dropped vehicle is forgotten.
    ///
    /// Each vehicle's next deadline (lost, or dropped once lost) only moves later as it is
    /// heard, so the earliest of them, noted at each walk and lowered when a vehicle is new
    /// or back, is a bound: before it, nothing can happen and no vehicle is looked at.
    pub fn advance(&mut self, now_s: f64, out: &mut Vec<FleetEvent>) {
        if now_s < self.next_due_s {
            return;
        }
        let (lost_after, drop_after) = (self.lost_after_s, self.drop_after_s);
        let mut next_due = f64::INFINITY;
        self.vehicles.retain(|&id, v| {
            let silent_s = now_s - v.last_t;
            if silent_s >= drop_after {
                out.push(FleetEvent::Dropped {
                    id,
                    t_s: now_s,
                    silent_s,
                });
                return false;
            }
            if silent_s >= lost_after && !v.lost {
                v.lost = true;
                out.push(FleetEvent::Lost {
                    id,
                    t_s: now_s,
                    silent_s,
                });
            }
            let after = if v.lost { drop_after } else { lost_after };
            next_due = next_due.min(v.last_t + after - DUE_SLACK_S);
            true
        });
        self.next_due_s = next_due;
    }

    /// The vehicles present now, by network and system id.
    pub fn vehicles(&self) -> impl Iterator<Item = VehicleId> + '_ {
        self.vehicles.keys().copied()
    }

    /// The system ids followed.
    pub fn filter(&self) -> &VehicleFilter {
        &self.filter
    }

    /// Messages ignored because their system id is outside the filter.
    pub fn filtered(&self) -> u64 {
        self.filtered
    }
}

/// The vehicle a mission-protocol message (MISSION_COUNT, MISSION_ITEM(_INT), MISSION_ACK)
/// is addressed to.
// MISSION_ITEM is deprecated, and still what older ground stations log.
#[allow(deprecated)]
fn mission_target(msg: &MavMessage) -> Option<u8> {
    match msg {
        MavMessage::MISSION_COUNT(c) => Some(c.target_system),
        MavMessage::MISSION_ITEM_INT(i) => Some(i.target_system),
        MavMessage::MISSION_ITEM(i) => Some(i.target_system),
        MavMessage::MISSION_ACK(a) => Some(a.target_system),
        _ => None,
    }
}

#[cfg(test)]
#[path = "fleet_tests.rs"]
mod tests;
