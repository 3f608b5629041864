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

use super::mission::{MissionOn, Resolved};
use super::{ChainTasks, Inference, VehicleChain, CHANNEL_DEPTH, SILENT_TICK};
use crate::report::status::ChainStatus;
use crate::report::VehicleId;
use crate::sink::Fanout;
use crate::source::fleet::{
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

/// One vehicle's running chain, as the demultiplexer holds it.
struct Vehicle {
    msgs: mpsc::Sender<TimedMessage>,
    events: mpsc::UnboundedSender<FleetEvent>,
    tasks: ChainTasks,
}

impl Fleet {
    /// Route every message to its vehicle's chain (starting one for a vehicle newly heard),
    /// report vehicles gone silent, and end dropped vehicles' chains. Ends when the source
    /// does, after every chain and the inference stage have drained.
    pub(super) async fn run(mut self, mut msgs: mpsc::Receiver<TimedMessage>) -> Result<()> {
        let mut chains: std::collections::HashMap<VehicleId, Vehicle> = Default::default();
        let mut ended = Vec::new();
        let mut events = Vec::new();
        // The source's clock: its newest time, and (live) the wall-clock instant it came.
        let mut clock: Option<(f64, Instant)> = None;
        let mut tick = tokio::time::interval(SILENT_TICK);
        loop {
            tokio::select! {
                m = msgs.recv() => {
                    let Some(m) = m else { break };
                    if m.t_s.is_finite() && clock.is_none_or(|(t, _)| m.t_s >= t) {
                        clock = Some((m.t_s, Instant::now()));
                    }
                    if let Route::Vehicle { id, new, back } = self.demux.route(&m) {
                        if new {
                            match self.start(id) {
                                Ok(v) => { chains.insert(id, v); }
                                Err(e) => tracing::error!(vehicle = %id, "cannot start a chain for this vehicle: {e:#}"),
                            }
                        }
                        if let Some(v) = chains.get(&id) {
                            if back {
                                tracing::info!(vehicle = %id, "vehicle heard again");
                                let _ = v.events.send(FleetEvent::Back { id, t_s: m.t_s });
                            }
                            // A chain that ended early (it cannot) would only lose this message.
                            let _ = v.msgs.send(m).await;
                            self.status.stats.queues.observe(&v.msgs);
                        }
                    }
                    if !self.live {
                        if let Some((t, _)) = clock { self.demux.advance(t, &mut events); }
                    }
                }
                _ = tick.tick(), if self.live => {
                    if let Some((t, at)) = clock { self.demux.advance(t + at.elapsed().as_secs_f64(), &mut events); }
                }
            }
            for ev in events.drain(..) {
                match ev {
                    FleetEvent::Lost { id, silent_s, .. } => {
                        tracing::warn!(
                            vehicle = %id,
                            "vehicle lost: nothing heard for {silent_s:.1} s"
                        );
                        if let Some(v) = chains.get(&id) {
                            let _ = v.events.send(ev);
                        }
                    }
                    FleetEvent::Back { .. } => {}
                    FleetEvent::Dropped { id, silent_s, .. } => {
                        tracing::warn!(
                            vehicle = %id,
                            "vehicle dropped: nothing heard for {silent_s:.1} s"
                        );
                        if let Some(v) = chains.remove(&id) {
                            let _ = v.events.send(ev);
                            // Its input closes: the chain drains, the relay says it was dropped.
                            ended.push((id, v.tasks));
                        }
                    }
                }
            }
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
                tokio::task::spawn_blocking(move || {
                    crate::vehicle::store::remember(
                        &dir,
                        end.identity.as_ref(),
                        fits.as_deref(),
                        &end.flight,
                    )
                })
                .await?;
            }
        }
        Ok(())
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
        let (tx, rx) = mpsc::channel(CHANNEL_DEPTH);
        let chain = chain.with_memory(self.data_dir.clone());
        let (events, tasks) =
            chain.spawn(rx, &self.inference, self.fanout.clone(), &status, self.live);
        Ok(Vehicle {
            msgs: tx,
            events,
            tasks,
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
}

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
        Route::Vehicle {
            id,
            new: true,
            back: false,
        }
    }

    /// Time is now `now_s` (the source's clock): push the vehicles that went lost or must be
    /// dropped onto `out`. A dropped vehicle is forgotten.
    pub fn advance(&mut self, now_s: f64, out: &mut Vec<FleetEvent>) {
        let (lost_after, drop_after) = (self.lost_after_s, self.drop_after_s);
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
            true
        });
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
mod tests {
    use super::*;
    use crate::dialect::{MavAutopilot, MavType, HEARTBEAT_DATA};

    const ONE: VehicleId = VehicleId::single(1);
    const TWO: VehicleId = VehicleId::single(2);

    fn msg(sys: u32, t_s: f64, msg: MavMessage) -> TimedMessage {
        let header = mavlink::MavHeader {
            system_id: sys,
            component_id: 1,
            sequence: 0,
        };
        TimedMessage::new(t_s, header, msg)
    }
    fn hb(mavtype: MavType, autopilot: MavAutopilot) -> MavMessage {
        MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            mavtype,
            autopilot,
            ..Default::default()
        })
    }

    #[test]
    fn filters_parse_ids_and_ranges_and_name_what_is_wrong() {
        let f = VehicleFilter::parse("3, 7,10-20").unwrap();
        assert!(f.contains(3) && f.contains(7) && f.contains(10) && f.contains(20));
        assert!(!f.contains(4) && !f.contains(21) && !f.contains(0) && !f.contains(300));
        assert!(VehicleFilter::parse("1-250").unwrap().contains(250));
        assert!(VehicleFilter::parse("0").unwrap_err().contains("\"0\""));
        assert!(VehicleFilter::parse("20-10")
            .unwrap_err()
            .contains("backwards"));
        assert!(VehicleFilter::parse("5,x").unwrap_err().contains("\"x\""));
        let bad = FleetConfig {
            vehicles: Some("1-300".into()),
            drop_after_s: 1.0,
            ..Default::default()
        };
        let e = bad.validate().unwrap_err();
        assert!(
            e.contains("fleet.vehicles") && e.contains("fleet.drop_after_s"),
            "{e}"
        );
    }

    #[test]
    fn only_vehicles_open_chains_and_silence_makes_them_lost_then_dropped() {
        let mut d = Demux::new(&FleetConfig::default(), None).unwrap();
        let quad = || {
            hb(
                MavType::MAV_TYPE_QUADROTOR,
                MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
            )
        };
        // A ground station and a companion are not vehicles; their telemetry-less chatter is ignored.
        assert_eq!(
            d.route(&msg(
                255,
                0.0,
                hb(MavType::MAV_TYPE_GCS, MavAutopilot::MAV_AUTOPILOT_INVALID)
            )),
            Route::Ignore
        );
        assert_eq!(
            d.route(&msg(255, 0.1, MavMessage::ATTITUDE(Default::default()))),
            Route::Ignore
        );
        assert_eq!(
            d.route(&msg(
                9,
                0.0,
                hb(
                    MavType::MAV_TYPE_ONBOARD_CONTROLLER,
                    MavAutopilot::MAV_AUTOPILOT_GENERIC
                )
            )),
            Route::Ignore
        );
        assert_eq!(
            d.route(&msg(1, 0.0, quad())),
            Route::Vehicle {
                id: VehicleId::single(1),
                new: true,
                back: false
            }
        );
        assert_eq!(
            d.route(&msg(1, 0.1, quad())),
            Route::Vehicle {
                id: VehicleId::single(1),
                new: false,
                back: false
            }
        );
        // Telemetry before a heartbeat opens a vehicle too (a log cut between heartbeats).
        assert_eq!(
            d.route(&msg(2, 0.2, MavMessage::ATTITUDE(Default::default()))),
            Route::Vehicle {
                id: VehicleId::single(2),
                new: true,
                back: false
            }
        );
        assert_eq!(d.vehicles().collect::<Vec<_>>(), vec![ONE, TWO]);
        let mut ev = Vec::new();
        d.route(&msg(2, 9.0, quad()));
        d.advance(10.5, &mut ev);
        assert!(
            matches!(ev.as_slice(), [FleetEvent::Lost { id: ONE, .. }]),
            "{ev:?}"
        );
        d.advance(11.0, &mut ev);
        assert_eq!(ev.len(), 1, "lost is said once");
        assert_eq!(
            d.route(&msg(1, 11.0, quad())),
            Route::Vehicle {
                id: VehicleId::single(1),
                new: false,
                back: true
            }
        );
        ev.clear();
        d.advance(70.0, &mut ev);
        assert!(
            matches!(
                ev.as_slice(),
                [
                    FleetEvent::Lost { id: ONE, .. },
                    FleetEvent::Dropped { id: TWO, .. }
                ]
            ),
            "{ev:?}"
        );
        assert_eq!(d.vehicles().collect::<Vec<_>>(), vec![ONE]);
        assert_eq!(
            d.route(&msg(2, 72.0, quad())),
            Route::Vehicle {
                id: VehicleId::single(2),
                new: true,
                back: false
            }
        );
    }

    #[test]
    fn a_ground_stations_mission_messages_go_to_the_vehicle_they_are_for() {
        let mut d = Demux::new(
            &FleetConfig::default(),
            Some(VehicleFilter::parse("1-2").unwrap()),
        )
        .unwrap();
        let count = |target_system| {
            MavMessage::MISSION_COUNT(crate::dialect::MISSION_COUNT_DATA {
                target_system,
                count: 3,
                ..Default::default()
            })
        };
        // Before the vehicle is heard there is no chain to give it to.
        assert_eq!(d.route(&msg(255, 0.0, count(2))), Route::Ignore);
        let quad = hb(MavType::MAV_TYPE_QUADROTOR, MavAutopilot::MAV_AUTOPILOT_PX4);
        assert!(matches!(
            d.route(&msg(2, 0.1, quad)),
            Route::Vehicle { new: true, .. }
        ));
        // A logged upload to vehicle 2 from the ground station (outside the filter) is
        // vehicle 2's; one to a vehicle never heard, and a broadcast, are nobody's.
        assert_eq!(
            d.route(&msg(255, 0.2, count(2))),
            Route::Vehicle {
                id: TWO,
                new: false,
                back: false
            }
        );
        assert_eq!(d.route(&msg(255, 0.3, count(1))), Route::Ignore);
        assert_eq!(d.route(&msg(255, 0.4, count(0))), Route::Ignore);
        // It keeps the vehicle alive no longer: silent since 0.1 s, it is lost at 10.5 s.
        d.route(&msg(255, 10.0, count(2)));
        let mut ev = Vec::new();
        d.advance(10.5, &mut ev);
        assert!(
            matches!(ev.as_slice(), [FleetEvent::Lost { id: TWO, .. }]),
            "{ev:?}"
        );
    }

    #[test]
    fn a_filter_ignores_and_counts_other_vehicles() {
        let mut d = Demux::new(
            &FleetConfig::default(),
            Some(VehicleFilter::parse("1-2").unwrap()),
        )
        .unwrap();
        let quad = hb(MavType::MAV_TYPE_QUADROTOR, MavAutopilot::MAV_AUTOPILOT_PX4);
        assert_eq!(d.route(&msg(3, 0.0, quad.clone())), Route::Ignore);
        assert_eq!(
            d.route(&msg(2, 0.0, quad)),
            Route::Vehicle {
                id: VehicleId::single(2),
                new: true,
                back: false
            }
        );
        assert_eq!(d.filtered(), 1);
    }

    #[test]
    fn the_same_system_id_on_two_networks_is_two_vehicles() {
        let mut d = Demux::new(&FleetConfig::default(), None).unwrap();
        let quad = || hb(MavType::MAV_TYPE_QUADROTOR, MavAutopilot::MAV_AUTOPILOT_PX4);
        let on = |net: u8, t: f64| TimedMessage {
            network: net,
            ..msg(1, t, quad())
        };
        let a = VehicleId {
            network: 1,
            system_id: 1,
        };
        let b = VehicleId {
            network: 2,
            system_id: 1,
        };
        assert_eq!(
            d.route(&on(1, 0.0)),
            Route::Vehicle {
                id: a,
                new: true,
                back: false
            }
        );
        assert_eq!(
            d.route(&on(2, 0.1)),
            Route::Vehicle {
                id: b,
                new: true,
                back: false
            }
        );
        assert_eq!(d.vehicles().collect::<Vec<_>>(), vec![a, b]);
        assert_eq!((a.to_string(), b.to_string()), ("1:1".into(), "2:1".into()));
        assert_eq!(ONE.to_string(), "1", "on the only network, as always");
    }
}
