//! Power models: a window (and the vehicle profile a model was built with) in, watts out.
//! Pure: no I/O, no clocks.

pub mod adapt;
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
    /// Whether `window` lies inside what the model was fitted on, so that online adaptation
    /// ([`adapt`]) may learn from it. Default true (the physics models have no training
    /// range); the LSTM says false for a window far outside its training data.
    fn in_training_range(&self, _window: &Window) -> bool {
        true
    }
}

/// The set of models the inference stage runs side by side.
pub struct Ensemble {
    models: Vec<Box<dyn PowerModel>>,
    scratch: Vec<Prediction>,
    /// Online adaptation to measured power, when on ([`Ensemble::with_adaptation`]).
    adapt: Option<adapt::Adaptation>,
}

impl Ensemble {
    /// An ensemble of these models, run in this order.
    pub fn new(models: Vec<Box<dyn PowerModel>>) -> Self {
        Self { models, scratch: Vec::new(), adapt: None }
    }
    /// Adapt every model's output to measured power ([`adapt`]).
    pub fn with_adaptation(mut self, adaptation: adapt::Adaptation) -> Self {
        self.adapt = Some(adaptation);
        self
    }
    /// The adaptation's state, when adaptation is on.
    pub fn adaptation(&self) -> Option<&adapt::Adaptation> {
        self.adapt.as_ref()
    }
    /// The adaptation's state, to restore what an earlier flight learned or to start a new
    /// flight afresh.
    pub fn adaptation_mut(&mut self) -> Option<&mut adapt::Adaptation> {
        self.adapt.as_mut()
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
        let mut out: Vec<Estimate> = windows
            .iter()
            .map(|w| Estimate { t_s: w.t_s(), sample: w.last().clone(), models: Vec::with_capacity(self.models.len()) })
            .collect();
        for (i, m) in self.models.iter_mut().enumerate() {
            m.predict(windows, &mut self.scratch);
            let lag = m.target_lag();
            for ((e, p), w) in out.iter_mut().zip(&self.scratch).zip(windows) {
                let mut me = ModelEstimate::new(m.name(), p.power_w, p.band_w);
                if let Some(ad) = &mut self.adapt {
                    // The prediction is for the sample `lag` back: teach with its power.
                    let measured = w.back(lag).measured_w;
                    let in_range = measured.is_some() && m.in_training_range(w);
                    if let Some(a) = ad.step(i, p.power_w, measured, in_range) {
                        me.adapted_w = Some(a.adapted_w);
                        me.reference_w = Some(a.reference_w);
                    }
                }
                e.models.push(me);
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
    /// Online adaptation to measured power (`[models.adapt]`): on by default.
    pub adapt: adapt::AdaptConfig,
}

impl ModelsConfig {
    /// Range checks; each message names the key.
    pub fn validate(&self) -> Result<(), String> {
        self.adapt.validate()
    }
}

/// Set up the calling thread to run models: one libtorch intra-op thread (the LSTM is
/// small; at batch 1 a thread team costs more than it gains). Per thread, so the thread that
/// runs inference calls it.
pub fn pin_inference_thread() {
    tch::set_num_threads(1);
}

/// The models a configuration asks for, built and checked (profiles loaded, cards matched),
/// adapting to measured power unless `[models.adapt] enabled = false`. `payload_g` is the
/// mission's configured payload (the motors-off threshold of adaptation is the loaded
/// vehicle's ideal hover power).
pub fn build_ensemble(
    models: &ModelsConfig,
    vehicle: Option<&std::path::Path>,
    telemetry: &crate::telemetry::TelemetryConfig,
    payload_g: Option<f32>,
) -> anyhow::Result<Ensemble> {
    let ensemble = Ensemble::new(build_models(models, vehicle, telemetry)?);
    if !models.adapt.enabled {
        return Ok(ensemble);
    }
    let adaptation = build_adaptation(&models.adapt, vehicle, telemetry, payload_g, &ensemble.names())?;
    Ok(ensemble.with_adaptation(adaptation))
}

/// The adaptation for these models on this vehicle: windows every 1 / `rate_hz` s, the
/// motors-off threshold from the profile's ideal hover power with the payload.
pub fn build_adaptation(
    cfg: &adapt::AdaptConfig,
    vehicle: Option<&std::path::Path>,
    telemetry: &crate::telemetry::TelemetryConfig,
    payload_g: Option<f32>,
    names: &[String],
) -> anyhow::Result<adapt::Adaptation> {
    cfg.validate().map_err(anyhow::Error::msg)?;
    let profile = load_profile(vehicle)?;
    let payload_kg = f64::from(payload_g.unwrap_or(0.0)).max(0.0) / 1000.0;
    let hover_w = adapt::ideal_hover_w(profile.mass_kg(payload_kg), profile.air.g_m_s2, profile.air.rho_kg_m3, profile.disk_area_m2());
    Ok(adapt::Adaptation::new(cfg, names, 1.0 / telemetry.rate_hz, hover_w))
}

/// The vehicle profile file, else the built-in M100.
fn load_profile(vehicle: Option<&std::path::Path>) -> anyhow::Result<profile::VehicleProfile> {
    match vehicle {
        Some(path) => profile::VehicleProfile::load(path),
        None => Ok(profile::VehicleProfile::m100()),
    }
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
    let profile = load_profile(vehicle)?;
    out.extend(physics::models(&profile));
    // The LSTM after the physics models, when enabled and found.
    if let Some(m) = lstm::from_config(&models.lstm, telemetry)? {
        out.push(Box::new(m));
    }
    Ok(out)
}
