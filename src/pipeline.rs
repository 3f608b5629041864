//! Wires the stages into tokio tasks joined by bounded channels and owns shutdown.
//!
//! ```text
//! source task ─mpsc<TimedMessage>→ telemetry task ─mpsc<Window>→ inference task
//!   ─mpsc<Estimate>→ energy+alerts task ─broadcast<Arc<Report>>→ one task per sink
//! ```
//!
//! Shutdown is one path whatever starts it (Ctrl-C, the end of a replay, a fatal source
//! error): the source stops and drops its sender, each stage drains what it holds and drops
//! its own, and every sink sees its channel close, flushes and writes its summary. Nothing
//! is lost on the way out.

use std::sync::Arc;

use anyhow::Result;
use tokio::sync::{broadcast, mpsc};
use tokio_util::sync::CancellationToken;

use crate::config::Config;
use crate::energy::Report;
use crate::model::Estimate;
use crate::source::{IngestStats, StatsSnapshot, TimedMessage};
use crate::window::Window;

/// Channel depth between stages. Deep enough to ride out a slow model for a few seconds
/// at 10 Hz; a flat-out replay simply waits on the slowest stage (back-pressure).
pub const CHANNEL_DEPTH: usize = 1024;
/// Most windows the inference stage runs as one batch when they queue up.
pub const MAX_BATCH: usize = 256;
/// How long the energy stage waits for a sink that is far behind before it sends anyway
/// (that sink then misses reports, and counts them).
pub const SINK_PATIENCE: std::time::Duration = std::time::Duration::from_secs(1);
/// On a live link, with no estimate for this long the alert rules are still evaluated, on a
/// "nothing heard" estimate, so `telemetry_lost` fires when the link goes wholly silent.
pub const SILENT_TICK: std::time::Duration = std::time::Duration::from_secs(1);

/// Everything a run of the pipeline needs.
pub struct Pipeline {
    pub config: Config,
    pub source: crate::source::SourceSpec,
    pub sinks: Vec<crate::sink::SinkSpec>,
}

/// Run the pipeline to the end of its source or until `shutdown` is cancelled. Returns the
/// ingest counters (the summary line's numbers).
pub async fn run(p: Pipeline, shutdown: CancellationToken) -> Result<StatsSnapshot> {
    let stats = Arc::new(IngestStats::default());
    let cfg = p.config;

    // Built before any task starts, so a bad model or profile fails before we listen.
    let mut telemetry = crate::telemetry::Telemetry::new(&cfg.telemetry, &cfg.mission);
    let mut ensemble = crate::model::build_ensemble(&cfg)?;
    let mut energy = crate::energy::EnergyTracker::new(&cfg)?;
    let mut alerts = crate::alert::AlertEngine::new(&cfg.alerts)?;

    let (msg_tx, mut msg_rx) = mpsc::channel::<TimedMessage>(CHANNEL_DEPTH);
    let (win_tx, mut win_rx) = mpsc::channel::<Window>(CHANNEL_DEPTH);
    let (est_tx, mut est_rx) = mpsc::channel::<Estimate>(CHANNEL_DEPTH);
    let (rep_tx, _) = broadcast::channel::<Arc<Report>>(CHANNEL_DEPTH);

    // Sinks subscribe first so they see every report.
    let health = crate::telemetry::HealthHandle::default();
    let mut sink_tasks = Vec::new();
    let link = crate::source::LinkHandle::default();
    for spec in p.sinks {
        let rx = rep_tx.subscribe();
        sink_tasks.push(crate::sink::spawn(spec, rx, stats.clone(), health.clone(), link.clone())?);
    }

    let live = matches!(p.source, crate::source::SourceSpec::Link(_));
    // vehicle (issue 11): who the vehicle is and its battery parameters — asked for on a
    // live link, taken from the logged PARAM_VALUEs in a replay — on to the energy stage.
    let reader = if live { crate::vehicle::params::ParamReader::live() } else { crate::vehicle::params::ParamReader::passive() };
    let mav_ids = (cfg.sinks.mavlink.system_id, cfg.sinks.mavlink.component_id);
    let mut vehicle = crate::vehicle::params::Driver::new(reader, link.clone(), mav_ids.0, mav_ids.1);
    let (vehicle_tx, mut vehicle_rx) = tokio::sync::watch::channel(crate::vehicle::params::VehicleParams::default());
    let source = tokio::spawn(crate::source::run(p.source, msg_tx, stats.clone(), link, shutdown.clone()));

    let tstats = stats.clone();
    let thealth = health.clone();
    let telemetry_task = tokio::spawn(async move {
        let mut out = Vec::new();
        let mut shown = tokio::time::Instant::now();
        while let Some(m) = msg_rx.recv().await {
            if let Some(params) = vehicle.on_message(&m) {
                let _ = vehicle_tx.send(params);
            }
            telemetry.push(&m, &mut out);
            if shown.elapsed() >= std::time::Duration::from_secs(1) {
                shown = tokio::time::Instant::now();
                if let Ok(mut h) = thealth.lock() {
                    *h = telemetry.health();
                }
            }
            for w in out.drain(..) {
                IngestStats::add(&tstats.windows, 1);
                if win_tx.send(w).await.is_err() {
                    return;
                }
            }
        }
        telemetry.finish(&mut out);
        for w in out.drain(..) {
            IngestStats::add(&tstats.windows, 1);
            let _ = win_tx.send(w).await;
        }
    });

    // Model work is CPU-bound: one dedicated thread for the whole run, off the reactor.
    // One thread, not one per batch: libtorch's thread settings are per OS thread, and a
    // fresh thread's defaults (an intra-op team as wide as the machine) cost ~10 ms a window.
    let inference_task = tokio::task::spawn_blocking(move || {
        crate::model::pin_inference_thread();
        let mut batch = Vec::with_capacity(MAX_BATCH);
        while let Some(w) = win_rx.blocking_recv() {
            batch.push(w);
            // Windows that queued up meanwhile (a flat-out replay) run as one batch.
            while batch.len() < MAX_BATCH {
                match win_rx.try_recv() {
                    Ok(w) => batch.push(w),
                    Err(_) => break,
                }
            }
            for e in ensemble.estimate(&batch) {
                if est_tx.blocking_send(e).is_err() {
                    return;
                }
            }
            batch.clear();
        }
    });

    let energy_task = tokio::spawn(async move {
        // The last real estimate and when it came: the base of a silent tick.
        let mut last: Option<(Estimate, crate::energy::EnergyState, tokio::time::Instant)> = None;
        let mut vehicle_final = false;
        loop {
            let next = if live {
                tokio::time::timeout(SILENT_TICK, est_rx.recv()).await
            } else {
                Ok(est_rx.recv().await)
            };
            // vehicle (issue 11): capacity and cells from the vehicle where the config is silent.
            // A closed channel (the telemetry stage done: a fast replay) still holds the last word.
            let (changed, closed) = vehicle_rx.has_changed().map_or((true, true), |c| (c, false));
            if changed && !vehicle_final {
                energy.set_vehicle(vehicle_rx.borrow_and_update().clone());
                vehicle_final = closed;
            }
            let report = match next {
                Ok(Some(est)) => {
                    let state = energy.update(&est);
                    let events = alerts.evaluate(&est, &state);
                    if live {
                        last = Some((est.clone(), state.clone(), tokio::time::Instant::now()));
                    }
                    Report { estimate: est, energy: state, alerts: events }
                }
                Ok(None) => break,
                Err(_) => {
                    // Nothing heard for SILENT_TICK: every feature is stale, nothing is
                    // measured or predicted. Energy is left as it stood; only the alert rules
                    // run, and a report goes out only if one of them changes state.
                    let Some((est, state, at)) = &last else { continue };
                    let mut quiet = est.clone();
                    quiet.t_s += at.elapsed().as_secs_f64();
                    quiet.sample.stale_mask = u32::MAX;
                    quiet.sample.measured_w = None;
                    quiet.models.clear();
                    let events = alerts.evaluate(&quiet, state);
                    if events.is_empty() {
                        continue;
                    }
                    Report { estimate: quiet, energy: state.clone(), alerts: events }
                }
            };
            // A broadcast never waits: hold back while the slowest sink is far behind, so a
            // flat-out replay loses nothing. A sink stuck for longer than SINK_PATIENCE
            // loses reports instead of stalling everyone (it counts them).
            let mut waited = std::time::Duration::ZERO;
            while rep_tx.len() >= CHANNEL_DEPTH * 3 / 4 && waited < SINK_PATIENCE {
                tokio::time::sleep(std::time::Duration::from_millis(2)).await;
                waited += std::time::Duration::from_millis(2);
            }
            // No receivers is not an error: a run may have no sinks.
            let _ = rep_tx.send(Arc::new(report));
        }
    });

    let source_result = source.await?;
    telemetry_task.await?;
    inference_task.await?;
    energy_task.await?;
    for t in sink_tasks {
        t.await??;
    }
    source_result?;
    Ok(stats.snapshot())
}

/// A token cancelled on Ctrl-C (SIGINT) or SIGTERM.
pub fn shutdown_on_signal() -> CancellationToken {
    let token = CancellationToken::new();
    let t = token.clone();
    tokio::spawn(async move {
        #[cfg(unix)]
        {
            use tokio::signal::unix::{signal, SignalKind};
            let mut term = match signal(SignalKind::terminate()) {
                Ok(s) => s,
                Err(_) => {
                    let _ = tokio::signal::ctrl_c().await;
                    t.cancel();
                    return;
                }
            };
            tokio::select! {
                _ = tokio::signal::ctrl_c() => {},
                _ = term.recv() => {},
            }
        }
        #[cfg(not(unix))]
        let _ = tokio::signal::ctrl_c().await;
        tracing::info!("shutting down");
        t.cancel();
    });
    token
}
