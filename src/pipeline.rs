//! One vehicle's chain as named stages, the demultiplexer that runs one chain per vehicle
//! of a link, the run that feeds them from a source and fans their reports out to the
//! sinks, and shutdown.
//!
//! ```text
//! source ─TimedMessage→ demux ─TimedMessage→ one chain per vehicle:
//!     telemetry_stage ─Window→ inference_stage (one for all vehicles) ─Estimate→ energy_stage ─Report→ relay ─Report→ Fanout → one task per sink
//!            └────────── VehicleParams (watch: the latest word only) ──────────▶┘
//! ```
//!
//! The telemetry stage also reads the vehicle ([`crate::vehicle::params`]): on a live link it
//! asks for the battery parameters (PARAM_REQUEST_READ on the link, resent, bounded), in a
//! replay it takes the logged PARAM_VALUEs; what it learns reaches the energy stage on a
//! `tokio::sync::watch` (only the newest value matters, and it never holds a stage back).
//!
//! Every arrow is a bounded channel carrying one typed value; a full channel holds the
//! stage before it back, so a flat-out replay loses nothing. The demultiplexer
//! ([`crate::fleet::Demux`]) starts a [`VehicleChain`] for each vehicle it hears, ends it when
//! the vehicle is dropped, and tells the vehicle's relay when it is lost (the relay then
//! reports the `vehicle_lost` / `vehicle_dropped` alert after the vehicle's last report).
//! [`VehicleChain`] is one vehicle's state (telemetry, models, energy, alert rules), built
//! and checked before anything listens; [`VehicleChain::spawn`] runs its stages. The models
//! run once for the fleet ([`Inference`]): each window goes with the channel its estimate
//! goes back on. What the chain says about itself beside the reports (counters, signal
//! health, the uplink, the stop signal) is one [`ChainStatus`] every sink gets.
//!
//! Shutdown is one path whatever starts it (Ctrl-C or SIGTERM through
//! [`shutdown_on_signal`], the end of a replay, a fatal source error): the source stops and
//! drops its sender, each stage drains what it holds and drops its own, and every sink
//! sees its queue close, flushes and writes its summary. Nothing is lost on the way out.

use std::sync::Arc;

use anyhow::Result;
use tokio::sync::mpsc;
use tokio::task::JoinHandle;
use tokio::time::Instant;
use tokio_util::sync::CancellationToken;

use crate::alert::AlertEngine;
use crate::config::Config;
use crate::energy::EnergyTracker;
use crate::fleet::{Demux, FleetEvent, Route};
use crate::model::Ensemble;
use crate::report::{AlertEvent, AlertState, EnergyState, Estimate, MissionUpdate, Report, Severity};
use crate::sink::mavlink::MavlinkSinkConfig;
use crate::sink::{Fanout, ReportRx, SinkSpec};
use crate::source::{LinkSigning, SourceSpec, TimedMessage};
use crate::status::{ChainStatus, IngestStats, LinkHandle, StatsSnapshot};
use crate::telemetry::Telemetry;
use crate::vehicle::params::{Driver, Identity, ParamReader, VehicleParams};
use crate::vehicle::store::FlightLog;
use crate::window::Window;
use tokio::sync::watch;

/// Channel depth between stages. Deep enough to ride out a slow model for a few seconds
/// at 10 Hz; a flat-out replay simply waits on the slowest stage (back-pressure).
pub const CHANNEL_DEPTH: usize = 1024;
/// Most windows the inference stage runs as one batch when they queue up.
pub const MAX_BATCH: usize = 256;
/// On a live link, with no estimate for this long the alert rules are still evaluated, on
/// [`Estimate::silent`], so `telemetry_lost` fires when the link goes wholly silent.
pub const SILENT_TICK: std::time::Duration = std::time::Duration::from_secs(1);
/// How long the end of a run waits for an uplink to write what its sink queued last.
const UPLINK_FLUSH: std::time::Duration = std::time::Duration::from_secs(2);
/// How often the telemetry stage refreshes the signal health the terminal view shows.
const HEALTH_EVERY: std::time::Duration = std::time::Duration::from_secs(1);

/// Everything a run of the pipeline needs.
pub struct Pipeline {
    pub config: Config,
    pub source: SourceSpec,
    pub sinks: Vec<SinkSpec>,
    /// The vehicle store's folder ([`crate::vehicle::store`]); `None`: nothing remembered.
    pub data_dir: Option<std::path::PathBuf>,
}

/// Run the pipeline to the end of its source or until `shutdown` is cancelled. Returns the
/// ingest counters (the summary line's numbers).
pub async fn run(p: Pipeline, shutdown: CancellationToken) -> Result<StatsSnapshot> {
    // Built before any task starts, so a bad model or profile fails before we listen.
    let mut chain = VehicleChain::build(&p.config)?;
    let demux = Demux::new(&p.config.fleet, None).map_err(anyhow::Error::msg)?;
    // The signing key is read now: a missing or world-readable key fails before we listen.
    let signing = p.config.link.load().map_err(anyhow::Error::msg)?.map(|s| Arc::new(LinkSigning::new(s)));
    let signer = signing.clone().map(|s| s as Arc<dyn crate::status::FrameSigner>);
    let status = ChainStatus { shutdown: shutdown.clone(), link: LinkHandle::with_signer(signer), ..ChainStatus::default() };

    // Sinks start first so they see every report.
    let (fanout, sinks) = start_sinks(p.sinks, &status)?;

    let live = matches!(p.source, SourceSpec::Link(_));
    let mission = mission_setup(&p.config, &p.source, demux.filter())?;
    let (msg_tx, msg_rx) = mpsc::channel::<TimedMessage>(CHANNEL_DEPTH);
    let source = tokio::spawn(crate::source::run(p.source, msg_tx, status.stats.clone(), status.link.clone(), signing, shutdown));
    // The mission tap between the source and the demultiplexer, when there is a mission
    // to follow: it follows the vehicle it first hears, whose chain (the first) gets it.
    let (msg_rx, mission_task) = match mission {
        Some(setup) => {
            let (status_tx, status_rx) = mpsc::channel(crate::mission::live::STATUS_DEPTH);
            let (rx, task) = crate::mission::live::spawn(msg_rx, setup, status.link.clone(), status_tx);
            chain.mission = Some(status_rx);
            (rx, Some(task))
        }
        None => (msg_rx, None),
    };
    let inference = Inference::spawn(std::mem::replace(&mut chain.models, Ensemble::new(Vec::new())), Batching::from_config(&p.config), live, status.stats.clone());
    let fleet = Fleet { config: p.config, demux, first: Some(chain), inference, fanout, status: status.clone(), live, data_dir: p.data_dir };
    let demux = tokio::spawn(fleet.run(msg_rx));

    let source_result = source.await?;
    if let Some(t) = mission_task {
        t.await?;
    }
    demux.await??;
    sinks.join().await?;
    source_result?;
    Ok(status.stats.snapshot())
}

/// Start every sink: each gets its own queue on the returned [`Fanout`] and the chain's
/// status. A MAVLink sink with an `address` of its own writes through an uplink opened
/// here (the same transports as the monitored link, `source::link`). Fails before anything
/// runs when a sink cannot start.
pub fn start_sinks(specs: Vec<SinkSpec>, status: &ChainStatus) -> Result<(Fanout, SinkTasks)> {
    let mut fanout = Fanout::default().gauged(status.stats.clone());
    let mut tasks = SinkTasks { sinks: Vec::with_capacity(specs.len()), uplinks: Vec::new(), uplink_stop: status.shutdown.child_token() };
    for spec in specs {
        let mut sink_status = status.clone();
        if let SinkSpec::Mavlink(MavlinkSinkConfig { address: Some(a), .. }) = &spec {
            let (link, task) = crate::source::link::spawn_uplink(a.parse()?, &status.link, tasks.uplink_stop.clone());
            sink_status.link = link.clone();
            tasks.uplinks.push((link, task));
        }
        tasks.sinks.push(crate::sink::spawn(spec, fanout.subscribe(), sink_status)?);
    }
    Ok((fanout, tasks))
}

/// The running sinks (and the uplinks they write to).
pub struct SinkTasks {
    sinks: Vec<JoinHandle<Result<()>>>,
    uplinks: Vec<(LinkHandle, JoinHandle<Result<()>>)>,
    uplink_stop: CancellationToken,
}

impl SinkTasks {
    /// Wait for every sink to finish (after the [`Fanout`] was dropped), let the uplinks
    /// write what the sinks queued last (a final alert), then close them.
    pub async fn join(self) -> Result<()> {
        for t in self.sinks {
            t.await??;
        }
        for (link, _) in &self.uplinks {
            let flush_by = Instant::now() + UPLINK_FLUSH;
            while link.pending() > 0 && Instant::now() < flush_by {
                tokio::time::sleep(std::time::Duration::from_millis(5)).await;
            }
        }
        self.uplink_stop.cancel();
        for (_, t) in self.uplinks {
            t.await??;
        }
        Ok(())
    }
}

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

/// One window for the shared inference stage, whose it is, and where its estimate goes.
pub struct Job {
    pub window: Window,
    pub vehicle: u8,
    pub reply: mpsc::Sender<Estimate>,
}

/// How the shared inference stage batches (`[fleet] batch_wait_ms`, `lstm_rate_hz`).
#[derive(Debug, Clone, Copy)]
pub struct Batching {
    /// With more than one vehicle heard, the longest a window waits for others to join.
    pub wait: std::time::Duration,
    /// The heavy models (the LSTM) run on every `heavy_every`-th window of each vehicle.
    pub heavy_every: u64,
}

impl Batching {
    /// From the configuration: the wait, and the LSTM's period in windows.
    pub fn from_config(cfg: &Config) -> Self {
        let every = cfg.fleet.lstm_rate_hz.map_or(1.0, |r| (cfg.telemetry.rate_hz / r).round());
        Self { wait: std::time::Duration::from_secs_f64(cfg.fleet.batch_wait_ms / 1e3), heavy_every: (every as u64).max(1) }
    }
}

/// The inference stage every vehicle's chain sends its windows to: one for the whole run,
/// so the windows of all vehicles that queue up together run as one batch.
pub struct Inference {
    jobs: mpsc::Sender<Job>,
    /// What the vehicle store remembers of a vehicle, for its adaptation (by system id).
    warm: std::sync::mpsc::Sender<(u8, WarmStart)>,
    task: JoinHandle<std::collections::BTreeMap<u8, Fits>>,
}

impl Inference {
    /// Start the stage on its own thread with these models (on the tokio runtime it is
    /// called from). `live`: never wait for the vehicle store.
    pub fn spawn(models: Ensemble, batching: Batching, live: bool, stats: Arc<IngestStats>) -> Self {
        let (jobs, rx) = mpsc::channel::<Job>(CHANNEL_DEPTH);
        let (warm, warm_rx) = std::sync::mpsc::channel();
        let rt = tokio::runtime::Handle::current();
        // Model work is CPU-bound: one dedicated thread for the whole run, off the reactor.
        Self { jobs, warm, task: tokio::task::spawn_blocking(move || inference_stage(models, rx, batching, rt, warm_rx, live, stats)) }
    }
    /// Wait for it to drain and end, once every chain sending to it has ended; each
    /// vehicle's adaptation fits (adaptation on).
    pub async fn join(self) -> Result<std::collections::BTreeMap<u8, Fits>> {
        drop(self.jobs);
        drop(self.warm);
        Ok(self.task.await?)
    }
}

impl VehicleChain {
    /// Build and check every stage (profiles loaded, model cards matched, rules compiled).
    pub fn build(cfg: &Config) -> Result<Self> {
        let models = crate::model::build_ensemble(&cfg.models, cfg.vehicle.as_deref(), &cfg.telemetry, cfg.mission.payload_g)?;
        Ok(Self { models, ..Self::another(cfg)? })
    }

    /// Another vehicle's chain on the same configuration: its own telemetry, energy and
    /// alert state, no models (the fleet's vehicles share one [`Inference`] stage).
    pub fn another(cfg: &Config) -> Result<Self> {
        let mut energy = EnergyTracker::new(&cfg.energy, cfg.mission.speed_m_s)?;
        // The vehicle profile's forecast model (`learn` picks it), when it names one.
        if let Some((model, why)) = crate::model::profile::forecast_default(cfg.vehicle.as_deref()) {
            energy.set_default_model(&model, &why);
        }
        let rebuild = cfg.vehicle.is_none().then(|| {
            let (models, telemetry, payload_g) = (cfg.models.clone(), cfg.telemetry.clone(), cfg.mission.payload_g);
            Arc::new(move |path: &std::path::Path| crate::model::build_ensemble(&models, Some(path), &telemetry, payload_g)) as Rebuild
        });
        Ok(Self {
            telemetry: Telemetry::new(&cfg.telemetry, &cfg.mission),
            models: Ensemble::new(Vec::new()),
            energy,
            alerts: AlertEngine::new(&cfg.alerts)?,
            mission: None,
            vehicle: ParamReader::passive(),
            mav_ids: (cfg.sinks.mavlink.system_id, cfg.sinks.mavlink.component_id),
            memory: None,
            rebuild,
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
        let system_id = self.telemetry.system_id().unwrap_or(1);
        for est in self.models.estimate(&windows) {
            out.push(account(&mut self.energy, &mut self.alerts, est, system_id));
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
        let vehicle = status.system_id.load(std::sync::atomic::Ordering::Relaxed);
        let mut own = Fanout::default().gauged(status.stats.clone());
        let stats = status.stats.clone();
        let reports = own.subscribe();
        // On a live link the reader asks; replaying, it listens to the logged fetch.
        let reader = if live { ParamReader::live() } else { self.vehicle };
        let driver = Driver::new(reader, status.link.clone(), self.mav_ids.0.unwrap_or(vehicle), self.mav_ids.1);
        let (vehicle_tx, vehicle_rx) = watch::channel(VehicleParams::default());
        let (capacity_tx, capacity_rx) = watch::channel(StoreNews::default());
        let rebuild = self.rebuild;
        let memory = self.memory.map(|dir| Memory { dir, vehicle, warm: inference.warm.clone(), capacity: Some(capacity_tx), rebuild });
        let tasks = ChainTasks {
            telemetry: tokio::spawn(telemetry_stage(self.telemetry, driver, msgs, win_tx, vehicle_tx, memory, status.clone())),
            windows: tokio::spawn(async move {
                while let Some(window) = win_rx.recv().await {
                    if jobs.send(Job { window, vehicle, reply: est_tx.clone() }).await.is_err() {
                        return;
                    }
                    stats.queues.observe(&jobs);
                }
            }),
            energy: tokio::spawn(energy_stage(self.energy, self.alerts, est_rx, self.mission, vehicle_rx, capacity_rx, own, status.clone(), live)),
            relay: tokio::spawn(relay(reports, ev_rx, fanout, status.latency.clone())),
        };
        (ev_tx, tasks)
    }
}

/// The demultiplexer and what it starts chains with.
struct Fleet {
    config: Config,
    demux: Demux,
    /// The chain built (and checked) before the run: the first vehicle's.
    first: Option<VehicleChain>,
    inference: Inference,
    fanout: Fanout,
    status: ChainStatus,
    live: bool,
    /// The vehicle store's folder ([`crate::vehicle::store`]); `None`: nothing remembered.
    data_dir: Option<std::path::PathBuf>,
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
    async fn run(mut self, mut msgs: mpsc::Receiver<TimedMessage>) -> Result<()> {
        let mut chains: std::collections::HashMap<u8, Vehicle> = Default::default();
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
                                Err(e) => tracing::error!(vehicle = id, "cannot start a chain for this vehicle: {e:#}"),
                            }
                        }
                        if let Some(v) = chains.get(&id) {
                            if back {
                                tracing::info!(vehicle = id, "vehicle heard again");
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
                        tracing::warn!(vehicle = id, "vehicle lost: nothing heard for {silent_s:.1} s");
                        if let Some(v) = chains.get(&id) {
                            let _ = v.events.send(ev);
                        }
                    }
                    FleetEvent::Back { .. } => {}
                    FleetEvent::Dropped { id, silent_s, .. } => {
                        tracing::warn!(vehicle = id, "vehicle dropped: nothing heard for {silent_s:.1} s");
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
                tokio::task::spawn_blocking(move || crate::vehicle::store::remember(&dir, end.identity.as_ref(), fits.as_deref(), &end.flight)).await?;
            }
        }
        Ok(())
    }

    /// Start vehicle `id`'s chain: the chain built before the run for the first vehicle
    /// (it reports the signal health the terminal shows), a fresh one for the others.
    fn start(&mut self, id: u8) -> Result<Vehicle> {
        let (chain, mut status) = match self.first.take() {
            Some(c) => (c, self.status.clone()),
            None => (VehicleChain::another(&self.config)?, ChainStatus { health: Default::default(), ..self.status.clone() }),
        };
        status.system_id = Arc::new(std::sync::atomic::AtomicU8::new(id));
        tracing::info!(vehicle = id, "vehicle heard: following it");
        let (tx, rx) = mpsc::channel(CHANNEL_DEPTH);
        let chain = chain.with_memory(self.data_dir.clone());
        let (events, tasks) = chain.spawn(rx, &self.inference, self.fanout.clone(), &status, self.live);
        Ok(Vehicle { msgs: tx, events, tasks })
    }
}

/// One vehicle's reports on to every sink, and what the demultiplexer says about it in
/// between: lost (alert `vehicle_lost` raised; cleared when the vehicle is heard again) and dropped (alert `vehicle_dropped`, after the
/// vehicle's last report). Each is reported on the vehicle's last estimate and energy; a
/// vehicle that never produced a report has nothing to report it on (it is logged).
/// Each report's message → estimate latency is counted in `latency` as it goes to the sinks.
async fn relay(mut reports: ReportRx, mut events: mpsc::UnboundedReceiver<FleetEvent>, mut fanout: Fanout, latency: Arc<crate::status::LatencyHistogram>) {
    let mut last: Option<Arc<Report>> = None;
    let mut dropped = None;
    let mut open = true;
    let event = |last: &Option<Arc<Report>>, rule: &str, state, severity, t_s: f64, message: String| {
        last.as_ref().map(|r| Report {
            estimate: r.estimate.silent(t_s.max(r.estimate.t_s)),
            energy: r.energy.clone(),
            alerts: vec![AlertEvent { t: t_s, rule: rule.into(), severity, state, message }],
            system_id: r.system_id,
        })
    };
    loop {
        tokio::select! {
            biased;
            r = reports.next() => match r {
                Some(r) => {
                    if let Some(at) = r.estimate.arrived {
                        latency.record(at.elapsed());
                    }
                    last = Some(r.clone());
                    fanout.send_shared(r).await;
                }
                None => break,
            },
            e = events.recv(), if open => {
                let report = match e {
                    None => { open = false; None }
                    Some(FleetEvent::Lost { id, t_s, silent_s }) => {
                        event(&last, "vehicle_lost", AlertState::Raised, Severity::Warning, t_s, format!("vehicle {id}: nothing heard for {silent_s:.0} s"))
                    }
                    Some(FleetEvent::Back { id, t_s }) => {
                        event(&last, "vehicle_lost", AlertState::Cleared, Severity::Warning, t_s, format!("vehicle {id} heard again"))
                    }
                    Some(d @ FleetEvent::Dropped { .. }) => { dropped = Some(d); None }
                };
                if let Some(r) = report {
                    fanout.send(r).await;
                }
            }
        }
    }
    // The drop is told before the chain's input closes, so it is queued by now even if
    // the reports ended before the loop above read it.
    while let Ok(e) = events.try_recv() {
        if matches!(e, FleetEvent::Dropped { .. }) {
            dropped = Some(e);
        }
    }
    if let Some(FleetEvent::Dropped { id, t_s, silent_s }) = dropped {
        let msg = format!("vehicle {id} dropped: nothing heard for {silent_s:.0} s");
        if let Some(r) = event(&last, "vehicle_dropped", AlertState::Raised, Severity::Info, t_s, msg) {
            fanout.send(r).await;
        }
    }
}

/// The vehicle store's side of a run: where it is, and where what it remembers goes (the
/// fits to the inference stage, the pack's effective capacity to the energy stage).
struct Memory {
    dir: std::path::PathBuf,
    /// The vehicle's system id (the inference stage's key for its adaptation).
    vehicle: u8,
    warm: std::sync::mpsc::Sender<(u8, WarmStart)>,
    /// Taken by the one lookup.
    capacity: Option<watch::Sender<StoreNews>>,
    /// Builds the models from a learned profile the store keeps for the vehicle.
    rebuild: Option<Rebuild>,
}

/// The models built from the profile `learn` kept for the vehicle, and its forecast model
/// with the reason; nothing without one, without a builder (a profile is configured), or
/// when the profile does not load (a warning: the run goes on with the configured models).
fn learned_models(learned: &crate::vehicle::store::Learned, rebuild: Option<&Rebuild>) -> (Option<Box<Ensemble>>, Option<(String, String)>) {
    let (Some(p), Some(rebuild)) = (&learned.profile, rebuild) else { return (None, None) };
    match rebuild(&p.path) {
        Ok(models) => {
            tracing::info!("vehicle store: the models start from the profile learned for this vehicle, {}", p.path.display());
            let why = format!("vehicle profile learned for this vehicle ({})", p.path.display());
            (Some(Box::new(models)), p.forecast_model.clone().map(|m| (m, why)))
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
                            let (dir, warm, id, vehicle, rebuild) = (mem.dir.clone(), mem.warm.clone(), id.clone(), mem.vehicle, mem.rebuild.clone());
                            tokio::task::spawn_blocking(move || {
                                let learned = crate::vehicle::store::lookup(&dir, &id);
                                // The profile `learn` kept for it (no profile configured).
                                let (models, forecast) = learned_models(&learned, rebuild.as_ref());
                                // The store's news first: an estimate made with the warm
                                // fits reaches the energy stage after it.
                                let _ = capacity.send(StoreNews { capacity: learned.capacity_wh, forecast });
                                let _ = warm.send((vehicle, WarmStart::Ready(learned.fits, models)));
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
                    status.system_id.store(id, std::sync::atomic::Ordering::Relaxed);
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

/// Windows → every model's estimate, each sent back to the chain it came from. Runs on one
/// thread for the whole run, not one per batch: libtorch's thread settings are per OS
/// thread, and a fresh thread's defaults (an intra-op team as wide as the machine) cost
/// ~10 ms a window. Windows that queued up meanwhile (a flat-out replay, or every vehicle
/// of a fleet whose windows fell due together) run as one batch; once more than one
/// vehicle has been heard, a batch waits up to [`Batching::wait`] for more. The heavy
/// models (the LSTM) run on every [`Batching::heavy_every`]-th window of a vehicle; the
/// windows between carry that vehicle's latest heavy estimates.
///
/// Each vehicle adapts the models on its own ([`Ensemble::estimate_some`]). What earlier
/// flights of a vehicle taught its adaptation arrives on `warm` once the vehicle is known;
/// a replay waits for it (at most [`WARM_WAIT`]) so a replay is reproducible, a live link
/// never waits. Returns each vehicle's adaptation fits at the end.
fn inference_stage(
    mut models: Ensemble,
    mut jobs: mpsc::Receiver<Job>,
    batching: Batching,
    rt: tokio::runtime::Handle,
    warm: std::sync::mpsc::Receiver<(u8, WarmStart)>,
    live: bool,
    stats: Arc<IngestStats>,
) -> std::collections::BTreeMap<u8, Fits> {
    let heavy_names = models.heavy_names();
    let mut b = Batch::default();
    // Per vehicle: windows seen, and the heavy models' latest estimates.
    let mut seen: std::collections::HashMap<u8, (u64, Vec<crate::report::ModelEstimate>)> = Default::default();
    // Vehicles known whose fits are being looked up.
    let mut waiting = std::collections::BTreeSet::new();
    let mut vehicles = Vec::new();
    while let Some(j) = jobs.blocking_recv() {
        let deadline = tokio::time::Instant::now() + batching.wait;
        b.take(j, &mut seen, batching.heavy_every);
        let wait = seen.len() > 1 && !batching.wait.is_zero();
        while b.windows.len() < MAX_BATCH {
            match jobs.try_recv() {
                Ok(j) => b.take(j, &mut seen, batching.heavy_every),
                // Wait a little for the other vehicles' windows of this tick.
                Err(mpsc::error::TryRecvError::Empty) if wait => match rt.block_on(tokio::time::timeout_at(deadline, jobs.recv())) {
                    Ok(Some(j)) => b.take(j, &mut seen, batching.heavy_every),
                    _ => break,
                },
                Err(_) => break,
            }
        }
        for (id, news) in warm.try_iter() {
            warm_start(&mut models, id, news, &mut waiting, seen.len());
        }
        if !live {
            let until = std::time::Instant::now() + WARM_WAIT;
            while b.meta.iter().any(|(v, ..)| waiting.contains(v)) {
                match warm.recv_timeout(until.saturating_duration_since(std::time::Instant::now())) {
                    Ok((id, news)) => warm_start(&mut models, id, news, &mut waiting, seen.len()),
                    Err(_) => {
                        tracing::warn!("vehicle store: no answer in {WARM_WAIT:?}; the replay goes on without a warm start");
                        waiting.clear();
                    }
                }
            }
        }
        vehicles.clear();
        vehicles.extend(b.meta.iter().map(|(v, ..)| *v));
        let estimates = models.estimate_some(&b.windows, &b.heavy, &vehicles);
        for (mut e, (vehicle, full, reply)) in estimates.into_iter().zip(b.meta.drain(..)) {
            if let (true, Some((_, held))) = (batching.heavy_every > 1, seen.get_mut(&vehicle)) {
                if full {
                    *held = e.models.iter().filter(|m| heavy_names.contains(&m.name)).cloned().collect();
                } else {
                    e.models.extend(held.iter().cloned());
                }
            }
            // A vehicle dropped meanwhile no longer wants its estimate.
            let _ = reply.blocking_send(e);
            stats.queues.observe(&reply);
        }
        b.windows.clear();
        b.heavy.clear();
    }
    seen.keys().filter_map(|&id| Some((id, models.adaptation(id)?.fits().to_vec()))).collect()
}

/// The batch the inference stage is gathering: windows, whether the heavy models run on
/// each, and whose each is (vehicle, heavy, reply).
#[derive(Default)]
struct Batch {
    windows: Vec<Window>,
    heavy: Vec<bool>,
    meta: Vec<(u8, bool, mpsc::Sender<Estimate>)>,
}

impl Batch {
    fn take(&mut self, j: Job, seen: &mut std::collections::HashMap<u8, (u64, Vec<crate::report::ModelEstimate>)>, every: u64) {
        let n = &mut seen.entry(j.vehicle).or_default().0;
        let full = n.is_multiple_of(every);
        *n += 1;
        self.windows.push(j.window);
        self.heavy.push(full);
        self.meta.push((j.vehicle, full, j.reply));
    }
}

/// Take the warm start's news; whether the answer is still to come. `vehicles`: how many
/// vehicles the stage has heard (a learned profile's models replace the run's only while
/// one vehicle is: a fleet's vehicles share the models).
fn warm_start(models: &mut Ensemble, vehicle: u8, news: WarmStart, waiting: &mut std::collections::BTreeSet<u8>, vehicles: usize) {
    match news {
        WarmStart::Pending => {
            waiting.insert(vehicle);
        }
        WarmStart::Ready(learned, profile_models) => {
            waiting.remove(&vehicle);
            match profile_models {
                Some(m) if vehicles <= 1 => *models = *m,
                Some(_) => tracing::warn!(vehicle, "vehicle store: a learned profile is not applied in a fleet (the vehicles share the models)"),
                None => {}
            }
            if let (Some(l), Some(ad)) = (learned, models.adaptation_mut(vehicle)) {
                let n = ad.restore(&l);
                tracing::info!(vehicle, "warm start: {n} model(s) start from what earlier flights of this vehicle taught");
            }
        }
    }
}

/// Adaptation fits by model name (what the vehicle store keeps).
pub type Fits = Vec<(String, crate::model::adapt::ModelFit)>;

/// The warm start's news to the inference stage.
pub enum WarmStart {
    /// The vehicle is known and its fits are being looked up.
    Pending,
    /// What earlier flights taught (none: a new vehicle, or no store), and the models of the
    /// profile `learn` kept for the vehicle (none: none kept, or a profile is configured).
    Ready(Option<Fits>, Option<Box<Ensemble>>),
}

/// Longest a replay waits for the vehicle store's answer.
const WARM_WAIT: std::time::Duration = std::time::Duration::from_secs(3);

/// Estimates → energy bookkeeping and alert events → one [`Report`] each, to every sink.
/// On a live link, a silence of [`SILENT_TICK`] still runs the alert rules (on
/// [`Estimate::silent`]); such a tick reports only when a rule changes state, and leaves
/// the energy as it stood.
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
    let vehicle_id = || match status.system_id.load(std::sync::atomic::Ordering::Relaxed) {
        0 => 1,
        id => id,
    };
    // The last real estimate, its energy, and when it came: the base of a silent tick.
    let mut last: Option<(Estimate, EnergyState, Instant)> = None;
    let mut next_mission: Option<MissionUpdate> = None;
    // Whether the vehicle's last word (its sender gone: the telemetry stage done) was taken.
    let mut vehicle_final = false;
    let mut capacity_final = false;
    loop {
        let next = if live {
            tokio::time::timeout(SILENT_TICK, estimates.recv()).await
        } else {
            Ok(estimates.recv().await)
        };
        // Capacity and cells from the vehicle where the config is silent. A closed channel (a
        // fast replay whose telemetry stage is done) still holds the last word: take it once.
        let (changed, closed) = vehicle.has_changed().map_or((true, true), |c| (c, false));
        if changed && !vehicle_final {
            energy.set_vehicle(vehicle.borrow_and_update().clone());
            vehicle_final = closed;
        }
        // The pack's effective capacity from earlier flights (the vehicle store), and the
        // forecast model of a learned profile the models now run from, likewise.
        let (changed, closed) = learned.has_changed().map_or((true, true), |c| (c, false));
        if changed && !capacity_final {
            let news = learned.borrow_and_update().clone();
            energy.set_learned_capacity(news.capacity);
            if let Some((model, why)) = news.forecast {
                energy.set_default_model(&model, &why);
            }
            capacity_final = closed;
        }
        let report = match next {
            Ok(Some(est)) => {
                take_mission(&mut energy, &mut mission, &mut next_mission, est.t_s);
                let report = account(&mut energy, &mut alerts, est, vehicle_id());
                flight.observe(&report);
                if live {
                    last = Some((report.estimate.clone(), report.energy.clone(), Instant::now()));
                }
                report
            }
            Ok(None) => break,
            Err(_silence) => {
                let Some((est, state, at)) = &last else { continue };
                let quiet = est.silent(est.t_s + at.elapsed().as_secs_f64());
                let events = alerts.evaluate(&quiet, state);
                if events.is_empty() {
                    continue;
                }
                Report { estimate: quiet, energy: state.clone(), alerts: events, system_id: vehicle_id() }
            }
        };
        fanout.send(report).await;
    }
    let identity = vehicle.borrow().identity.clone();
    (flight, identity)
}

/// The mission statuses due by source time `t_s` into the energy tracker (the latest one
/// wins): the tap runs ahead of the estimates, so each status waits for its time.
fn take_mission(energy: &mut EnergyTracker, rx: &mut Option<mpsc::Receiver<MissionUpdate>>, next: &mut Option<MissionUpdate>, t_s: f64) {
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
fn mission_setup(cfg: &Config, source: &SourceSpec, follows: &crate::fleet::VehicleFilter) -> Result<Option<crate::mission::live::LiveSetup>> {
    if !cfg.forecast.live.enabled || matches!(source, SourceSpec::Dataset { .. }) {
        return Ok(None);
    }
    let vehicle = match cfg.vehicle.as_deref() {
        Some(p) => crate::model::profile::VehicleProfile::load(p)?,
        None => crate::model::profile::VehicleProfile::m100(),
    };
    let mut models = crate::model::physics::models(&vehicle);
    if let Some(p) = &cfg.forecast.live.calibrated_profile {
        models.extend(crate::model::physics::models(&crate::model::profile::VehicleProfile::load(p)?));
    }
    Ok(Some(crate::mission::live::LiveSetup {
        forecast: cfg.forecast.clone(),
        models,
        rate_hz: cfg.telemetry.rate_hz,
        window: cfg.telemetry.window,
        payload_g: cfg.mission.payload_g.map_or(0.0, f64::from),
        speed_m_s: cfg.mission.speed_m_s.map(f64::from),
        active: matches!(source, SourceSpec::Link(_)),
        // Requests go out as the configured id, else as the vehicle's companion computer.
        system_id: cfg.sinks.mavlink.system_id,
        component_id: cfg.sinks.mavlink.component_id,
        follows: follows.clone(),
    }))
}

/// The energy + alerts step for one estimate: energy bookkeeping, then the alert rules on
/// it, into the report every sink gets.
pub fn account(energy: &mut EnergyTracker, alerts: &mut AlertEngine, estimate: Estimate, system_id: u8) -> Report {
    let state = energy.update(&estimate);
    let events = alerts.evaluate(&estimate, &state);
    Report { estimate, energy: state, alerts: events, system_id }
}

/// A token cancelled on Ctrl-C (SIGINT) or SIGTERM: the run's one stop signal.
pub fn shutdown_on_signal() -> CancellationToken {
    let token = CancellationToken::new();
    let t = token.clone();
    tokio::spawn(async move {
        #[cfg(unix)]
        {
            use tokio::signal::unix::{signal, SignalKind};
            match signal(SignalKind::terminate()) {
                Ok(mut term) => tokio::select! {
                    _ = tokio::signal::ctrl_c() => {},
                    _ = term.recv() => {},
                },
                Err(_) => {
                    let _ = tokio::signal::ctrl_c().await;
                }
            }
        }
        #[cfg(not(unix))]
        let _ = tokio::signal::ctrl_c().await;
        tracing::info!("shutting down");
        t.cancel();
    });
    token
}
