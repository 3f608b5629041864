//! The model card: everything needed to feed a trained network exactly the inputs it was
//! trained on, and to say how good it is. It lives beside the weights as `card.toml`.
//!
//! A network is only meaningful with the features, their order, their scaling, the
//! resample rate and the window it was trained with; the card records all of them, and
//! [`ModelCard::check`] refuses to run a model whose card disagrees with what the ingest
//! path produces (so a retuned `[telemetry]` never silently feeds a model wrong inputs).

use std::path::Path;

use anyhow::Context;
use serde::{Deserialize, Serialize};

use crate::features::{FEATURE_NAMES, N_FEATURES};
use crate::telemetry::TelemetryConfig;

/// Which inputs the network sees in the three position slots (2, 3, 4 of
/// [`FEATURE_NAMES`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum FeatureSet {
    /// The paper's 21 features as they are: longitude, latitude, altitude above sea level.
    Paper,
    /// Location-invariant: horizontal distance to home (m), height above home (m) and the
    /// climb since the window's first sample (m) replace longitude, latitude and ASL
    /// altitude, which cannot transfer to another site.
    Home,
}

/// Names of the home feature set's three position inputs.
pub const HOME_POSITION_NAMES: [&str; 3] =
    ["home_distance_m", "home_height_m", "climb_in_window_m"];

impl FeatureSet {
    /// The input names, in order, that this feature set feeds the network.
    pub fn names(self) -> Vec<String> {
        let mut names: Vec<String> = FEATURE_NAMES.iter().map(|s| s.to_string()).collect();
        if self == FeatureSet::Home {
            for (i, n) in HOME_POSITION_NAMES.iter().enumerate() {
                names[crate::features::idx::POS_X + i] = n.to_string();
            }
        }
        names
    }
}

/// Which hidden states of the top LSTM layer the dense head reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Readout {
    /// The final forward and backward states (Keras' `Bidirectional(LSTM)`, the paper's):
    /// each has read the whole window, and the instant estimated is implicit.
    #[default]
    Final,
    /// Both directions' states at the estimated instant, `window − 1 − target_lag` (a
    /// fixed-lag smoother's readout): the forward state has read the window up to the
    /// instant, the backward one the samples after it, back to it. The backward pass is
    /// `target_lag + 1` steps instead of the window.
    Instant,
}

impl Readout {
    /// The default: a card that omits `readout` reads the final states.
    pub fn is_final(&self) -> bool {
        *self == Readout::Final
    }
}

/// Which flights `band_widen_w` was calibrated on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BandCalibration {
    /// The card's validation flights (`train`'s default; they also early-stop the members).
    #[default]
    Validation,
    /// The held-out flights of a by-flight cross-validation of the same recipe
    /// (`train --band-from-cv cv.csv`): the mean over the folds of each fold's widening,
    /// floored at 0. Those flights chose nothing, not even an epoch.
    Cv,
}

impl BandCalibration {
    /// The default: a card that omits `band_calibration` was calibrated on its validation
    /// flights.
    pub fn is_validation(&self) -> bool {
        *self == BandCalibration::Validation
    }
}

/// Where the network's weights are and what they are.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum WeightsFormat {
    /// A tch `VarStore` of the built-in BiLSTM (`.safetensors`, PyTorch `nn.LSTM` names).
    Safetensors,
    /// A TorchScript module exported from PyTorch (`torch.jit.save`): input
    /// `[batch, window, features]` standardised, output `[batch, 3]` or `[batch]` of
    /// tanh-scaled power (columns point, low, high).
    Torchscript,
}

/// The model card, `card.toml` beside the weights.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelCard {
    /// Card format version (1).
    pub format: u32,
    /// Model name shown in tables and JSON (`lstm`).
    pub name: String,
    /// Weights file, relative to the card's folder.
    pub weights: String,
    /// An ensemble's further members: weights files beside `weights`, the same network,
    /// inputs and scaling, each trained on the same flights from its own
    /// `train --init-seed`. The estimate and its band are the mean of every member's
    /// outputs, `weights` first. Absent: one network.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub members: Vec<String>,
    /// What the weights file is.
    pub weights_format: WeightsFormat,
    /// Which inputs fill the position slots.
    pub feature_set: FeatureSet,
    /// Input names in the order the network sees them (checked against `feature_set`).
    pub feature_names: Vec<String>,
    /// Resample rate the network was trained at, Hz (must equal `telemetry.rate_hz`).
    pub rate_hz: f64,
    /// Window length T, samples (must equal `telemetry.window`).
    pub window: usize,
    /// Training-set mean of each input (standardisation x' = (x − mean) / std).
    pub feature_mean: Vec<f32>,
    /// Training-set standard deviation of each input (1 where an input was constant).
    pub feature_std: Vec<f32>,
    /// Target scale, W: the network's tanh output times this is power. Chosen as 1.2 × the
    /// largest training power so tanh's range covers the data without saturating.
    pub power_scale_w: f32,
    /// Samples between a window's newest and the instant the estimate is for (0: the
    /// newest, as in the paper). Absent in older cards: 0.
    #[serde(default)]
    pub target_lag: usize,
    /// Which top-layer states the head reads (built-in network only). Absent: `final`.
    #[serde(default, skip_serializing_if = "Readout::is_final")]
    pub readout: Readout,
    /// Nominal quantiles of the band heads (low, high), e.g. (0.05, 0.95).
    pub band_quantiles: (f32, f32),
    /// Watts added on each side of the heads' band: split-conformal calibration (CQR) on the
    /// flights `band_calibration` names, so that the band covers its nominal share
    /// (`band_quantiles`' high − low) of their windows; never negative. Written by `train`
    /// and `train --score-only`; absent in older cards: 0 (the heads' band as trained).
    #[serde(default)]
    pub band_widen_w: f32,
    /// Where `band_widen_w` was calibrated: `validation` (absent: the card's validation
    /// flights) or `cv` (a cross-validation's held-out flights, `train --band-from-cv`).
    #[serde(default, skip_serializing_if = "BandCalibration::is_validation")]
    pub band_calibration: BandCalibration,
    /// Gradient-boosted trees blended with the network ([`TreesBlend`]). Absent: the
    /// network alone.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trees: Option<TreesBlend>,
    /// LSTM hidden cells per direction and layer (built-in network only).
    pub hidden: i64,
    /// Stacked bidirectional LSTM layers (built-in network only).
    pub layers: i64,
    /// How it was trained.
    pub training: TrainingInfo,
    /// How well it does on flights never trained or validated on.
    pub metrics: Option<Metrics>,
    /// The same scores on the validation flights (`training.validation_flights`), which
    /// early-stopped the network and calibrated its band: the figures a choice between
    /// models is made on, the test flights' being scored once.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub validation_metrics: Option<Metrics>,
}

/// `[trees]`: a LightGBM model (its text file, `lab/scripts/lgbm_cv.py fit`) whose estimate
/// is blended with the network's: estimate = w × network + (1 − w) × trees, the band moved
/// by the same amount. The trees read the window's raw inputs (`feature_set`'s, as the
/// network sees them before standardising) at each of `lags`, named `<input>` for lag 0
/// and `<input>_lag<k>` after. Where the window's newest inputs lie outside the network's
/// training range (`feature_mean` ± 6 `feature_std`) the network runs alone: trees are
/// flat outside their data, so they are not trusted there. The trees must estimate the
/// same instant as the network: trained at the card's `target_lag` (`lgbm_cv.py --lag`),
/// which their text model does not record, so it cannot be checked here.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TreesBlend {
    /// LightGBM text model, relative to the card's folder.
    pub file: String,
    /// The network's share w, 0 to 1.
    pub weight_lstm: f64,
    /// Samples before the window's newest whose inputs the trees read, in their order
    /// (0: the newest); each below `window`.
    pub lags: Vec<usize>,
}

impl TreesBlend {
    /// The names of the trees' inputs for `set` at `lags`, in their order: `<input>` at lag
    /// 0, `<input>_lag<k>` after (`train --export-csv`'s header, which the trees are
    /// trained on).
    pub fn input_names(set: FeatureSet, lags: &[usize]) -> Vec<String> {
        let names = set.names();
        lags.iter()
            .flat_map(|&k| {
                names.iter().map(move |n| {
                    if k == 0 {
                        n.clone()
                    } else {
                        format!("{n}_lag{k}")
                    }
                })
            })
            .collect()
    }
}

/// How a model was trained: enough to repeat it.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrainingInfo {
    /// Data file name (not path) and its sha256.
    pub data_file: String,
    pub data_sha256: String,
    /// How windows were built: `ingest` (the live path, `offline::data::load_flights`, the
    /// only loader `train` has).
    pub loader: String,
    /// Random seed (validation split; weights init and batch order unless `init_seed`).
    pub seed: u64,
    /// Seed of the weights init, dropout and batch order when it differs from `seed`
    /// (`train --init-seed`: an ensemble member on `seed`'s validation flights).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub init_seed: Option<u64>,
    pub dropout: f64,
    /// `train --relative-loss`: weight of the relative error in the point estimate's loss
    /// (absent: 0, the absolute loss).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub relative_loss: f64,
    pub learning_rate: f64,
    /// `train --plateau-decay`: the learning rate's factor after 2 epochs without a better
    /// validation MAE (absent: a constant rate).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plateau_decay: Option<f64>,
    pub batch_size: usize,
    /// Epochs run and the epoch whose weights were kept (best validation MAE).
    pub epochs_run: usize,
    pub best_epoch: usize,
    /// Optimiser steps taken.
    pub steps: usize,
    /// Every `stride`-th window of each training flight was used.
    pub stride: usize,
    pub train_windows: usize,
    pub train_flights: Vec<u32>,
    pub validation_flights: Vec<u32>,
    /// Wall time of the training run, s, and where it ran.
    pub train_time_s: f64,
    pub device: String,
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// Scores on held-out flights, in watts and percent: what `eval --all-windows` scores for
/// this model (`offline::metrics::score_over`), pooled over the test flights.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Metrics {
    /// The flights scored: in `metrics` the test flights (never trained or validated on),
    /// in `validation_metrics` the validation flights.
    pub test_flights: Vec<u32>,
    /// Mean absolute error over all test windows, W.
    pub mae_w: f64,
    pub rmse_w: f64,
    /// Mean absolute percentage error over in-flight windows (measured power > 100 W,
    /// `offline::metrics::IN_FLIGHT_W`), %.
    pub mape_in_flight_pct: f64,
    /// Mean over test flights of |∫P̂ − ∫P| / ∫P, %.
    pub energy_error_pct: f64,
    /// Flight 276's MAE, W (the paper's evaluation flight).
    pub flight_276_mae_w: Option<f64>,
    /// Share of test windows whose measured power lies inside the band, %.
    pub band_coverage_pct: f64,
}

impl ModelCard {
    /// Read a card; the error names the file and the key.
    pub fn load(path: &Path) -> anyhow::Result<ModelCard> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("{}: cannot read model card", path.display()))?;
        let card: ModelCard = toml::from_str(&text)
            .map_err(|e| anyhow::anyhow!("{}: {}", path.display(), e.to_string().trim_end()))?;
        card.self_check()
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        Ok(card)
    }

    /// Write the card as TOML.
    pub fn save(&self, path: &Path) -> anyhow::Result<()> {
        let text = toml::to_string_pretty(self).context("serialising the model card")?;
        std::fs::write(path, text)
            .with_context(|| format!("{}: cannot write model card", path.display()))
    }

    /// Internal consistency: lengths and scales.
    fn self_check(&self) -> Result<(), String> {
        if self.format != 1 {
            return Err(format!(
                "format = {}: this dronewatt reads model card format 1",
                self.format
            ));
        }
        for (key, len) in [
            ("feature_names", self.feature_names.len()),
            ("feature_mean", self.feature_mean.len()),
            ("feature_std", self.feature_std.len()),
        ] {
            if len != N_FEATURES {
                return Err(format!("{key} has {len} entries, expected {N_FEATURES}"));
            }
        }
        use crate::validate::{above, in_range};
        for (i, s) in self.feature_std.iter().enumerate() {
            in_range(&format!("feature_std[{i}]"), *s, above(0.0), "")?;
        }
        in_range("power_scale_w", self.power_scale_w, above(0.0), "W")?;
        if let Some(t) = &self.trees {
            if !(0.0..=1.0).contains(&t.weight_lstm) {
                return Err(format!(
                    "trees.weight_lstm = {}: the network's share is 0 to 1",
                    t.weight_lstm
                ));
            }
            if t.lags.is_empty() {
                return Err("trees.lags is empty: the trees read at least one sample".into());
            }
            if let Some(k) = t.lags.iter().find(|k| **k >= self.window) {
                return Err(format!(
                    "trees.lags holds {k}, but a window has {} samples",
                    self.window
                ));
            }
        }
        Ok(())
    }

    /// The window step whose states the head reads: `None` for the final states, else the
    /// estimated instant, `window − 1 − target_lag`.
    pub fn readout_step(&self) -> Option<usize> {
        (self.readout == Readout::Instant).then(|| self.window.saturating_sub(1 + self.target_lag))
    }

    /// Does this card fit what the ingest path produces? The error names the mismatch.
    pub fn check(&self, cfg: &TelemetryConfig) -> Result<(), String> {
        let expected = self.feature_set.names();
        if self.feature_names != expected {
            let i = self
                .feature_names
                .iter()
                .zip(&expected)
                .position(|(a, b)| a != b)
                .unwrap_or(0);
            return Err(format!(
                "feature_names[{i}] is '{}' but dronewatt's {:?} feature set has '{}' there: the model was trained on other inputs",
                self.feature_names.get(i).map(String::as_str).unwrap_or("?"),
                self.feature_set,
                expected[i]
            ));
        }
        if (self.rate_hz - cfg.rate_hz).abs() > 1e-9 {
            return Err(format!(
                "rate_hz = {} but telemetry.rate_hz = {}: the model was trained at another resample rate",
                self.rate_hz, cfg.rate_hz
            ));
        }
        if self.readout == Readout::Instant && self.target_lag >= self.window {
            return Err(format!(
                "readout = \"instant\" needs target_lag ({}) below window ({})",
                self.target_lag, self.window
            ));
        }
        if self.window != cfg.window {
            return Err(format!(
                "window = {} but telemetry.window = {}: the model was trained on windows of another length",
                self.window, cfg.window
            ));
        }
        Ok(())
    }
}
