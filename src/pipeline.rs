//! One vehicle's chain as named stages, the run that feeds it from a source and fans its
//! reports out to the sinks, and shutdown.
//!
//! ```text
//! source ─TimedMessage→ telemetry_stage ─Window→ inference_stage ─Estimate→ energy_stage ─Report→ Fanout → one task per sink
//!                          └──── VehicleParams (watch: the latest word only) ────▶┘
//! ```
//!
//! The telemetry stage also reads the vehicle ([`crate::vehicle::params`]): on a live link it
//! asks for the battery parameters (PARAM_REQUEST_READ on the link, resent, bounded), in a
//! replay it takes the logged PARAM_VALUEs; what it learns reaches the energy stage on a
//! `tokio::sync::watch` (only the newest value matters, and it never holds a stage back).
//!
//! Every arrow is a bounded channel carrying one typed value; a full channel holds the
//! stage before it back, so a flat-out replay loses nothing. [`VehicleChain`] is one
//! vehicle's state (telemetry, models, energy, alert rules), built and checked before
//! anything listens; [`VehicleChain::spawn`] runs its stages. What the chain says about
//! itself beside the reports (counters, signal health, the uplink, the stop signal) is one
//! [`ChainStatus`] every sink gets.
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
use crate::model::Ensemble;
use crate::report::{EnergyState, Estimate, Report};
use crate::sink::mavlink::MavlinkSinkConfig;
use crate::sink::{Fanout, SinkSpec};
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
    let chain = VehicleChain::build(&p.config)?;
    // The signing key is read now: a missing or world-readable key fails before we listen.
    let signing = p.config.link.load().map_err(anyhow::Error::msg)?.map(|s| Arc::new(LinkSigning::new(s)));
    let signer = signing.clone().map(|s| s as Arc<dyn crate::status::FrameSigner>);
    let status = ChainStatus { shutdown: shutdown.clone(), link: LinkHandle::with_signer(signer), ..ChainStatus::default() };

    // Sinks start first so they see every report.
    let (fanout, sinks) = start_sinks(p.sinks, &status)?;

    let live = matches!(p.source, SourceSpec::Link(_));
    let (msg_tx, msg_rx) = mpsc::channel::<TimedMessage>(CHANNEL_DEPTH);
    let source = tokio::spawn(crate::source::run(p.source, msg_tx, status.stats.clone(), status.link.clone(), signing, shutdown));
    let chain = chain.with_memory(p.data_dir.clone()).spawn(msg_rx, fanout, &status, live);

    let source_result = source.await?;
    let end = chain.join().await?;
    // The flight is over: remember the vehicle, off the reactor (a slow or locked database
    // delays nothing but this write, and a failure is a warning).
    if let Some(dir) = p.data_dir {
        tokio::task::spawn_blocking(move || crate::vehicle::store::remember(&dir, end.identity.as_ref(), end.fits.as_deref(), &end.flight)).await?;
    }
    sinks.join().await?;
    source_result?;
    Ok(status.stats.snapshot())
}

/// Start every sink: each gets its own queue on the returned [`Fanout`] and the chain's
/// status. A MAVLink sink with an `address` of its own writes through an uplink opened
/// here (the same transports as the monitored link, `source::link`). Fails before anything
/// runs when a sink cannot start.
pub fn start_sinks(specs: Vec<SinkSpec>, status: &ChainStatus) -> Result<(Fanout, SinkTasks)> {
    let mut fanout = Fanout::default();
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
    /// Who the vehicle is and its battery parameters (listening only until
    /// [`VehicleChain::spawn`] runs it on a live link).
    pub vehicle: ParamReader,
    /// dronewatt's own MAVLink ids, for the parameter requests (`[sinks.mavlink]`).
    mav_ids: (u8, u8),
    /// The vehicle store's folder, for the warm start ([`VehicleChain::with_memory`]).
    memory: Option<std::path::PathBuf>,
}

/// The running stages of one [`VehicleChain`].
pub struct ChainTasks {
    telemetry: JoinHandle<()>,
    inference: JoinHandle<Option<Fits>>,
    energy: JoinHandle<(FlightLog, Option<Identity>)>,
}

/// What a chain leaves when its input is over: what the vehicle store keeps.
pub struct ChainEnd {
    /// The vehicle, when its heartbeat was heard.
    pub identity: Option<Identity>,
    /// Every model's adaptation fits at the end (adaptation on).
    pub fits: Option<Fits>,
    /// The run's reports, summed up.
    pub flight: FlightLog,
}

impl ChainTasks {
    /// Wait for every stage to drain and end (after its input closed).
    pub async fn join(self) -> Result<ChainEnd> {
        self.telemetry.await?;
        let fits = self.inference.await?;
        let (flight, identity) = self.energy.await?;
        Ok(ChainEnd { identity, fits, flight })
    }
}

impl VehicleChain {
    /// Build and check every stage (profiles loaded, model cards matched, rules compiled).
    pub fn build(cfg: &Config) -> Result<Self> {
        Ok(Self {
            telemetry: Telemetry::new(&cfg.telemetry, &cfg.mission),
            models: crate::model::build_ensemble(&cfg.models, cfg.vehicle.as_deref(), &cfg.telemetry, cfg.mission.payload_g)?,
            energy: EnergyTracker::new(&cfg.energy, cfg.mission.speed_m_s)?,
            alerts: AlertEngine::new(&cfg.alerts)?,
            vehicle: ParamReader::passive(),
            mav_ids: (cfg.sinks.mavlink.system_id, cfg.sinks.mavlink.component_id),
            memory: None,
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

    /// Run the stages: messages in from `msgs`, reports out through `fanout`. `live` turns
    /// on the silent-link tick.
    pub fn spawn(self, msgs: mpsc::Receiver<TimedMessage>, fanout: Fanout, status: &ChainStatus, live: bool) -> ChainTasks {
        let (win_tx, win_rx) = mpsc::channel::<Window>(CHANNEL_DEPTH);
        let (est_tx, est_rx) = mpsc::channel::<Estimate>(CHANNEL_DEPTH);
        // On a live link the reader asks; replaying, it listens to the logged fetch.
        let reader = if live { ParamReader::live() } else { self.vehicle };
        let driver = Driver::new(reader, status.link.clone(), self.mav_ids.0, self.mav_ids.1);
        let (vehicle_tx, vehicle_rx) = watch::channel(VehicleParams::default());
        let (warm_tx, warm_rx) = std::sync::mpsc::channel();
        let (capacity_tx, capacity_rx) = watch::channel(None);
        let memory = self.memory.map(|dir| Memory { dir, warm: warm_tx, capacity: Some(capacity_tx) });
        ChainTasks {
            telemetry: tokio::spawn(telemetry_stage(self.telemetry, driver, msgs, win_tx, vehicle_tx, memory, status.clone())),
            // Model work is CPU-bound: one dedicated thread for the whole run, off the reactor.
            inference: tokio::task::spawn_blocking(move || inference_stage(self.models, win_rx, est_tx, warm_rx, live)),
            energy: tokio::spawn(energy_stage(self.energy, self.alerts, est_rx, vehicle_rx, capacity_rx, fanout, status.clone(), live)),
        }
    }
}

/// The vehicle store's side of a run: where it is, and where what it remembers goes (the
/// fits to the inference stage, the pack's effective capacity to the energy stage).
struct Memory {
    dir: std::path::PathBuf,
    warm: std::sync::mpsc::Sender<WarmStart>,
    /// Taken by the one lookup.
    capacity: Option<watch::Sender<Option<(f64, usize)>>>,
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
                            let _ = mem.warm.send(WarmStart::Pending);
                            let (dir, warm, id) = (mem.dir.clone(), mem.warm.clone(), id.clone());
                            tokio::task::spawn_blocking(move || {
                                let learned = crate::vehicle::store::lookup(&dir, &id);
                                // The capacity first: an estimate made with the warm fits
                                // reaches the energy stage after it.
                                let _ = capacity.send(learned.capacity_wh);
                                let _ = warm.send(WarmStart::Ready(learned.fits));
                            });
                        }
                    }
                    // Only the energy stage listens; it gone (shutting down) is no error.
                    let _ = vehicle_tx.send(params);
                }
                telemetry.push(&m, &mut out);
                if let Some(id) = telemetry.system_id() {
                    status.system_id.store(id, std::sync::atomic::Ordering::Relaxed);
                }
            }
            None => {
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
        }
    }
}

/// Windows → every model's estimate. Runs on one thread for the whole run, not one per
/// batch: libtorch's thread settings are per OS thread, and a fresh thread's defaults (an
/// intra-op team as wide as the machine) cost ~10 ms a window. Windows that queued up
/// meanwhile (a flat-out replay) run as one batch.
///
/// What earlier flights of the vehicle taught the adaptation arrives on `warm` once the
/// vehicle is known; a replay waits for it (at most [`WARM_WAIT`]) so a replay is
/// reproducible, a live link never waits. Returns the adaptation's fits at the end.
fn inference_stage(
    mut models: Ensemble,
    mut windows: mpsc::Receiver<Window>,
    estimates: mpsc::Sender<Estimate>,
    warm: std::sync::mpsc::Receiver<WarmStart>,
    live: bool,
) -> Option<Fits> {
    crate::model::pin_inference_thread();
    let mut batch = Vec::with_capacity(MAX_BATCH);
    // The vehicle is known and its fits are being looked up.
    let mut waiting = false;
    let fits = |models: &Ensemble| models.adaptation().map(|a| a.fits().to_vec());
    while let Some(w) = windows.blocking_recv() {
        for news in warm.try_iter() {
            waiting = warm_start(&mut models, news);
        }
        if waiting && !live {
            waiting = match warm.recv_timeout(WARM_WAIT) {
                Ok(news) => warm_start(&mut models, news),
                Err(_) => {
                    tracing::warn!("vehicle store: no answer in {WARM_WAIT:?}; the replay goes on without a warm start");
                    false
                }
            };
        }
        batch.push(w);
        while batch.len() < MAX_BATCH {
            match windows.try_recv() {
                Ok(w) => batch.push(w),
                Err(_) => break,
            }
        }
        for e in models.estimate(&batch) {
            if estimates.blocking_send(e).is_err() {
                return fits(&models);
            }
        }
        batch.clear();
    }
    fits(&models)
}

/// Take the warm start's news; whether the answer is still to come.
fn warm_start(models: &mut Ensemble, news: WarmStart) -> bool {
    match news {
        WarmStart::Pending => true,
        WarmStart::Ready(learned) => {
            if let (Some(l), Some(ad)) = (learned, models.adaptation_mut()) {
                let n = ad.restore(&l);
                tracing::info!("warm start: {n} model(s) start from what earlier flights of this vehicle taught");
            }
            false
        }
    }
}

/// Adaptation fits by model name (what the vehicle store keeps).
type Fits = Vec<(String, crate::model::adapt::ModelFit)>;

/// The warm start's news to the inference stage.
enum WarmStart {
    /// The vehicle is known and its fits are being looked up.
    Pending,
    /// What earlier flights taught (none: a new vehicle, or no store).
    Ready(Option<Fits>),
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
    mut vehicle: watch::Receiver<VehicleParams>,
    mut learned_capacity: watch::Receiver<Option<(f64, usize)>>,
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
        // The pack's effective capacity from earlier flights (the vehicle store), likewise.
        let (changed, closed) = learned_capacity.has_changed().map_or((true, true), |c| (c, false));
        if changed && !capacity_final {
            energy.set_learned_capacity(*learned_capacity.borrow_and_update());
            capacity_final = closed;
        }
        let report = match next {
            Ok(Some(est)) => {
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
