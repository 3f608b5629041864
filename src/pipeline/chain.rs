//! One vehicle's chain: its stages (telemetry → windows, energy + alerts) built from the
//! configuration and run as tasks, and what the vehicle store tells and keeps of it.

use std::sync::Arc;

use anyhow::Result;
use tokio::sync::mpsc;
use tokio::task::JoinHandle;

use super::mission::Resolved;
use super::{relay, FleetEvent, Inference, Job, WarmStart, CHANNEL_DEPTH};
use crate::alert::AlertEngine;
use crate::config::Config;
use crate::energy::EnergyTracker;
use crate::mission::live::{LiveSetup, MissionStep};
use crate::model::Ensemble;
use crate::report::status::ChainStatus;
use crate::report::{Estimate, Report, VehicleId};
use crate::sink::Fanout;
use crate::source::TimedMessage;
use crate::telemetry::window::Window;
use crate::telemetry::Telemetry;
use crate::vehicle::params::{Driver, Identity, ParamReader, VehicleParams};
use crate::vehicle::store::FlightLog;
use tokio::sync::oneshot;

use super::stages::{account, energy_stage, telemetry_stage};

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
pub(super) struct StoreNews {
    /// The pack's effective capacity learned on earlier flights, Wh, over how many.
    pub(super) capacity: Option<(f64, usize)>,
    /// The forecast model of the learned profile the models now run from, and why.
    pub(super) forecast: Option<(String, String)>,
    /// What the vehicle's last flight, and each identified pack's, left of its pack.
    pub(super) pack: crate::battery::PackHistories,
    /// A replayed log's first stamp, Unix s (reports' times count from it): the flight's end
    /// on the log's clock for the store.
    pub(super) log_origin_s: Option<f64>,
}

/// The running stages of one [`VehicleChain`].
pub struct ChainTasks {
    telemetry: JoinHandle<()>,
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
pub(super) enum VehicleNews {
    /// What the vehicle said about itself so far (identity, parameters, pack).
    Params(f64, VehicleParams),
    /// The vehicle store's answer, looked up off the stage: the energy stage waits for it
    /// when its estimates reach this time (a dropped sender: nothing remembered).
    Store(f64, oneshot::Receiver<StoreNews>),
}

impl VehicleNews {
    pub(super) fn t_s(&self) -> f64 {
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
        // The first hover calibrates the momentum-theory member (a spec sheet's forecast).
        energy.set_hover_reference(
            crate::energy::hover::HoverReference::of(profile),
            crate::energy::hover::follows_momentum_theory(profile),
        );
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

    /// Run the stages: messages in from `msgs` (in batches, each in order), windows to `inference` (the run's shared
    /// stage; this chain's own `models` are not used), reports out through `fanout`. `live`
    /// turns on the silent-link tick. The returned sender tells the chain's relay that the
    /// vehicle was lost or dropped.
    pub fn spawn(
        self,
        msgs: super::BatchRx,
        inference: &Inference,
        fanout: Fanout,
        status: &ChainStatus,
        live: bool,
    ) -> (mpsc::UnboundedSender<FleetEvent>, ChainTasks) {
        let (est_tx, est_rx) = mpsc::channel::<Estimate>(CHANNEL_DEPTH);
        let (ev_tx, ev_rx) = mpsc::unbounded_channel();
        let system_id = status.system_id.load(std::sync::atomic::Ordering::Relaxed);
        let vehicle = VehicleId {
            network: status.network,
            system_id,
        };
        let mut own = Fanout::default().gauged(status.stats.clone());
        // The windows go straight to the shared inference stage, with the way back.
        let windows = WindowsOut {
            jobs: inference.jobs.clone(),
            vehicle,
            reply: est_tx,
        };
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
                windows,
                news_tx,
                memory,
                status.clone(),
            )),
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

/// Where a chain's windows go: the shared inference stage's queue, each as a [`Job`] with
/// the vehicle and the channel its estimate comes back on (no task of its own between).
pub(super) struct WindowsOut {
    pub(super) jobs: mpsc::Sender<Job>,
    pub(super) vehicle: VehicleId,
    pub(super) reply: mpsc::Sender<Estimate>,
}

impl WindowsOut {
    /// Queue `window`; false when the inference stage is gone (the run is over).
    pub(super) async fn send(&self, window: Window) -> bool {
        let job = Job {
            window,
            vehicle: self.vehicle,
            reply: self.reply.clone(),
        };
        self.jobs.send(job).await.is_ok()
    }
}

/// The vehicle store's side of a run: where it is, and where what it remembers goes (the
/// fits to the inference stage, the pack's effective capacity to the energy stage).
pub(super) struct Memory {
    pub(super) dir: std::path::PathBuf,
    /// The vehicle (the inference stage's key for its adaptation).
    pub(super) vehicle: VehicleId,
    pub(super) warm: std::sync::mpsc::Sender<(VehicleId, WarmStart)>,
    /// Whether the one lookup was made.
    pub(super) looked_up: bool,
    /// Builds the models from a learned profile the store keeps for the vehicle.
    pub(super) rebuild: Option<Rebuild>,
    /// The vehicle's latest parameters and when its identity was first heard (s).
    pub(super) heard: Option<(f64, crate::vehicle::params::VehicleParams)>,
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
pub(super) fn look_up(
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
