//! The chain's two stage tasks: telemetry (messages → samples → windows, the vehicle beside,
//! the mission forecast) and energy (estimates → energy, pack, alerts), and the per-vehicle
//! accounting of what each report cost.

use std::sync::Arc;

use tokio::sync::mpsc;
use tokio::time::Instant;

use super::checkpoint::Kept;
use super::mission::take_mission;
use super::{HEALTH_EVERY, SILENT_TICK};
use crate::alert::AlertEngine;
use crate::energy::EnergyTracker;
use crate::mission::live::MissionStep;
use crate::report::status::{ChainStatus, IngestStats};
use crate::report::{Estimate, MissionUpdate, Report, VehicleId};
use crate::sink::Fanout;
use crate::telemetry::Telemetry;
use crate::vehicle::params::{Driver, Identity, VehicleParams};
use crate::vehicle::store::FlightLog;

use super::chain::{look_up, Memory, VehicleNews, WindowsOut};
/// Messages → fixed-rate samples → windows; refreshes the signal health about once a second.
/// Reads the vehicle beside ([`Driver`]: asks on a live link) and publishes what it learns;
/// runs the vehicle's mission forecast ([`MissionStep`]) on the same messages, first.
#[allow(clippy::too_many_arguments)] // a stage: its state, its channels in and out
pub(super) async fn telemetry_stage(
    mut telemetry: Telemetry,
    mut vehicle: Driver,
    mut mission: Option<MissionStep>,
    mut msgs: super::BatchRx,
    windows: WindowsOut,
    news: mpsc::UnboundedSender<VehicleNews>,
    mut memory: Option<Memory>,
    status: ChainStatus,
) {
    let mut out = Vec::new();
    let mut shown = Instant::now();
    let mut open = true;
    // The mission download's timeouts (a live link only).
    let ticking = mission.as_ref().is_some_and(MissionStep::active);
    let mut tick = tokio::time::interval(crate::mission::live::TICK);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    while open {
        let next = tokio::select! {
            m = msgs.recv() => Some(m),
            _ = tick.tick(), if ticking => None,
        };
        match next {
            None => {
                if let Some(step) = mission.as_mut() {
                    step.tick();
                }
                continue;
            }
            // The messages the demultiplexer had for this vehicle at once, in order.
            Some(Some(batch)) => {
                for m in &batch {
                    if let Some(step) = mission.as_mut() {
                        step.on_message(m);
                    }
                    if let Some(params) = vehicle.on_message(m) {
                        if let (Some(mem), true) = (&mut memory, params.identity.is_some()) {
                            let first = mem.heard.as_ref().map_or(m.t_s, |h| h.0);
                            mem.heard = Some((first, params.clone()));
                        }
                        // Only the energy stage listens; it gone (shutting down) is no error.
                        let _ = news.send(VehicleNews::Params(m.t_s, params));
                    }
                    // The vehicle and its pack known: look up what earlier flights taught.
                    if let Some(mem) = &mut memory {
                        let (asks, settled) = (vehicle.reader().asks(), vehicle.reader().settled());
                        let heard = mem.heard.as_ref().filter(|_| !mem.looked_up);
                        let due = crate::vehicle::store::lookup_due(heard, m.t_s, asks, settled);
                        if let Some(who) = due {
                            look_up(mem, who, m.t_s, &status, &news);
                        }
                    }
                    let made = out.len();
                    telemetry.push(m, &mut out);
                    // The windows this message completes: it is the newest that went in.
                    out[made..]
                        .iter_mut()
                        .for_each(|w| w.arrived = Some(m.arrived));
                }
                // Read: back to the demultiplexer, to be filled again.
                msgs.give(batch);
                if let Some(id) = telemetry.system_id() {
                    status
                        .system_id
                        .store(id, std::sync::atomic::Ordering::Relaxed);
                }
            }
            Some(None) => {
                // What the end of the input flushes was made by no message's arrival: these
                // windows keep `arrived: None` and count in no latency.
                telemetry.finish(&mut out);
                open = false;
            }
        }
        if shown.elapsed() >= HEALTH_EVERY || !open {
            shown = Instant::now();
            if let Ok(mut h) = status.health.lock() {
                *h = telemetry.health();
            }
        }
        for w in out.drain(..) {
            IngestStats::add(&status.stats.windows, 1);
            if !windows.send(w).await {
                return;
            }
            status.stats.queues.observe(&windows.jobs);
        }
    }
}

/// What the energy stage has taken of the vehicle's news ([`VehicleNews`]).
#[derive(Default)]
pub(super) struct Taken {
    /// The vehicle's last word taken (its identity goes to the store at the end).
    pub(super) params: VehicleParams,
    /// The store's pack histories and the pack flying (BATTERY_INFO): the carry-over is
    /// picked again when either changes ([`crate::battery::PackHistories::pick`]).
    packs: crate::battery::PackHistories,
    pub(super) pack_id: Option<String>,
    /// The news read and not yet due.
    next: Option<VehicleNews>,
    /// `params` came from a fleet worker's checkpoint: what the vehicle says next is
    /// taken over them ([`VehicleParams::over`]).
    pub(super) restored: bool,
}

impl Taken {
    /// Take the news due by source time `until` (all of it: None) into the energy tracker
    /// and the flight log, in order. A store answer not yet back is waited for: the
    /// estimates after its time are made with what it says, however the threads ran.
    async fn take(
        &mut self,
        rx: &mut mpsc::UnboundedReceiver<VehicleNews>,
        until: Option<f64>,
        energy: &mut EnergyTracker,
        flight: &mut FlightLog,
    ) {
        let mut repick = false;
        loop {
            if self.next.is_none() {
                self.next = rx.try_recv().ok();
            }
            let due = self
                .next
                .as_ref()
                .is_some_and(|n| until.is_none_or(|t| n.t_s() <= t));
            if !due {
                break;
            }
            match self.next.take() {
                Some(VehicleNews::Params(_, params)) => {
                    // Over what a checkpoint restored: what the replay did not hear again
                    // (parameters fetched at the start) stands.
                    let params = if self.restored {
                        params.over(&self.params)
                    } else {
                        params
                    };
                    if params.pack_id.is_some() && params.pack_id != self.pack_id {
                        self.pack_id.clone_from(&params.pack_id);
                        flight.set_pack_id(self.pack_id.clone());
                        repick = true;
                    }
                    energy.set_vehicle(params.clone());
                    self.params = params;
                }
                Some(VehicleNews::Store(_, answer)) => {
                    // The pack's effective capacity from earlier flights, and the forecast
                    // model of a learned profile the models now run from.
                    let news = answer.await.unwrap_or_default();
                    energy.set_learned_capacity(news.capacity);
                    self.packs = news.pack;
                    repick = true;
                    flight.set_log_origin(news.log_origin_s);
                    if let Some((model, why)) = news.forecast {
                        energy.set_default_model(&model, &why);
                    }
                }
                None => break,
            }
        }
        if repick {
            energy.set_pack_history(self.packs.pick(self.pack_id.as_deref()));
        }
    }
}

/// Estimates → energy bookkeeping and alert events → one [`Report`] each, to every sink.
/// On a live link, a silence of [`SILENT_TICK`] still runs the alert rules (on
/// [`Estimate::silent`]); such a tick reports only when a rule changes state, and leaves
/// the energy as it stood.
#[allow(clippy::too_many_arguments)] // a stage: its state, its channels in and out, its clock
pub(super) async fn energy_stage(
    mut energy: EnergyTracker,
    mut alerts: AlertEngine,
    mut estimates: mpsc::Receiver<Estimate>,
    mut mission: Option<mpsc::Receiver<MissionUpdate>>,
    mut news: mpsc::UnboundedReceiver<VehicleNews>,
    mut fanout: Fanout,
    status: ChainStatus,
    live: bool,
) -> (FlightLog, Option<Identity>, crate::vehicle::store::PackSig) {
    let mut flight = FlightLog::default();
    let mut stuck = crate::model::stuck::StuckWatch::default();
    let vehicle_id = || VehicleId {
        network: status.network,
        system_id: match status.system_id.load(std::sync::atomic::Ordering::Relaxed) {
            0 => 1,
            id => id,
        },
    };
    // The last real report (its estimate and energy) and when it came: the base of a silent
    // tick. Shared with the sinks, not copied (a live estimate's clone was an allocation each).
    let mut last: Option<(Arc<Report>, Instant)> = None;
    let mut next_mission: Option<MissionUpdate> = None;
    let mut taken = Taken::default();
    let mut kept = Kept::default();
    loop {
        let next = if live {
            tokio::time::timeout(SILENT_TICK, estimates.recv()).await
        } else {
            Ok(estimates.recv().await)
        };
        let report = match next {
            Ok(Some(est)) => {
                // A fleet worker's takeover: the vehicle's state from its checkpoint, and
                // the estimates it already reflects skipped.
                kept.restore(vehicle_id(), &mut energy, &mut alerts, &mut taken);
                if kept.reflects(est.t_s) {
                    continue;
                }
                // What the vehicle said up to this estimate's time, and no later.
                taken
                    .take(&mut news, Some(est.t_s), &mut energy, &mut flight)
                    .await;
                take_mission(&mut energy, &mut mission, &mut next_mission, est.t_s);
                let t_s = est.t_s;
                let report = account(&mut energy, &mut alerts, est, vehicle_id());
                kept.record(vehicle_id(), t_s, &energy, &alerts, &taken);
                flight.observe(&report);
                for m in stuck.observe(&report.estimate) {
                    tracing::warn!(vehicle = %report.vehicle, "{m}");
                }
                let report = Arc::new(report);
                if live {
                    last = Some((report.clone(), Instant::now()));
                }
                report
            }
            Ok(None) => break,
            Err(_silence) => {
                let Some((r, at)) = &last else {
                    continue;
                };
                let quiet = r
                    .estimate
                    .silent(r.estimate.t_s + at.elapsed().as_secs_f64());
                let events = alerts.evaluate(&quiet, &r.energy);
                if events.is_empty() {
                    continue;
                }
                Arc::new(Report {
                    estimate: quiet,
                    energy: r.energy.clone(),
                    alerts: events,
                    vehicle: vehicle_id(),
                })
            }
        };
        fanout.send_shared(report).await;
    }
    // The rest of the news (the vehicle's identity and the store's clock for the flight
    // log), the input being over.
    taken.take(&mut news, None, &mut energy, &mut flight).await;
    let pack = crate::vehicle::store::PackSig::of(&taken.params);
    (flight, taken.params.identity, pack)
}

/// The energy + alerts step for one estimate: energy bookkeeping, then the alert rules on
/// it, into the report every sink gets.
pub fn account(
    energy: &mut EnergyTracker,
    alerts: &mut AlertEngine,
    estimate: Estimate,
    vehicle: VehicleId,
) -> Report {
    // the momentum-theory member at the first hover's calibration, once made
    let estimate = energy.calibrated(estimate);
    let state = energy.update(&estimate);
    let events = alerts.evaluate(&estimate, &state);
    Report {
        estimate,
        energy: state,
        alerts: events,
        vehicle,
    }
}
