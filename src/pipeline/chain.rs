//! One vehicle's chain: its stages (telemetry → windows, energy + alerts) built from the
//! configuration and run as tasks, and what the vehicle store tells and keeps of it.

use std::sync::Arc;

use anyhow::Result;
use tokio::sync::mpsc;
use tokio::task::JoinHandle;
use tokio::time::Instant;

use super::{
    relay, FleetEvent, Inference, Job, WarmStart, CHANNEL_DEPTH, HEALTH_EVERY, SILENT_TICK,
};
use crate::alert::AlertEngine;
use crate::config::Config;
use crate::energy::EnergyTracker;
use crate::model::Ensemble;
use crate::report::status::{ChainStatus, IngestStats};
use crate::report::{EnergyState, Estimate, MissionUpdate, Report, VehicleId};
use crate::sink::Fanout;
use crate::source::{SourceSpec, TimedMessage};
use crate::telemetry::window::Window;
use crate::telemetry::Telemetry;
use crate::vehicle::params::{Driver, Identity, ParamReader, VehicleParams};
use crate::vehicle::store::FlightLog;
use tokio::sync::watch;

/// One vehicle's chain: telemetry → windows → inference → energy + alerts, each stage's
/// state built from its own slice of the configuration.
pub struct VehicleChain {
    pub telemetry: Telemetry,
    pub models: Ensemble,
    pub energy: EnergyTracker,
    pub alerts: AlertEngine,
    /// The live mission forecast's statuses, in source-time order (`crate::mission::live`),
    /// when a mission tap runs.
    pub mission: Option<mpsc::Receiver<MissionUpdate>>,
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
    energy: JoinHandle<(FlightLog, Option<Identity>)>,
    relay: JoinHandle<()>,
}

/// What a chain leaves when its input is over: what the vehicle store keeps (with the
/// adaptation's fits, which the shared inference stage holds: [`Inference::join`]).
pub struct ChainEnd {
    /// The vehicle, when its heartbeat was heard.
    pub identity: Option<Identity>,
    /// The run's reports, summed up.
    pub flight: FlightLog,
}

impl ChainTasks {
    /// Wait for every stage to drain and end (after its input closed).
    pub async fn join(self) -> Result<ChainEnd> {
        self.telemetry.await?;
        self.windows.await?;
        let (flight, identity) = self.energy.await?;
        self.relay.await?;
        Ok(ChainEnd { identity, flight })
    }
}

impl VehicleChain {
    /// Build and check every stage (profiles loaded, model cards matched, rules compiled).
    pub fn build(cfg: &Config) -> Result<Self> {
        let models = crate::model::build_live_ensemble(
            &cfg.models,
            cfg.vehicle.as_deref(),
            &cfg.telemetry,
            cfg.mission.payload_g,
        )?;
        Ok(Self {
            models,
            ..Self::another(cfg)?
        })
    }

    /// Another vehicle's chain on the same configuration: its own telemetry, energy and
    /// alert state, no models (the fleet's vehicles share one [`Inference`] stage).
    pub fn another(cfg: &Config) -> Result<Self> {
        let mut energy = EnergyTracker::new(&cfg.energy, cfg.mission.speed_m_s)?;
        // The vehicle profile's forecast model (`learn` picks it), when it names one.
        if let Some((model, why)) = crate::model::profile::forecast_default(cfg.vehicle.as_deref())
        {
            energy.set_default_model(&model, &why);
        }
        let rebuild = cfg.vehicle.is_none().then(|| {
            let (models, telemetry, payload_g) = (
                cfg.models.clone(),
                cfg.telemetry.clone(),
                cfg.mission.payload_g,
            );
            Arc::new(move |path: &std::path::Path| {
                crate::model::build_live_ensemble(&models, Some(path), &telemetry, payload_g)
            }) as Rebuild
        });
        Ok(Self {
            telemetry: Telemetry::new(&cfg.telemetry, &cfg.mission).with_class(
                crate::model::profile::class_override(cfg.vehicle.as_deref()),
            ),
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
        let (vehicle_tx, vehicle_rx) = watch::channel(VehicleParams::default());
        let (capacity_tx, capacity_rx) = watch::channel(StoreNews::default());
        let rebuild = self.rebuild;
        let memory = self.memory.map(|dir| Memory {
            dir,
            vehicle,
            warm: inference.warm.clone(),
            capacity: Some(capacity_tx),
            rebuild,
        });
        let tasks = ChainTasks {
            telemetry: tokio::spawn(telemetry_stage(
                self.telemetry,
                driver,
                msgs,
                win_tx,
                vehicle_tx,
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
                self.mission,
                vehicle_rx,
                capacity_rx,
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
    /// Taken by the one lookup.
    capacity: Option<watch::Sender<StoreNews>>,
    /// Builds the models from a learned profile the store keeps for the vehicle.
    rebuild: Option<Rebuild>,
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

/// Messages → fixed-rate samples → windows; refreshes the signal health about once a second.
/// Reads the vehicle beside ([`Driver`]: asks on a live link) and publishes what it learns.
async fn telemetry_stage(
    mut telemetry: Telemetry,
    mut vehicle: Driver,
    mut msgs: mpsc::Receiver<TimedMessage>,
    windows: mpsc::Sender<Window>,
    vehicle_tx: watch::Sender<VehicleParams>,
    mut memory: Option<Memory>,
    status: ChainStatus,
) {
    let mut out = Vec::new();
    let mut shown = Instant::now();
    let mut open = true;
    while open {
        match msgs.recv().await {
            Some(m) => {
                if let Some(params) = vehicle.on_message(&m) {
                    // The vehicle is known: look up what earlier flights taught (off this task;
                    // `Pending` goes first, so the windows after this message find it).
                    if let (Some(id), Some(mem)) = (&params.identity, &mut memory) {
                        if let Some(capacity) = mem.capacity.take() {
                            let _ = mem.warm.send((mem.vehicle, WarmStart::Pending));
                            let (dir, warm, id, vehicle, rebuild) = (
                                mem.dir.clone(),
                                mem.warm.clone(),
                                id.clone(),
                                mem.vehicle,
                                mem.rebuild.clone(),
                            );
                            // a replayed log's clock: its first stamp + the time since
                            let origin = status.stats.log_origin_s();
                            let now_log_s = origin.map(|o| o + m.t_s);
                            tokio::task::spawn_blocking(move || {
                                let learned = crate::vehicle::store::lookup(&dir, &id, now_log_s);
                                // The profile `learn` kept for it (no profile configured).
                                let (models, forecast) = learned_models(&learned, rebuild.as_ref());
                                // The store's news first: an estimate made with the warm
                                // fits reaches the energy stage after it.
                                let _ = capacity.send(StoreNews {
                                    capacity: learned.capacity_wh,
                                    forecast,
                                    pack: learned.pack,
                                    log_origin_s: origin,
                                });
                                let _ =
                                    warm.send((vehicle, WarmStart::Ready(learned.fits, models)));
                            });
                        }
                    }
                    // Only the energy stage listens; it gone (shutting down) is no error.
                    let _ = vehicle_tx.send(params);
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
            None => {
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
    mut vehicle: watch::Receiver<VehicleParams>,
    mut learned: watch::Receiver<StoreNews>,
    mut fanout: Fanout,
    status: ChainStatus,
    live: bool,
) -> (FlightLog, Option<Identity>) {
    let mut flight = FlightLog::default();
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
    // Whether the vehicle's last word (its sender gone: the telemetry stage done) was taken.
    let mut vehicle_final = false;
    let mut capacity_final = false;
    // The store's pack histories and the pack flying (BATTERY_INFO): the carry-over is
    // picked again when either changes ([`crate::battery::PackHistories::pick`]).
    let mut packs = crate::battery::PackHistories::default();
    let mut pack_id: Option<String> = None;
    loop {
        let next = if live {
            tokio::time::timeout(SILENT_TICK, estimates.recv()).await
        } else {
            Ok(estimates.recv().await)
        };
        // Capacity and cells from the vehicle where the config is silent. A closed channel (a
        // fast replay whose telemetry stage is done) still holds the last word: take it once.
        let (changed, closed) = vehicle.has_changed().map_or((true, true), |c| (c, false));
        let mut repick = false;
        if changed && !vehicle_final {
            let params = vehicle.borrow_and_update().clone();
            if params.pack_id.is_some() && params.pack_id != pack_id {
                pack_id.clone_from(&params.pack_id);
                flight.set_pack_id(pack_id.clone());
                repick = true;
            }
            energy.set_vehicle(params);
            vehicle_final = closed;
        }
        // The pack's effective capacity from earlier flights (the vehicle store), and the
        // forecast model of a learned profile the models now run from, likewise.
        let (changed, closed) = learned.has_changed().map_or((true, true), |c| (c, false));
        if changed && !capacity_final {
            let news = learned.borrow_and_update().clone();
            energy.set_learned_capacity(news.capacity);
            packs = news.pack;
            repick = true;
            flight.set_log_origin(news.log_origin_s);
            if let Some((model, why)) = news.forecast {
                energy.set_default_model(&model, &why);
            }
            capacity_final = closed;
        }
        if repick {
            energy.set_pack_history(packs.pick(pack_id.as_deref()));
        }
        let report = match next {
            Ok(Some(est)) => {
                take_mission(&mut energy, &mut mission, &mut next_mission, est.t_s);
                let report = account(&mut energy, &mut alerts, est, vehicle_id());
                flight.observe(&report);
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
    let identity = vehicle.borrow().identity.clone();
    (flight, identity)
}

/// The mission statuses due by source time `t_s` into the energy tracker (the latest one
/// wins): the tap runs ahead of the estimates, so each status waits for its time.
fn take_mission(
    energy: &mut EnergyTracker,
    rx: &mut Option<mpsc::Receiver<MissionUpdate>>,
    next: &mut Option<MissionUpdate>,
    t_s: f64,
) {
    let Some(rx) = rx else { return };
    loop {
        if next.is_none() {
            *next = rx.try_recv().ok();
        }
        match next.take() {
            Some(m) if m.t_s <= t_s => energy.set_mission(m.status),
            other => {
                *next = other;
                return;
            }
        }
    }
}

/// What the live mission forecast needs, when the source can carry a mission (a live
/// link, a `.tlog` or raw log; not the data set) and `[forecast.live] enabled`.
pub(super) fn mission_setup(
    cfg: &Config,
    source: &SourceSpec,
    follows: &crate::source::fleet::VehicleFilter,
) -> Result<Option<crate::mission::live::LiveSetup>> {
    if !cfg.forecast.live.enabled || matches!(source, SourceSpec::Dataset { .. }) {
        return Ok(None);
    }
    let vehicle = match cfg.vehicle.as_deref() {
        Some(p) => crate::model::profile::VehicleProfile::load(p)?,
        None => crate::model::profile::VehicleProfile::m100(),
    };
    let mut models = crate::model::physics::models(&vehicle);
    // a plane's and a VTOL's wing-borne samples (only run where the class asks for it)
    let wing = vehicle.fixed_wing.unwrap_or_default();
    wing.validate().map_err(anyhow::Error::msg)?;
    models.push(Box::new(crate::model::physics::fixed_wing::FixedWing::new(
        wing,
    )));
    if let Some(p) = &cfg.forecast.live.calibrated_profile {
        models.extend(crate::model::physics::models(
            &crate::model::profile::VehicleProfile::load(p)?,
        ));
    }
    Ok(Some(crate::mission::live::LiveSetup {
        forecast: cfg.forecast.clone(),
        models,
        rate_hz: cfg.telemetry.rate_hz,
        window: cfg.telemetry.window,
        payload_g: cfg.mission.payload_g.map_or(0.0, f64::from),
        speed_m_s: cfg.mission.speed_m_s.map(f64::from),
        active: matches!(source, SourceSpec::Link(_) | SourceSpec::Links { .. }),
        // Requests go out as the configured id, else as the vehicle's companion computer.
        system_id: cfg.sinks.mavlink.system_id,
        component_id: cfg.sinks.mavlink.component_id,
        follows: follows.clone(),
        class: vehicle.vehicle.class,
        flight: vehicle.fixed_wing_flight.unwrap_or_default(),
    }))
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
