//! Power models: a window (and the vehicle profile a model was built with) in, watts out.
//! Pure: no I/O, no clocks.

pub mod card;
pub mod lstm;
pub mod lstm_cpu;
pub mod physics;
pub mod profile;

pub use crate::report::{Estimate, ModelEstimate};
use crate::window::Window;

/// One model's output for one window.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prediction {
    /// Predicted electrical power, watts.
    pub power_w: f32,
    /// An uncertainty band (low, high), watts, where the model gives one.
    pub band_w: Option<(f32, f32)>,
}

/// Anything that turns windows into watts. Implementations do no I/O.
pub trait PowerModel: Send {
    /// Stable name used in tables, JSON and MAVLink (`dandrea`, `tseng_cal`, `lstm` …).
    fn name(&self) -> &str;
    /// Predict every window of `windows` into `out` (cleared first), in order. Batching is
    /// the model's business: the LSTM runs them as one batch, physics models one by one.
    fn predict(&mut self, windows: &[Window], out: &mut Vec<Prediction>);
    /// Samples between a window's newest and the instant its estimate is for
    /// ([`Window::back`]): 0 for the physics models; the LSTM's card may set a fixed lag
    /// (fixed-lag smoothing: power leads the motion it causes, so a window that also sees
    /// the 0.3 s after an instant estimates that instant better). `eval` scores each
    /// model against the measured power at its own instant.
    fn target_lag(&self) -> usize {
        0
    }
    /// Whether the model costs enough that a fleet may run it on fewer windows than every
    /// one (`[fleet] lstm_rate_hz`, [`Ensemble::estimate_some`]): the LSTM. Default false.
    fn heavy(&self) -> bool {
        false
    }
}

/// The set of models the inference stage runs side by side.
pub struct Ensemble {
    models: Vec<Box<dyn PowerModel>>,
    scratch: Vec<Prediction>,
}

impl Ensemble {
    /// An ensemble of these models, run in this order.
    pub fn new(models: Vec<Box<dyn PowerModel>>) -> Self {
        Self { models, scratch: Vec::new() }
    }
    /// Names of the [`PowerModel::heavy`] models, in order.
    pub fn heavy_names(&self) -> Vec<String> {
        self.models.iter().filter(|m| m.heavy()).map(|m| m.name().to_string()).collect()
    }
    /// Names of the models, in order.
    pub fn names(&self) -> Vec<String> {
        self.models.iter().map(|m| m.name().to_string()).collect()
    }
    /// Each model's [`PowerModel::target_lag`], in order: the estimate a window yields is
    /// for the sample this many steps before its newest.
    pub fn target_lags(&self) -> Vec<usize> {
        self.models.iter().map(|m| m.target_lag()).collect()
    }
    /// Run every model on every window (a batch when a replay runs flat out).
    pub fn estimate(&mut self, windows: &[Window]) -> Vec<Estimate> {
        self.estimate_some(windows, &[])
    }

    /// [`Ensemble::estimate`], but the [`PowerModel::heavy`] models run only on the windows
    /// whose `heavy[i]` is true (all of them where `heavy` is shorter than `windows`); the
    /// others' estimates lack those models.
    pub fn estimate_some(&mut self, windows: &[Window], heavy: &[bool]) -> Vec<Estimate> {
        let mut out: Vec<Estimate> = windows
            .iter()
            .map(|w| Estimate { t_s: w.t_s(), sample: w.last().clone(), models: Vec::with_capacity(self.models.len()) })
            .collect();
        let all = heavy.len() < windows.len() || heavy.iter().all(|&h| h);
        let mut picked = Vec::new();
        for m in &mut self.models {
            let name = m.name().to_string();
            let named = |p: &Prediction| ModelEstimate { name: name.clone(), power_w: p.power_w, band_w: p.band_w };
            if !m.heavy() || all {
                m.predict(windows, &mut self.scratch);
                for (e, p) in out.iter_mut().zip(&self.scratch) {
                    e.models.push(named(p));
                }
                continue;
            }
            picked.clear();
            picked.extend(windows.iter().zip(heavy).filter(|(_, &h)| h).map(|(w, _)| w.clone()));
            if picked.is_empty() {
                continue;
            }
            m.predict(&picked, &mut self.scratch);
            let mut preds = self.scratch.iter();
            for (e, _) in out.iter_mut().zip(heavy).filter(|(_, &h)| h) {
                if let Some(p) = preds.next() {
                    e.models.push(named(p));
                }
            }
        }
        out
    }
}

/// Which models run (the `[models]` table).
#[derive(Debug, Clone, Default, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ModelsConfig {
    /// The LSTM (`[models.lstm]`): on by default, with the shipped model.
    pub lstm: lstm::LstmConfig,
}

/// Work that needs libtorch (training, TorchScript models), asked of `dronewatt`, which
/// does not load it. The command line answers it by handing the whole command to
/// `dronewatt-torch` (crate `torch/`), which registers the libtorch parts at start.
#[derive(Debug, thiserror::Error)]
#[error("{what} needs libtorch, which `dronewatt` does not load: run the command with `dronewatt-torch` (`cargo build --workspace` builds it beside `dronewatt`)")]
pub struct NeedsLibtorch {
    /// What asked for it.
    pub what: String,
}

/// The models a configuration asks for, built and checked (profiles loaded, cards matched).
pub fn build_ensemble(
    models: &ModelsConfig,
    vehicle: Option<&std::path::Path>,
    telemetry: &crate::telemetry::TelemetryConfig,
) -> anyhow::Result<Ensemble> {
    Ok(Ensemble::new(build_models(models, vehicle, telemetry)?))
}

/// Every model a configuration runs, in table order: the one place models are listed, so
/// the live ensemble and `dronewatt eval` score exactly the same set. `vehicle` is the
/// profile file (`vehicle` in the TOML; the built-in M100 without one); `telemetry` is
/// checked against the LSTM's card (rate and window must match what it was trained on).
pub fn build_models(
    models: &ModelsConfig,
    vehicle: Option<&std::path::Path>,
    telemetry: &crate::telemetry::TelemetryConfig,
) -> anyhow::Result<Vec<Box<dyn PowerModel>>> {
    let mut out: Vec<Box<dyn PowerModel>> = Vec::new();
    // The physics models (+ Tseng's Solo form) on the configured vehicle profile.
    let profile = match vehicle {
        Some(path) => profile::VehicleProfile::load(path)?,
        None => profile::VehicleProfile::m100(),
    };
    out.extend(physics::models(&profile));
    // The LSTM after the physics models, when enabled and found.
    if let Some(m) = lstm::from_config(&models.lstm, telemetry)? {
        out.push(Box::new(m));
    }
    Ok(out)
}
