//! One vehicle's chain as named stages, the demultiplexer that runs one chain per vehicle
//! of a link, the run that feeds them from a source and fans their reports out to the
//! sinks, and shutdown.
//!
//! ```text
//! source ─TimedMessage→ demux ─TimedMessage→ one chain per vehicle:
//!     telemetry_stage ─Window→ inference_stage (one for all vehicles) ─Estimate→ energy_stage ─Report→ relay ─Report→ Fanout → one task per sink
//!      (+ MissionStep) ─── MissionUpdate (the vehicle's mission forecast) ─────▶┤
//!            └────────── VehicleNews (parameters, the store's answer; stamped t_s) ──▶┘
//! ```
//!
//! Each vehicle's chain forecasts its own mission: the telemetry stage hands every message
//! of its vehicle to a [`crate::mission::live::MissionStep`] first (a ground station's
//! mission messages reach the chain of the vehicle they address), whose statuses the energy
//! stage takes in source-time order. Every chain is built from [`Resolved`], what the
//! configuration names read once at start.
//!
//! The telemetry stage also reads the vehicle ([`crate::vehicle::params`]): on a live link it
//! asks for the battery parameters (PARAM_REQUEST_READ on the link, resent, bounded), in a
//! replay it takes the logged PARAM_VALUEs; what it learns reaches the energy stage stamped
//! with the source time of the message that said it, and the energy stage takes it when its
//! estimates reach that time (the log's own clock, never thread timing: a replay gives the
//! same reports at any speed).
//!
//! Every arrow is a bounded channel carrying one typed value; a full channel holds the
//! stage before it back, so a flat-out replay loses nothing. The demultiplexer
//! ([`Demux`]) starts a [`VehicleChain`] for each vehicle it hears, ends it when
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

mod batches;
mod chain;
pub mod checkpoint;
mod fleet;
mod inference;
mod mission;
mod nats_out;
mod shutdown;
mod sinks;
mod stages;

pub use batches::BatchRx;
pub use chain::{ChainEnd, ChainTasks, Rebuild, VehicleChain};
use fleet::Fleet;
pub use fleet::{Demux, FleetEvent, Route};
pub use inference::{Batching, Fits, Inference, Job, WarmStart};
use mission::MissionOn;
pub use mission::Resolved;
pub use shutdown::shutdown_on_signal;
use sinks::relay;
pub use sinks::{start_sinks, SinkTasks};
pub use stages::account;

use std::sync::Arc;

use anyhow::Result;
use tokio::sync::mpsc;
use tokio_util::sync::CancellationToken;

use crate::config::Config;
use crate::model::Ensemble;
use crate::report::status::{ChainStatus, LinkHandle, StatsSnapshot};
use crate::sink::SinkSpec;
use crate::source::{LinkSigning, SourceSpec, TimedMessage};

/// Channel depth between stages. Deep enough to ride out a slow model for a few seconds
/// at 10 Hz; a flat-out replay simply waits on the slowest stage (back-pressure).
pub const CHANNEL_DEPTH: usize = 1024;
/// Most windows the inference stage runs as one batch when they queue up.
pub const MAX_BATCH: usize = 256;
/// On a live link, with no estimate for this long the alert rules are still evaluated, on
/// [`crate::report::Estimate::silent`], so `telemetry_lost` fires when the link goes wholly silent.
pub const SILENT_TICK: std::time::Duration = std::time::Duration::from_secs(1);
/// How long the end of a run waits for an uplink to write what its sink queued last.
pub(crate) const UPLINK_FLUSH: std::time::Duration = std::time::Duration::from_secs(2);
/// How often the telemetry stage refreshes the signal health the terminal view shows.
pub(crate) const HEALTH_EVERY: std::time::Duration = std::time::Duration::from_secs(1);

/// Everything a run of the pipeline needs.
pub struct Pipeline {
    pub config: Config,
    pub source: SourceSpec,
    pub sinks: Vec<SinkSpec>,
    /// The vehicle store's folder ([`crate::vehicle::store`]); `None`: nothing remembered.
    pub data_dir: Option<std::path::PathBuf>,
}

/// The pack named by the run where the config's `[energy]` is silent: the M100 data set's
/// flights fly the M100's TB48D, and a vehicle profile with a `[battery]` its own pack (the
/// profile as [`Resolved`] read it). No other vehicle gets either (the capacity stays not
/// known until the vehicle says).
fn known_pack(config: &mut Config, source: &SourceSpec, resolved: &Resolved) {
    if matches!(source, SourceSpec::Dataset { .. }) {
        config
            .energy
            .fill_pack(&crate::vehicle::BatteryConfig::m100());
    }
    if resolved.vehicle.path.is_some() {
        if let Some(pack) = crate::vehicle::pack_spec::profile_pack(&resolved.vehicle.profile) {
            config.energy.fill_pack(&pack);
        }
    }
}

/// Run the pipeline to the end of its source or until `shutdown` is cancelled. Returns the
/// ingest counters (the summary line's numbers).
pub async fn run(mut p: Pipeline, shutdown: CancellationToken) -> Result<StatsSnapshot> {
    // The files the config names, read once; the first chain built before any task starts,
    // so a bad model or profile fails before we listen.
    let resolved = Resolved::load(&p.config)?;
    known_pack(&mut p.config, &p.source, &resolved);
    let mut chain = VehicleChain::build(&p.config, &resolved)?;
    let demux = Demux::new(&p.config.fleet, None).map_err(anyhow::Error::msg)?;
    // Every vehicle's mission forecast, a step of its chain (checked now on the first).
    let mission = MissionOn::of(&p.config, &p.source, demux.filter());
    chain.mission = mission
        .as_ref()
        .map(|m| m.setup(&p.config, &resolved))
        .transpose()?;
    // The signing key is read now: a missing or world-readable key fails before we listen.
    let signing = p
        .config
        .link
        .load()
        .map_err(anyhow::Error::msg)?
        .map(|s| Arc::new(LinkSigning::new(s)));
    let signer = signing
        .clone()
        .map(|s| s as Arc<dyn crate::report::status::FrameSigner>);
    let status = ChainStatus {
        shutdown: shutdown.clone(),
        link: LinkHandle::with_signer(signer),
        ..ChainStatus::default()
    };

    // Sinks start first so they see every report.
    let (mut fanout, sinks) = start_sinks(p.sinks, &status)?;
    // A fleet worker's reports to NATS too.
    let nats_out = matches!(p.source, crate::source::SourceSpec::Nats(_))
        .then(|| tokio::spawn(nats_out::run(fanout.subscribe())));

    let live = p.source.is_live();
    let flat = p.source.is_flat();
    // A fleet worker's chains hand their state over for its checkpoints.
    if matches!(p.source, crate::source::SourceSpec::Nats(_)) {
        crate::source::nats::checkpoint::set_card(
            checkpoint::card(&p.config, &resolved.vehicle),
            checkpoint::check,
        );
    }
    let (msg_tx, msg_rx) = mpsc::channel::<TimedMessage>(CHANNEL_DEPTH);
    let source = tokio::spawn(crate::source::run(
        p.source,
        msg_tx,
        status.stats.clone(),
        status.link.clone(),
        signing,
        shutdown,
    ));
    let inference = Inference::spawn(
        std::mem::replace(&mut chain.models, Ensemble::new(Vec::new())),
        Batching::from_config(&p.config).flat(flat),
        live,
        status.stats.clone(),
    );
    let fleet = Fleet {
        config: p.config,
        resolved,
        mission,
        demux,
        first: Some(chain),
        inference,
        fanout,
        status: status.clone(),
        live,
        data_dir: p.data_dir,
    };
    let demux = tokio::spawn(fleet.run(msg_rx));

    let source_result = source.await?;
    demux.await??;
    sinks.join().await?;
    if let Some(t) = nats_out {
        t.await?;
    }
    source_result?;
    Ok(status.stats.snapshot())
}
