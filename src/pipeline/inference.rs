//! The inference stage: one for the whole run, batching every vehicle's windows through the
//! models, with each vehicle's adaptation warm-started from the vehicle store.

use std::sync::Arc;

use anyhow::Result;
use tokio::sync::mpsc;
use tokio::task::JoinHandle;

use super::{CHANNEL_DEPTH, MAX_BATCH};
use crate::config::Config;
use crate::model::Ensemble;
use crate::report::status::IngestStats;
use crate::report::{Estimate, VehicleId};
use crate::telemetry::window::Window;

/// One window for the shared inference stage, whose it is, and where its estimate goes.
pub struct Job {
    pub window: Window,
    pub vehicle: VehicleId,
    pub reply: mpsc::Sender<Estimate>,
}

/// How the shared inference stage batches (`[fleet] batch_wait_ms`, `lstm_rate_hz`).
#[derive(Debug, Clone, Copy)]
pub struct Batching {
    /// With more than one vehicle heard, the longest a window waits for others to join.
    pub wait: std::time::Duration,
    /// The heavy models (the LSTM) run on every `heavy_every`-th window of each vehicle.
    pub heavy_every: u64,
    /// A recorded source played flat out: a batch waits for [`Batching::max`] windows as long
    /// as more keep coming (`FLAT_IDLE`, 2 ms). Never on a live link or a paced replay, where a
    /// window waits for no other.
    pub flat: bool,
    /// Most windows a batch holds: [`MAX_BATCH`], or what `DRONEWATT_MAX_BATCH` says (a test's
    /// knob: 1 runs every window alone, the unbatched path a batched replay must equal).
    pub max: usize,
}

/// The environment variable that caps a batch (1..=[`MAX_BATCH`]; anything else is
/// ignored with a warning). For tests and benchmarks only: the figures do not depend on it,
/// only the speed does.
pub const MAX_BATCH_ENV: &str = "DRONEWATT_MAX_BATCH";

/// The batch cap: [`MAX_BATCH`] unless [`MAX_BATCH_ENV`] names a smaller one.
fn max_batch() -> usize {
    let Ok(v) = std::env::var(MAX_BATCH_ENV) else {
        return MAX_BATCH;
    };
    match v.trim().parse::<usize>() {
        Ok(n) if (1..=MAX_BATCH).contains(&n) => n,
        _ => {
            tracing::warn!("{MAX_BATCH_ENV}={v:?}: not a batch size 1..={MAX_BATCH}; batches of up to {MAX_BATCH}");
            MAX_BATCH
        }
    }
}

impl Batching {
    /// From the configuration: the wait, and the LSTM's period in windows.
    pub fn from_config(cfg: &Config) -> Self {
        let every = cfg
            .fleet
            .lstm_rate_hz
            .map_or(1.0, |r| (cfg.telemetry.rate_hz / r).round());
        Self {
            wait: std::time::Duration::from_secs_f64(cfg.fleet.batch_wait_ms / 1e3),
            heavy_every: (every as u64).max(1),
            flat: false,
            max: max_batch(),
        }
    }

    /// Whether the source is played flat out ([`Batching::flat`]).
    pub fn flat(self, flat: bool) -> Self {
        Self { flat, ..self }
    }
}

/// Flat out, the longest the inference stage waits for the next window before it runs the
/// batch it holds: the producers' stall (a descheduled thread, the end of the input, a
/// vehicle store lookup), never a wait on the clock the replay's own pace would have.
pub const FLAT_IDLE: std::time::Duration = std::time::Duration::from_millis(2);

/// The inference stage every vehicle's chain sends its windows to: one for the whole run,
/// so the windows of all vehicles that queue up together run as one batch.
pub struct Inference {
    pub(super) jobs: mpsc::Sender<Job>,
    /// What the vehicle store remembers of a vehicle, for its adaptation (by network and system id).
    pub(super) warm: std::sync::mpsc::Sender<(VehicleId, WarmStart)>,
    task: JoinHandle<std::collections::BTreeMap<VehicleId, Fits>>,
}

impl Inference {
    /// Start the stage on its own thread with these models (on the tokio runtime it is
    /// called from). `live`: never wait for the vehicle store.
    pub fn spawn(
        models: Ensemble,
        batching: Batching,
        live: bool,
        stats: Arc<IngestStats>,
    ) -> Self {
        let (jobs, rx) = mpsc::channel::<Job>(CHANNEL_DEPTH);
        let (warm, warm_rx) = std::sync::mpsc::channel();
        let rt = tokio::runtime::Handle::current();
        // Model work is CPU-bound: one dedicated thread for the whole run, off the reactor.
        Self {
            jobs,
            warm,
            task: tokio::task::spawn_blocking(move || {
                inference_stage(models, rx, batching, rt, warm_rx, live, stats)
            }),
        }
    }
    /// Wait for it to drain and end, once every chain sending to it has ended; each
    /// vehicle's adaptation fits (adaptation on).
    pub async fn join(self) -> Result<std::collections::BTreeMap<VehicleId, Fits>> {
        drop(self.jobs);
        drop(self.warm);
        Ok(self.task.await?)
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
    warm: std::sync::mpsc::Receiver<(VehicleId, WarmStart)>,
    live: bool,
    stats: Arc<IngestStats>,
) -> std::collections::BTreeMap<VehicleId, Fits> {
    let heavy_names = models.heavy_names();
    let mut b = Batch::default();
    // Per vehicle: windows seen, and the heavy models' latest estimates.
    let mut seen: std::collections::HashMap<VehicleId, (u64, Vec<crate::report::ModelEstimate>)> =
        Default::default();
    // Vehicles known whose fits are being looked up.
    let mut waiting = std::collections::BTreeSet::new();
    let mut vehicles = Vec::new();
    // Batches run and windows in them (said at the end, at debug level).
    let (mut batches, mut windows) = (0u64, 0u64);
    while let Some(j) = jobs.blocking_recv() {
        let deadline = tokio::time::Instant::now() + batching.wait;
        b.take(j, &mut seen, batching.heavy_every);
        let wait = seen.len() > 1 && !batching.wait.is_zero();
        while b.windows.len() < batching.max {
            match jobs.try_recv() {
                Ok(j) => b.take(j, &mut seen, batching.heavy_every),
                // Flat out: the windows behind are coming, as fast as the stages before
                // make them; the batch runs once full or once they pause.
                Err(mpsc::error::TryRecvError::Empty) if batching.flat => {
                    match rt.block_on(tokio::time::timeout(FLAT_IDLE, jobs.recv())) {
                        Ok(Some(j)) => b.take(j, &mut seen, batching.heavy_every),
                        _ => break,
                    }
                }
                // Wait a little for the other vehicles' windows of this tick.
                Err(mpsc::error::TryRecvError::Empty) if wait => {
                    match rt.block_on(tokio::time::timeout_at(deadline, jobs.recv())) {
                        Ok(Some(j)) => b.take(j, &mut seen, batching.heavy_every),
                        _ => break,
                    }
                }
                Err(_) => break,
            }
        }
        for (id, news) in warm.try_iter() {
            warm_start(&mut models, id, news, &mut waiting, seen.len());
        }
        if !live {
            let until = std::time::Instant::now() + WARM_WAIT;
            while b.meta.iter().any(|(v, ..)| waiting.contains(v)) {
                match warm.recv_timeout(until.saturating_duration_since(std::time::Instant::now()))
                {
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
        batches += 1;
        windows += b.windows.len() as u64;
        let estimates = models.estimate_some(&b.windows, &b.heavy, &vehicles);
        for (mut e, (vehicle, full, reply)) in estimates.into_iter().zip(b.meta.drain(..)) {
            if let (true, Some((_, held))) = (batching.heavy_every > 1, seen.get_mut(&vehicle)) {
                if full {
                    *held = e
                        .models
                        .iter()
                        .filter(|m| heavy_names.contains(&m.name))
                        .cloned()
                        .collect();
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
    tracing::debug!(
        batches,
        windows,
        flat = batching.flat,
        "inference: the run's batches"
    );
    seen.keys()
        .filter_map(|&id| Some((id, models.adaptation(id)?.fits().to_vec())))
        .collect()
}

/// The batch the inference stage is gathering: windows, whether the heavy models run on
/// each, and whose each is (vehicle, heavy, reply).
#[derive(Default)]
struct Batch {
    windows: Vec<Window>,
    heavy: Vec<bool>,
    meta: Vec<(VehicleId, bool, mpsc::Sender<Estimate>)>,
}

impl Batch {
    fn take(
        &mut self,
        j: Job,
        seen: &mut std::collections::HashMap<VehicleId, (u64, Vec<crate::report::ModelEstimate>)>,
        every: u64,
    ) {
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
fn warm_start(
    models: &mut Ensemble,
    vehicle: VehicleId,
    news: WarmStart,
    waiting: &mut std::collections::BTreeSet<VehicleId>,
    vehicles: usize,
) {
    match news {
        WarmStart::Pending => {
            waiting.insert(vehicle);
        }
        WarmStart::Ready(learned, profile_models) => {
            waiting.remove(&vehicle);
            match profile_models {
                Some(m) if vehicles <= 1 => *models = *m,
                Some(_) => {
                    tracing::warn!(vehicle = %vehicle, "vehicle store: a learned profile is not applied in a fleet (the vehicles share the models)")
                }
                None => {}
            }
            if let (Some(l), Some(ad)) = (learned, models.adaptation_mut(vehicle)) {
                let n = ad.restore(&l);
                tracing::info!(vehicle = %vehicle, "warm start: {n} model(s) start from what earlier flights of this vehicle taught");
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
