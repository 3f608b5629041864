//! Power models: a window (and the vehicle profile a model was built with) in, watts out.
//! Pure: no I/O, no clocks.

pub mod adapt;
pub mod card;
pub mod lstm;
pub mod lstm_cpu;
pub mod physics;
pub mod profile;
pub mod spec;
pub mod stuck;
pub mod trees;

use crate::features::Lift;
use crate::report::{Estimate, ModelEstimate};
use crate::telemetry::window::Window;

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
    /// Whether `window` lies inside what the model was fitted on, so that online adaptation
    /// ([`adapt`]) may learn from it. Default true (the physics models have no training
    /// range); the LSTM says false for a window far outside its training data.
    fn in_training_range(&self, _window: &Window) -> bool {
        true
    }
    /// What carries the vehicle when this model applies ([`Lift`]): `Rotor` for the
    /// multirotor models and the LSTM (the default), `Wing` for the fixed-wing model. A
    /// model runs only on windows whose newest sample flies on its lift
    /// ([`crate::features::VehicleKind::lift`]), so an estimate's `models` hold only
    /// the models that apply to the vehicle's class (none for a rover, boat or sub).
    fn lift(&self) -> Lift {
        Lift::Rotor
    }
    /// The least measured power, W, at which online adaptation may learn from a window of
    /// this model (the motors turn); `None`: the adaptation's own threshold (a share of the
    /// profile's ideal hover power, made for rotors).
    fn min_teach_w(&self) -> Option<f64> {
        None
    }
    /// For a model linear in its own regressors: the regressors φ at the window's newest
    /// sample and the model's own coefficients θ₀ (its prediction is θ₀·φ), so that online
    /// adaptation fits θ itself ([`adapt::regression`]); `None` (the default) where the
    /// model is not, or not for this window.
    fn regressors(&self, _window: &Window) -> Option<([f64; 4], [f64; 4])> {
        None
    }
}

/// The set of models the inference stage runs side by side.
pub struct Ensemble {
    models: Vec<Box<dyn PowerModel>>,
    scratch: Vec<Prediction>,
    /// Online adaptation to measured power, when on ([`Ensemble::with_adaptation`]): the
    /// state every vehicle starts from.
    adapt: Option<adapt::Adaptation>,
    /// Each vehicle's adaptation, by network and system id: a fleet's vehicles share the
    /// models, never what the models learned about each of them.
    adapted: std::collections::BTreeMap<crate::report::VehicleId, adapt::Adaptation>,
    /// Models (by index, a bit each) whose negative prediction was said ([`no_negative`]).
    negative_said: u64,
    /// Figures for the operator: none negative ([`Ensemble::shown_to_operators`]).
    for_operators: bool,
}

/// A power drawn from the pack is never negative: a model's figure under 0 W (the LSTM on
/// the ground can say −3.4 W) is shown as 0 W, and why is said once per model. What the
/// adaptation learns from stays the model's own figure, and the offline scoring
/// ([`build_ensemble`]) scores the models' own figures (clamped, the LSTM's energy error on
/// flight 276 over all windows moves from under 2.0 % to 2.05 %).
fn no_negative(said: &mut u64, i: usize, name: &str, w: f32) -> f32 {
    if w >= 0.0 || w.is_nan() {
        return w;
    }
    if *said & (1 << (i % 64)) == 0 {
        *said |= 1 << (i % 64);
        tracing::info!(
            "{name} predicted {w:.1} W: shown as 0 W (a pack's power is never negative; the model is outside what it learned, usually on the ground)"
        );
    }
    0.0
}

impl Ensemble {
    /// An ensemble of these models, run in this order.
    pub fn new(models: Vec<Box<dyn PowerModel>>) -> Self {
        Self {
            models,
            scratch: Vec::new(),
            adapt: None,
            adapted: Default::default(),
            negative_said: 0,
            for_operators: false,
        }
    }
    /// Figures for the operator (live and replayed flights): a model's negative power is
    /// shown as 0 W and said, once per model.
    pub fn shown_to_operators(mut self) -> Self {
        self.for_operators = true;
        self
    }
    /// Adapt every model's output to measured power ([`adapt`]).
    pub fn with_adaptation(mut self, adaptation: adapt::Adaptation) -> Self {
        self.adapt = Some(adaptation);
        self
    }
    /// Vehicle `vehicle`'s adaptation, when adaptation is on (the starting state before its
    /// first window).
    pub fn adaptation(&self, vehicle: crate::report::VehicleId) -> Option<&adapt::Adaptation> {
        self.adapted.get(&vehicle).or(self.adapt.as_ref())
    }
    /// Vehicle `vehicle`'s adaptation, to restore what an earlier flight learned or to
    /// start a new flight afresh.
    pub fn adaptation_mut(
        &mut self,
        vehicle: crate::report::VehicleId,
    ) -> Option<&mut adapt::Adaptation> {
        let start = self.adapt.as_ref()?;
        Some(self.adapted.entry(vehicle).or_insert_with(|| start.clone()))
    }
    /// Names of the [`PowerModel::heavy`] models, in order.
    pub fn heavy_names(&self) -> Vec<String> {
        self.models
            .iter()
            .filter(|m| m.heavy())
            .map(|m| m.name().to_string())
            .collect()
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
    /// Run every model on every window of one vehicle (the default vehicle of the adaptation; a batch
    /// when a replay runs flat out).
    pub fn estimate(&mut self, windows: &[Window]) -> Vec<Estimate> {
        self.estimate_some(windows, &[], &[])
    }

    /// [`Ensemble::estimate`], but the [`PowerModel::heavy`] models run only on the windows
    /// whose `heavy[i]` is true (all of them where `heavy` is shorter than `windows`); the
    /// others' estimates lack those models. Window `i` is vehicle `vehicles[i]`'s (the default where
    /// `vehicles` is shorter): it teaches and reads that vehicle's adaptation.
    pub fn estimate_some(
        &mut self,
        windows: &[Window],
        heavy: &[bool],
        vehicles: &[crate::report::VehicleId],
    ) -> Vec<Estimate> {
        let mut out: Vec<Estimate> = windows
            .iter()
            .map(|w| Estimate {
                t_s: w.t_s(),
                sample: w.last().clone(),
                models: Vec::with_capacity(self.models.len()),
                arrived: w.arrived,
            })
            .collect();
        let all = heavy.len() < windows.len() || heavy.iter().all(|&h| h);
        let mut picked = Vec::new();
        let mut at = Vec::new();
        for (i, m) in self.models.iter_mut().enumerate() {
            // The windows this model runs on (indices into `windows`): those of its
            // airframe, and for a heavy model those picked for it.
            at.clear();
            let lift = m.lift();
            let fits = |k: usize| windows[k].last().vehicle.lift() == lift;
            let every = (!m.heavy() || all) && (0..windows.len()).all(fits);
            if every {
                at.extend(0..windows.len());
                m.predict(windows, &mut self.scratch);
            } else {
                at.extend(
                    (0..windows.len()).filter(|&k| fits(k) && (!m.heavy() || all || heavy[k])),
                );
                if at.is_empty() {
                    continue;
                }
                picked.clear();
                picked.extend(at.iter().map(|&k| windows[k].clone()));
                m.predict(&picked, &mut self.scratch);
            }
            let lag = m.target_lag();
            for (&k, p) in at.iter().zip(&self.scratch) {
                let (shown, band) = if self.for_operators {
                    let band = p.band_w.map(|(lo, hi)| (lo.max(0.0), hi.max(0.0)));
                    (
                        no_negative(&mut self.negative_said, i, m.name(), p.power_w),
                        band,
                    )
                } else {
                    (p.power_w, p.band_w)
                };
                let mut me = ModelEstimate::new(m.name(), shown, band);
                if let Some(start) = &self.adapt {
                    let w = &windows[k];
                    let vehicle = vehicles.get(k).copied().unwrap_or_default();
                    let ad = self.adapted.entry(vehicle).or_insert_with(|| start.clone());
                    // The prediction is for the sample `lag` back: teach with its power.
                    let measured = w.back(lag).measured_w;
                    let in_range = measured.is_some() && m.in_training_range(w);
                    // A model with its own regression: that fitted first, the affine fit on
                    // top of its (out-of-sample) prediction.
                    let p_in = match m.regressors(w) {
                        Some((phi, theta0)) => {
                            let floor = m.min_teach_w().unwrap_or(ad.min_teach_w());
                            let motor = measured.is_some_and(|y| f64::from(y) >= floor);
                            ad.regress(i, &phi, theta0, measured, in_range && motor) as f32
                        }
                        None => p.power_w,
                    };
                    if let Some(a) = ad.step_from(i, p_in, measured, in_range, m.min_teach_w()) {
                        me.adapted_w = Some(if self.for_operators {
                            a.adapted_w.max(0.0)
                        } else {
                            a.adapted_w
                        });
                        me.reference_w = Some(a.reference_w);
                        me.adapted_err = a.err_w.map(|err_w| crate::report::AdaptedError {
                            err_w,
                            evidence_s: a.evidence_s,
                        });
                    }
                }
                out[k].models.push(me);
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

/// Work that needs libtorch (training, TorchScript models), asked of `dronewatt`, which
/// does not load it. The command line answers it by handing the whole command to
/// `dronewatt-torch` (crate `torch/`), which registers the libtorch parts at start.
#[derive(Debug, thiserror::Error)]
#[error("{what} needs libtorch, which `dronewatt` does not load: run the command with `dronewatt-torch` (`cargo build --workspace` builds it beside `dronewatt`)")]
pub struct NeedsLibtorch {
    /// What asked for it.
    pub what: String,
}

/// A vehicle profile read once at start (the configured file, else the built-in M100), with
/// the file it came from: what every stage that needs the vehicle is handed, so that no stage
/// reads the file again.
#[derive(Debug, Clone)]
pub struct LoadedProfile {
    pub profile: std::sync::Arc<profile::VehicleProfile>,
    /// The file (None: the built-in M100); what the profile names (its LSTM) is relative to it.
    pub path: Option<std::path::PathBuf>,
}

impl LoadedProfile {
    /// Read `vehicle` (a read or parse error names the file), else the built-in M100.
    pub fn load(vehicle: Option<&std::path::Path>) -> anyhow::Result<Self> {
        Ok(Self {
            profile: std::sync::Arc::new(load_profile(vehicle)?),
            path: vehicle.map(std::path::Path::to_path_buf),
        })
    }
}

/// The models a configuration asks for, built and checked (profiles loaded, cards matched),
/// adapting to measured power unless `[models.adapt] enabled = false`. `payload_g` is the
/// mission's configured payload (the motors-off threshold of adaptation is the loaded
/// vehicle's ideal hover power). The profile file is read once.
pub fn build_ensemble(
    models: &ModelsConfig,
    vehicle: Option<&std::path::Path>,
    telemetry: &crate::telemetry::TelemetryConfig,
    payload_g: Option<f32>,
) -> anyhow::Result<Ensemble> {
    let vehicle = LoadedProfile::load(vehicle)?;
    ensemble_of(
        models_for(models, &vehicle, telemetry)?,
        models,
        &vehicle.profile,
        telemetry,
        payload_g,
    )
}

/// [`build_ensemble`] and the fixed-wing model after it (profile `[fixed_wing]`, else a
/// generic 2 kg foam plane): what a live or replayed vehicle runs, whatever its class
/// turns out to be. Each model runs only on the windows of its lift ([`PowerModel::lift`]).
/// The offline scoring of the M100 data set (`eval`, `offline::chain`) keeps
/// [`build_ensemble`]: its columns are every model on every window.
pub fn build_live_ensemble(
    models: &ModelsConfig,
    vehicle: &LoadedProfile,
    telemetry: &crate::telemetry::TelemetryConfig,
    payload_g: Option<f32>,
) -> anyhow::Result<Ensemble> {
    let mut list = models_for(models, vehicle, telemetry)?;
    let wing = vehicle.profile.fixed_wing.unwrap_or_default();
    wing.validate().map_err(anyhow::Error::msg)?;
    list.push(Box::new(physics::fixed_wing::FixedWing::new(wing)));
    Ok(ensemble_of(list, models, &vehicle.profile, telemetry, payload_g)?.shown_to_operators())
}

fn ensemble_of(
    list: Vec<Box<dyn PowerModel>>,
    models: &ModelsConfig,
    vehicle: &profile::VehicleProfile,
    telemetry: &crate::telemetry::TelemetryConfig,
    payload_g: Option<f32>,
) -> anyhow::Result<Ensemble> {
    let ensemble = Ensemble::new(list);
    if !models.adapt.enabled {
        return Ok(ensemble);
    }
    let adaptation = adaptation_for(
        &models.adapt,
        vehicle,
        telemetry,
        payload_g,
        &ensemble.names(),
    )?;
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
    let profile = load_profile(vehicle)?;
    adaptation_for(cfg, &profile, telemetry, payload_g, names)
}

/// [`build_adaptation`] on a profile already loaded.
pub fn adaptation_for(
    cfg: &adapt::AdaptConfig,
    profile: &profile::VehicleProfile,
    telemetry: &crate::telemetry::TelemetryConfig,
    payload_g: Option<f32>,
    names: &[String],
) -> anyhow::Result<adapt::Adaptation> {
    cfg.validate().map_err(anyhow::Error::msg)?;
    let payload_kg = f64::from(payload_g.unwrap_or(0.0)).max(0.0) / 1000.0;
    let hover_w = adapt::ideal_hover_w(
        profile.mass_kg(payload_kg),
        profile.air.g_m_s2,
        profile.air.rho_kg_m3,
        profile.disk_area_m2(),
    );
    Ok(adapt::Adaptation::new(
        cfg,
        names,
        1.0 / telemetry.rate_hz,
        hover_w,
    ))
}

/// The vehicle profile file, else the built-in M100.
pub fn load_profile(vehicle: Option<&std::path::Path>) -> anyhow::Result<profile::VehicleProfile> {
    match vehicle {
        Some(path) => profile::VehicleProfile::load(path),
        None => Ok(profile::VehicleProfile::m100()),
    }
}

/// Every model a configuration runs, in table order: the one place models are listed, so
/// the live ensemble and `dronewatt-lab eval` score exactly the same set. `vehicle` is the
/// profile file (`vehicle` in the TOML; the built-in M100 without one); `telemetry` is
/// checked against the LSTM's card (rate and window must match what it was trained on).
pub fn build_models(
    models: &ModelsConfig,
    vehicle: Option<&std::path::Path>,
    telemetry: &crate::telemetry::TelemetryConfig,
) -> anyhow::Result<Vec<Box<dyn PowerModel>>> {
    models_for(models, &LoadedProfile::load(vehicle)?, telemetry)
}

/// [`build_models`] on a profile already loaded.
pub fn models_for(
    models: &ModelsConfig,
    vehicle: &LoadedProfile,
    telemetry: &crate::telemetry::TelemetryConfig,
) -> anyhow::Result<Vec<Box<dyn PowerModel>>> {
    let mut out: Vec<Box<dyn PowerModel>> = Vec::new();
    // The physics models (+ Tseng's Solo form) on the configured vehicle profile.
    let profile = &vehicle.profile;
    out.extend(physics::models(profile));
    // The LSTM after the physics models, when enabled and found: the configured one, else
    // the one fine-tuned for the vehicle profile (relative to the profile file), else the
    // shipped one.
    let mut lstm_cfg = models.lstm.clone();
    if let (None, Some(dir), Some(path)) = (&lstm_cfg.path, &profile.lstm, &vehicle.path) {
        lstm_cfg.path = Some(crate::files::relative_to(path, dir));
    }
    if let Some(m) = lstm::from_config(&lstm_cfg, telemetry)? {
        out.push(Box::new(m));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_negative_prediction_is_shown_as_zero_and_said_once_per_model() {
        let mut said = 0;
        assert_eq!(super::no_negative(&mut said, 0, "lstm", -3.4), 0.0);
        assert_eq!(said, 1);
        assert_eq!(super::no_negative(&mut said, 0, "lstm", -1.0), 0.0);
        assert_eq!(said, 1, "said once");
        assert_eq!(super::no_negative(&mut said, 2, "bem", -0.5), 0.0);
        assert_eq!(said, 0b101);
        assert_eq!(super::no_negative(&mut said, 1, "x", 168.3), 168.3);
        assert_eq!(super::no_negative(&mut said, 1, "x", 0.0), 0.0);
        assert!(super::no_negative(&mut said, 1, "x", f32::NAN).is_nan());
    }
}
