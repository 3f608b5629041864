//! One vehicle's chain: its stages (telemetry → windows, energy + alerts) built from the
//! configuration and run as tasks, and what the vehicle store tells and keeps of it.

use std::sync::Arc;

use anyhow::Result;
use tokio::sync::mpsc;
use tokio::task::JoinHandle;
use tokio::time::Instant;

use super::mission::{take_mission, Resolved};
use super::{
    relay, FleetEvent, Inference, Job, WarmStart, CHANNEL_DEPTH, HEALTH_EVERY, SILENT_TICK,
};
use crate::alert::AlertEngine;
use crate::config::Config;
use crate::energy::EnergyTracker;
use crate::mission::live::{LiveSetup, MissionStep};
use crate::model::Ensemble;
use crate::report::status::{ChainStatus, IngestStats};
use crate::report::{EnergyState, Estimate, MissionUpdate, Report, VehicleId};
use crate::sink::Fanout;
use crate::source::TimedMessage;
use crate::telemetry::window::Window;
use crate::telemetry::Telemetry;
use crate::vehicle::params::{Driver, Identity, ParamReader, VehicleParams};
use crate::vehicle::store::FlightLog;
use tokio::sync::oneshot;

/// One vehicle's chain: telemetry → windows → inference → energy + alerts, each stage's
/// state built from its own slice of the configuration.
pub struct VehicleChain {
    pub telemetry: Telemetry,
    pub models: Ensemble,
    pub energy: EnergyTracker,
    pub alerts: AlertEngine,
    /// The vehicle's live mission forecast (`crate::mission::live`), when there is a
    /// mission to follow: a step of its telemetry stage once the chain runs.
    pub mission: Option<LiveSetup>,
    /// Who the vehicle is and its battery parameters (listening only until
    /// [`VehicleChain::spawn`] runs it on a live link).
    pub vehicle: ParamReader,
    /// dronewatt's own MAVLink ids for the parameter requests (`[sinks.mavlink]`; no system
    /// id: the vehicle's own, as its companion computer).
    mav_ids: (Option<u8>, u8),
    /// The vehicle store's folder, for the warm start ([`VehicleChain::with_memory`]).
    memory: Option<std::path::PathBuf>,
    /// Builds the models from a profile `dronewatt learn` kept for the vehicle in the
    /// store; None when the config names a vehicle profile (the config wins).
    rebuild: Option<Rebuild>,
    /// `[link] listen_only`: ask the vehicle nothing, even on a live link.
    listen_only: bool,
}

/// Builds the ensemble from a vehicle profile file.
pub type Rebuild = Arc<dyn Fn(&std::path::Path) -> Result<Ensemble> + Send + Sync>;

/// What the vehicle store tells the energy stage about a vehicle.
#[derive(Debug, Clone, Default)]
struct StoreNews {
    /// The pack's effective capacity learned on earlier flights, Wh, over how many.
    capacity: Option<(f64, usize)>,
    /// The forecast model of the learned profile the models now run from, and why.
    forecast: Option<(String, String)>,
    /// What the vehicle's last flight, and each identified pack's, left of its pack.
    pack: crate::battery::PackHistories,
    /// A replayed log's first stamp, Unix s (reports' times count from it): the flight's end
    /// on the log's clock for the store.
    log_origin_s: Option<f64>,
}

/// The running stages of one [`VehicleChain`].
pub struct ChainTasks {
    telemetry: JoinHandle<()>,
    windows: JoinHandle<()>,
    energy: JoinHandle<(FlightLog, Option<Identity>, crate::vehicle::store::PackSig)>,
    relay: JoinHandle<()>,
}

/// What a chain leaves when its input is over: what the vehicle store keeps (with the
/// adaptation's fits, which the shared inference stage holds: [`Inference::join`]).
pub struct ChainEnd {
    /// The vehicle, when its heartbeat was heard.
    pub identity: Option<Identity>,
    /// The pack it reported of itself (which tells vehicles with no uid apart).
    pub pack: crate::vehicle::store::PackSig,
    /// The run's reports, summed up.
    pub flight: FlightLog,
}

impl ChainTasks {
    /// Wait for every stage to drain and end (after its input closed).
    pub async fn join(self) -> Result<ChainEnd> {
        self.telemetry.await?;
        self.windows.await?;
        let (flight, identity, pack) = self.energy.await?;
        self.relay.await?;
        Ok(ChainEnd {
            identity,
            pack,
            flight,
        })
    }
}

/// What the telemetry stage tells the energy stage about the vehicle, stamped with the
/// source time (`t_s`) of the message it came from. The energy stage takes each when its
/// estimates reach that time: the log's own clock orders parameters and estimates, never
/// the threads' timing (a flat-out replay and one at ×10 give the same reports).
enum VehicleNews {
    /// What the vehicle said about itself so far (identity, parameters, pack).
    Params(f64, VehicleParams),
    /// The vehicle store's answer, looked up off the stage: the energy stage waits for it
    /// when its estimates reach this time (a dropped sender: nothing remembered).
    Store(f64, oneshot::Receiver<StoreNews>),
}

impl VehicleNews {
    fn t_s(&self) -> f64 {
        match self {
            VehicleNews::Params(t, _) | VehicleNews::Store(t, _) => *t,
        }
    }
}

impl VehicleChain {
    /// Build and check every stage (model cards matched, rules compiled) from the values
    /// read at start.
    pub fn build(cfg: &Config, resolved: &Resolved) -> Result<Self> {
        let models = crate::model::build_live_ensemble(
            &cfg.models,
            &resolved.vehicle,
            &cfg.telemetry,
            cfg.mission.payload_g,
        )?;
        Ok(Self {
            models,
            ..Self::another(cfg, resolved)?
        })
    }

    /// Another vehicle's chain on the same configuration: its own telemetry, energy and
    /// alert state, no models (the fleet's vehicles share one [`Inference`] stage).
    pub fn another(cfg: &Config, resolved: &Resolved) -> Result<Self> {
        let profile = &resolved.vehicle.profile;
        let mut energy = EnergyTracker::new(&cfg.energy, cfg.mission.speed_m_s)?;
        // The vehicle profile's forecast model (`learn` picks it), when it names one.
        if let Some((model, why)) = profile.forecast_default() {
            energy.set_default_model(&model, &why);
        }
        let rebuild = cfg.vehicle.is_none().then(|| {
            let (models, telemetry, payload_g) = (
                cfg.models.clone(),
                cfg.telemetry.clone(),
                cfg.mission.payload_g,
            );
            Arc::new(move |path: &std::path::Path| {
                let learned = crate::model::LoadedProfile::load(Some(path))?;
                crate::model::build_live_ensemble(&models, &learned, &telemetry, payload_g)
            }) as Rebuild
        });
        Ok(Self {
            telemetry: Telemetry::new(&cfg.telemetry, &cfg.mission)
                .with_class(profile.vehicle.class),
            models: Ensemble::new(Vec::new()),
            energy,
            alerts: AlertEngine::new(&cfg.alerts)?,
            mission: None,
            vehicle: ParamReader::passive(),
            mav_ids: (cfg.sinks.mavlink.system_id, cfg.sinks.mavlink.component_id),
            memory: None,
            rebuild,
            listen_only: cfg.link.listen_only,
        })
    }

    /// Remember the vehicle in the store in `dir` ([`crate::vehicle::store`]): once its
    /// identity is heard, what earlier flights taught the adaptation is looked up (on a
    /// blocking thread) and the models start from it.
    pub fn with_memory(mut self, dir: Option<std::path::PathBuf>) -> Self {
        self.memory = dir;
        self
    }

    /// Every message through every stage in order, on the calling thread: what offline work
    /// (eval, benchmarks) runs flat out. The same steps as the spawned stages, in one loop:
    /// the windows a message completes are estimated as one batch, each estimate then
    /// accounted ([`account`]). Reports are appended to `out`; `None` ends the input
    /// (flushes what the resampler holds).
    pub fn push(&mut self, m: Option<&TimedMessage>, out: &mut Vec<Report>) {
        let mut windows = Vec::new();
        match m {
            Some(m) => {
                self.vehicle.on_message(m);
                if self.vehicle.take_changed() {
                    self.energy.set_vehicle(self.vehicle.params());
                }
                self.telemetry.push(m, &mut windows)
            }
            None => self.telemetry.finish(&mut windows),
        }
        if windows.is_empty() {
            return;
        }
        let vehicle = VehicleId::single(self.telemetry.system_id().unwrap_or(1));
        for est in self.models.estimate(&windows) {
            out.push(account(&mut self.energy, &mut self.alerts, est, vehicle));
        }
    }

    /// Run the stages: messages in from `msgs`, windows to `inference` (the run's shared
    /// stage; this chain's own `models` are not used), reports out through `fanout`. `live`
    /// turns on the silent-link tick. The returned sender tells the chain's relay that the
    /// vehicle was lost or dropped.
    pub fn spawn(
        self,
        msgs: mpsc::Receiver<TimedMessage>,
        inference: &Inference,
        fanout: Fanout,
        status: &ChainStatus,
        live: bool,
    ) -> (mpsc::UnboundedSender<FleetEvent>, ChainTasks) {
        let (win_tx, mut win_rx) = mpsc::channel::<Window>(CHANNEL_DEPTH);
        let (est_tx, est_rx) = mpsc::channel::<Estimate>(CHANNEL_DEPTH);
        let (ev_tx, ev_rx) = mpsc::unbounded_channel();
        let jobs = inference.jobs.clone();
        let system_id = status.system_id.load(std::sync::atomic::Ordering::Relaxed);
        let vehicle = VehicleId {
            network: status.network,
            system_id,
        };
        let mut own = Fanout::default().gauged(status.stats.clone());
        let stats = status.stats.clone();
        let reports = own.subscribe();
        // On a live link the reader asks (and asks for the streams); replaying, or told
        // to listen only, it listens to what comes (a log's logged fetch).
        let asks = live && !self.listen_only;
        let reader = if asks {
            ParamReader::live()
        } else {
            self.vehicle
        };
        let driver = Driver::new(
            reader,
            status.link.clone(),
            self.mav_ids.0.unwrap_or(system_id),
            self.mav_ids.1,
        )
        .with_streams(asks);
        // Unbounded: the news is a handful of parameter sets and one store answer a flight.
        let (news_tx, news_rx) = mpsc::unbounded_channel();
        let rebuild = self.rebuild;
        // The vehicle's mission forecast: a step of its telemetry stage, its statuses to its
        // energy stage, its frames on its own network's links.
        let (mission, statuses) = self
            .mission
            .map(|setup| MissionStep::new(setup, status.link.clone()))
            .unzip();
        let memory = self.memory.map(|dir| Memory {
            dir,
            vehicle,
            warm: inference.warm.clone(),
            looked_up: false,
            rebuild,
            heard: None,
        });
        let tasks = ChainTasks {
            telemetry: tokio::spawn(telemetry_stage(
                self.telemetry,
                driver,
                mission,
                msgs,
                win_tx,
                news_tx,
                memory,
                status.clone(),
            )),
            windows: tokio::spawn(async move {
                while let Some(window) = win_rx.recv().await {
                    if jobs
                        .send(Job {
                            window,
                            vehicle,
                            reply: est_tx.clone(),
                        })
                        .await
                        .is_err()
                    {
                        return;
                    }
                    stats.queues.observe(&jobs);
                }
            }),
            energy: tokio::spawn(energy_stage(
                self.energy,
                self.alerts,
                est_rx,
                statuses,
                news_rx,
                own,
                status.clone(),
                live,
            )),
            relay: tokio::spawn(relay(reports, ev_rx, fanout, status.latency.clone())),
        };
        (ev_tx, tasks)
    }
}

/// The vehicle store's side of a run: where it is, and where what it remembers goes (the
/// fits to the inference stage, the pack's effective capacity to the energy stage).
struct Memory {
    dir: std::path::PathBuf,
    /// The vehicle (the inference stage's key for its adaptation).
    vehicle: VehicleId,
    warm: std::sync::mpsc::Sender<(VehicleId, WarmStart)>,
    /// Whether the one lookup was made.
    looked_up: bool,
    /// Builds the models from a learned profile the store keeps for the vehicle.
    rebuild: Option<Rebuild>,
    /// The vehicle's latest parameters and when its identity was first heard (s).
    heard: Option<(f64, crate::vehicle::params::VehicleParams)>,
}

/// The models built from the profile `learn` kept for the vehicle, and its forecast model
/// with the reason; nothing without one, without a builder (a profile is configured), or
/// when the profile does not load (a warning: the run goes on with the configured models).
fn learned_models(
    learned: &crate::vehicle::store::Learned,
    rebuild: Option<&Rebuild>,
) -> (Option<Box<Ensemble>>, Option<(String, String)>) {
    let (Some(p), Some(rebuild)) = (&learned.profile, rebuild) else {
        return (None, None);
    };
    match rebuild(&p.path) {
        Ok(models) => {
            tracing::info!(
                "vehicle store: the models start from the profile learned for this vehicle, {}",
                p.path.display()
            );
            let why = format!(
                "vehicle profile learned for this vehicle ({})",
                p.path.display()
            );
            (
                Some(Box::new(models)),
                p.forecast_model.clone().map(|m| (m, why)),
            )
        }
        Err(e) => {
            tracing::warn!("vehicle store: the profile learned for this vehicle does not load ({e:#}); the configured models run");
            (None, None)
        }
    }
}

/// What earlier flights of vehicle `id` taught, looked up once it is known (off the task
/// that calls; `Pending` goes first, so the windows after message time `t_s` find it). The
/// answer reaches the energy stage as news stamped `t_s` ([`VehicleNews::Store`]).
fn look_up(
    mem: &mut Memory,
    (id, sig): (Identity, crate::vehicle::store::PackSig),
    t_s: f64,
    status: &ChainStatus,
    news: &mpsc::UnboundedSender<VehicleNews>,
) {
    if mem.looked_up {
        return;
    }
    mem.looked_up = true;
    let _ = mem.warm.send((mem.vehicle, WarmStart::Pending));
    let (answer_tx, answer_rx) = oneshot::channel();
    let _ = news.send(VehicleNews::Store(t_s, answer_rx));
    let (dir, warm, vehicle, rebuild) = (
        mem.dir.clone(),
        mem.warm.clone(),
        mem.vehicle,
        mem.rebuild.clone(),
    );
    // a replayed log's clock: its first stamp + the time since
    let origin = status.stats.log_origin_s();
    let now_log_s = origin.map(|o| o + t_s);
    tokio::task::spawn_blocking(move || {
        let learned = crate::vehicle::store::lookup(&dir, &id, &sig, now_log_s);
        // The profile `learn` kept for it (no profile configured).
        let (models, forecast) = learned_models(&learned, rebuild.as_ref());
        // The store's news first: an estimate made with the warm
        // fits reaches the energy stage after it.
        let _ = answer_tx.send(StoreNews {
            capacity: learned.capacity_wh,
            forecast,
            pack: learned.pack,
            log_origin_s: origin,
        });
        let _ = warm.send((vehicle, WarmStart::Ready(learned.fits, models)));
    });
}

/// Messages → fixed-rate samples → windows; refreshes the signal health about once a second.
/// Reads the vehicle beside ([`Driver`]: asks on a live link) and publishes what it learns;
/// runs the vehicle's mission forecast ([`MissionStep`]) on the same messages, first.
#[allow(clippy::too_many_arguments)] // a stage: its state, its channels in and out
async fn telemetry_stage(
    mut telemetry: Telemetry,
    mut vehicle: Driver,
    mut mission: Option<MissionStep>,
    mut msgs: mpsc::Receiver<TimedMessage>,
    windows: mpsc::Sender<Window>,
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
            Some(Some(m)) => {
                if let Some(step) = mission.as_mut() {
                    step.on_message(&m);
                }
                if let Some(params) = vehicle.on_message(&m) {
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
                telemetry.push(&m, &mut out);
                // The windows this message completes: it is the newest that went in.
                out.iter_mut().for_each(|w| w.arrived = Some(m.arrived));
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
            if windows.send(w).await.is_err() {
                return;
            }
            status.stats.queues.observe(&windows);
        }
    }
}

/// What the energy stage has taken of the vehicle's news ([`VehicleNews`]).
#[derive(Default)]
struct Taken {
    /// The vehicle's last word taken (its identity goes to the store at the end).
    params: VehicleParams,
    /// The store's pack histories and the pack flying (BATTERY_INFO): the carry-over is
    /// picked again when either changes ([`crate::battery::PackHistories::pick`]).
    packs: crate::battery::PackHistories,
    pack_id: Option<String>,
    /// The news read and not yet due.
    next: Option<VehicleNews>,
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
async fn energy_stage(
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
    // The last real estimate, its energy, and when it came: the base of a silent tick.
    let mut last: Option<(Estimate, EnergyState, Instant)> = None;
    let mut next_mission: Option<MissionUpdate> = None;
    let mut taken = Taken::default();
    loop {
        let next = if live {
            tokio::time::timeout(SILENT_TICK, estimates.recv()).await
        } else {
            Ok(estimates.recv().await)
        };
        let report = match next {
            Ok(Some(est)) => {
                // What the vehicle said up to this estimate's time, and no later.
                taken
                    .take(&mut news, Some(est.t_s), &mut energy, &mut flight)
                    .await;
                take_mission(&mut energy, &mut mission, &mut next_mission, est.t_s);
                let report = account(&mut energy, &mut alerts, est, vehicle_id());
                flight.observe(&report);
                for m in stuck.observe(&report.estimate) {
                    tracing::warn!(vehicle = %report.vehicle, "{m}");
                }
                if live {
                    last = Some((
                        report.estimate.clone(),
                        report.energy.clone(),
                        Instant::now(),
                    ));
                }
                report
            }
            Ok(None) => break,
            Err(_silence) => {
                let Some((est, state, at)) = &last else {
                    continue;
                };
                let quiet = est.silent(est.t_s + at.elapsed().as_secs_f64());
                let events = alerts.evaluate(&quiet, state);
                if events.is_empty() {
                    continue;
                }
                Report {
                    estimate: quiet,
                    energy: state.clone(),
                    alerts: events,
                    vehicle: vehicle_id(),
                }
            }
        };
        fanout.send(report).await;
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
    let state = energy.update(&estimate);
    let events = alerts.evaluate(&estimate, &state);
    Report {
        estimate,
        energy: state,
        alerts: events,
        vehicle,
    }
}
