//! One vehicle's chain as named stages, the run that feeds it from a source and fans its
//! reports out to the sinks, and shutdown.
//!
//! ```text
//! source ─TimedMessage→ telemetry_stage ─Window→ inference_stage ─Estimate→ energy_stage ─Report→ Fanout → one task per sink
//! ```
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
use crate::report::{EnergyState, Estimate, MissionUpdate, Report};
use crate::sink::mavlink::MavlinkSinkConfig;
use crate::sink::{Fanout, SinkSpec};
use crate::source::{LinkSigning, SourceSpec, TimedMessage};
use crate::status::{ChainStatus, IngestStats, LinkHandle, StatsSnapshot};
use crate::telemetry::Telemetry;
use crate::window::Window;

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
}

/// Run the pipeline to the end of its source or until `shutdown` is cancelled. Returns the
/// ingest counters (the summary line's numbers).
pub async fn run(p: Pipeline, shutdown: CancellationToken) -> Result<StatsSnapshot> {
    // Built before any task starts, so a bad model or profile fails before we listen.
    let mut chain = VehicleChain::build(&p.config)?;
    // The signing key is read now: a missing or world-readable key fails before we listen.
    let signing = p.config.link.load().map_err(anyhow::Error::msg)?.map(|s| Arc::new(LinkSigning::new(s)));
    let signer = signing.clone().map(|s| s as Arc<dyn crate::status::FrameSigner>);
    let status = ChainStatus { shutdown: shutdown.clone(), link: LinkHandle::with_signer(signer), ..ChainStatus::default() };

    // Sinks start first so they see every report.
    let (fanout, sinks) = start_sinks(p.sinks, &status)?;

    let live = matches!(p.source, SourceSpec::Link(_));
    let mission = mission_setup(&p.config, &p.source)?;
    let (msg_tx, msg_rx) = mpsc::channel::<TimedMessage>(CHANNEL_DEPTH);
    let source = tokio::spawn(crate::source::run(p.source, msg_tx, status.stats.clone(), status.link.clone(), signing, shutdown));
    // The mission tap between the source and the chain, when there is a mission to follow.
    let (msg_rx, mission_task) = match mission {
        Some(setup) => {
            let (status_tx, status_rx) = mpsc::channel(crate::mission::live::STATUS_DEPTH);
            let (rx, task) = crate::mission::live::spawn(msg_rx, setup, status.link.clone(), status_tx);
            chain.mission = Some(status_rx);
            (rx, Some(task))
        }
        None => (msg_rx, None),
    };
    let chain = chain.spawn(msg_rx, fanout, &status, live);

    let source_result = source.await?;
    if let Some(t) = mission_task {
        t.await?;
    }
    chain.join().await?;
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
    /// The live mission forecast's statuses, in source-time order (`crate::mission::live`),
    /// when a mission tap runs.
    pub mission: Option<mpsc::Receiver<MissionUpdate>>,
}

/// The running stages of one [`VehicleChain`].
pub struct ChainTasks {
    telemetry: JoinHandle<()>,
    inference: JoinHandle<()>,
    energy: JoinHandle<()>,
}

impl ChainTasks {
    /// Wait for every stage to drain and end (after its input closed).
    pub async fn join(self) -> Result<()> {
        self.telemetry.await?;
        self.inference.await?;
        self.energy.await?;
        Ok(())
    }
}

impl VehicleChain {
    /// Build and check every stage (profiles loaded, model cards matched, rules compiled).
    pub fn build(cfg: &Config) -> Result<Self> {
        Ok(Self {
            telemetry: Telemetry::new(&cfg.telemetry, &cfg.mission),
            models: crate::model::build_ensemble(&cfg.models, cfg.vehicle.as_deref(), &cfg.telemetry)?,
            energy: EnergyTracker::new(&cfg.energy, cfg.mission.speed_m_s)?,
            alerts: AlertEngine::new(&cfg.alerts)?,
            mission: None,
        })
    }

    /// Every message through every stage in order, on the calling thread: what offline work
    /// (eval, benchmarks) runs flat out. The same steps as the spawned stages, in one loop:
    /// the windows a message completes are estimated as one batch, each estimate then
    /// accounted ([`account`]). Reports are appended to `out`; `None` ends the input
    /// (flushes what the resampler holds).
    pub fn push(&mut self, m: Option<&TimedMessage>, out: &mut Vec<Report>) {
        let mut windows = Vec::new();
        match m {
            Some(m) => self.telemetry.push(m, &mut windows),
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
        ChainTasks {
            telemetry: tokio::spawn(telemetry_stage(self.telemetry, msgs, win_tx, status.clone())),
            // Model work is CPU-bound: one dedicated thread for the whole run, off the reactor.
            inference: tokio::task::spawn_blocking(move || inference_stage(self.models, win_rx, est_tx)),
            energy: tokio::spawn(energy_stage(self.energy, self.alerts, est_rx, self.mission, fanout, status.clone(), live)),
        }
    }
}

/// Messages → fixed-rate samples → windows; refreshes the signal health about once a second.
async fn telemetry_stage(
    mut telemetry: Telemetry,
    mut msgs: mpsc::Receiver<TimedMessage>,
    windows: mpsc::Sender<Window>,
    status: ChainStatus,
) {
    let mut out = Vec::new();
    let mut shown = Instant::now();
    let mut open = true;
    while open {
        match msgs.recv().await {
            Some(m) => {
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
fn inference_stage(mut models: Ensemble, mut windows: mpsc::Receiver<Window>, estimates: mpsc::Sender<Estimate>) {
    let mut batch = Vec::with_capacity(MAX_BATCH);
    while let Some(w) = windows.blocking_recv() {
        batch.push(w);
        while batch.len() < MAX_BATCH {
            match windows.try_recv() {
                Ok(w) => batch.push(w),
                Err(_) => break,
            }
        }
        for e in models.estimate(&batch) {
            if estimates.blocking_send(e).is_err() {
                return;
            }
        }
        batch.clear();
    }
}

/// Estimates → energy bookkeeping and alert events → one [`Report`] each, to every sink.
/// On a live link, a silence of [`SILENT_TICK`] still runs the alert rules (on
/// [`Estimate::silent`]); such a tick reports only when a rule changes state, and leaves
/// the energy as it stood.
async fn energy_stage(
    mut energy: EnergyTracker,
    mut alerts: AlertEngine,
    mut estimates: mpsc::Receiver<Estimate>,
    mut mission: Option<mpsc::Receiver<MissionUpdate>>,
    mut fanout: Fanout,
    status: ChainStatus,
    live: bool,
) {
    let vehicle = || match status.system_id.load(std::sync::atomic::Ordering::Relaxed) {
        0 => 1,
        id => id,
    };
    // The last real estimate, its energy, and when it came: the base of a silent tick.
    let mut last: Option<(Estimate, EnergyState, Instant)> = None;
    let mut next_mission: Option<MissionUpdate> = None;
    loop {
        let next = if live {
            tokio::time::timeout(SILENT_TICK, estimates.recv()).await
        } else {
            Ok(estimates.recv().await)
        };
        let report = match next {
            Ok(Some(est)) => {
                take_mission(&mut energy, &mut mission, &mut next_mission, est.t_s);
                let report = account(&mut energy, &mut alerts, est, vehicle());
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
                Report { estimate: quiet, energy: state.clone(), alerts: events, system_id: vehicle() }
            }
        };
        fanout.send(report).await;
    }
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
fn mission_setup(cfg: &Config, source: &SourceSpec) -> Result<Option<crate::mission::live::LiveSetup>> {
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
        system_id: cfg.sinks.mavlink.system_id,
        component_id: cfg.sinks.mavlink.component_id,
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
