//! Power models: a window (and the vehicle profile a model was built with) in, watts out.
//! Pure: no I/O, no clocks. Owners: physics (issue 4), LSTM (issue 5).

pub mod adapt;
pub mod card;
pub mod lstm;
pub mod lstm_cpu;
pub mod physics;
pub mod profile;

use crate::telemetry::Sample;
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

/// One model's estimate, named.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ModelEstimate {
    pub name: String,
    /// The model's own prediction, W.
    pub power_w: f32,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub band_w: Option<(f32, f32)>,
    /// The prediction corrected by online adaptation to measured power ([`adapt`]), W;
    /// absent when adaptation is off.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub adapted_w: Option<f32>,
    /// The prediction corrected by the slowly adapting reference ([`adapt`]) the
    /// `deviation_above` alert compares with, W; absent when adaptation is off.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference_w: Option<f32>,
}

impl ModelEstimate {
    /// A raw estimate (no adaptation).
    pub fn new(name: impl Into<String>, power_w: f32, band_w: Option<(f32, f32)>) -> Self {
        Self { name: name.into(), power_w, band_w, adapted_w: None, reference_w: None }
    }
}

/// Every model's estimate for one window: what the inference stage sends on.
#[derive(Debug, Clone)]
pub struct Estimate {
    /// Time of the window's newest sample, s.
    pub t_s: f64,
    /// The window's newest sample (features, measured power, home vector).
    pub sample: Sample,
    /// One entry per model that ran, in the ensemble's order.
    pub models: Vec<ModelEstimate>,
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
    /// The adaptation's state, to restore what an earlier flight learned.
    pub fn adaptation_mut(&mut self) -> Option<&mut adapt::Adaptation> {
        self.adapt.as_mut()
    }
    /// Names of the models, in order.
    pub fn names(&self) -> Vec<String> {
        self.models.iter().map(|m| m.name().to_string()).collect()
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

/// Set up the calling thread to run models: one libtorch intra-op thread (the LSTM is
/// small; at batch 1 a thread team costs more than it gains). Per thread, so the thread that
/// runs inference calls it.
pub fn pin_inference_thread() {
    tch::set_num_threads(1);
}

/// The models a configuration asks for, built and checked (profiles loaded, cards matched).
pub fn build_ensemble(cfg: &crate::config::Config) -> anyhow::Result<Ensemble> {
    let ensemble = Ensemble::new(build_models(cfg)?);
    if !cfg.models.adapt.enabled {
        return Ok(ensemble);
    }
    cfg.models.adapt.validate().map_err(anyhow::Error::msg)?;
    let adaptation = build_adaptation(cfg, &ensemble.names())?;
    Ok(ensemble.with_adaptation(adaptation))
}

/// The adaptation for these models on the configured vehicle and mission: windows every
/// 1 / `telemetry.rate_hz` s, motors-off threshold from the profile's ideal hover power.
pub fn build_adaptation(cfg: &crate::config::Config, names: &[String]) -> anyhow::Result<adapt::Adaptation> {
    let profile = load_profile(cfg)?;
    let payload_kg = f64::from(cfg.mission.payload_g.unwrap_or(0.0)).max(0.0) / 1000.0;
    let hover_w = adapt::ideal_hover_w(profile.mass_kg(payload_kg), profile.air.g_m_s2, profile.air.rho_kg_m3, profile.disk_area_m2());
    Ok(adapt::Adaptation::new(&cfg.models.adapt, names, 1.0 / cfg.telemetry.rate_hz, hover_w))
}

/// The configured vehicle profile, else the built-in M100.
fn load_profile(cfg: &crate::config::Config) -> anyhow::Result<profile::VehicleProfile> {
    match &cfg.vehicle {
        Some(path) => profile::VehicleProfile::load(path),
        None => Ok(profile::VehicleProfile::m100()),
    }
}

/// Every model a configuration runs, in table order: the one place models are listed, so
/// the live ensemble and `dronewatt eval` score exactly the same set.
pub fn build_models(cfg: &crate::config::Config) -> anyhow::Result<Vec<Box<dyn PowerModel>>> {
    let mut models: Vec<Box<dyn PowerModel>> = Vec::new();
    // physics (issue 4): the six models (+ Tseng's Solo form) on the configured vehicle profile.
    let profile = load_profile(cfg)?;
    models.extend(physics::models(&profile));
    // lstm (issue 5): after the physics models, when enabled and found.
    if let Some(m) = lstm::from_config(&cfg.models.lstm, &cfg.telemetry)? {
        models.push(Box::new(m));
    }
    Ok(models)
}
