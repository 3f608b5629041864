//! The stacked bidirectional LSTM power model of the paper (Section 3), in tch/libtorch.
//!
//! Network: x ∈ ℝ^{T×21} (standardised with the training set's mean and std, T = 10 at
//! 10 Hz) → BiLSTM(128) → BiLSTM(128) → the last layer's final forward and backward
//! hidden states, concatenated (ℝ^256, what Keras' `Bidirectional(LSTM(128))` returns) →
//! dropout → dense(256 → 3) → tanh. Column 0 is the point estimate, columns 1 and 2 the
//! band's low and high quantiles (beyond the paper: quantile heads trained with the
//! pinball loss, so the band costs nothing at inference). Power P = tanh(·) × P_scale, with
//! P_scale from the model card (1.2 × the largest training power, so tanh's range covers
//! the data). Trained with Adam on the pinball loss of all three heads (the point head's,
//! at 0.5, is the MAE). A card may set a target lag L: the estimate is then for the sample
//! L steps before the window's newest ([`crate::window::Window::back`]).
//!
//! On the CPU every batch, one window (the live case) or thousands (a replay flat out,
//! `eval`), runs through the batched hand-written forward of [`super::lstm_cpu`]; libtorch
//! runs CUDA and TorchScript models (and is the reference the tests compare against).
//!
//! Variable names follow PyTorch's `nn.LSTM` (`lstm.weight_ih_l0_reverse` …) and
//! `nn.Linear` (`head.weight`), so the same `.safetensors` loads in PyTorch.
//!
//! Where the default model is found (first hit wins):
//! 1. `[models.lstm] path` in the configuration (or `--model`);
//! 2. `config/models/lstm-m100` beside the executable or up to three folders above it
//!    (covers `target/{debug,release}` and `target/*/deps` of a checkout);
//! 3. `config/models/lstm-m100` in the source tree the binary was built from
//!    (`CARGO_MANIFEST_DIR`).

use std::path::{Path, PathBuf};

use anyhow::Context;
use tch::nn::{self, Module, RNN};
use tch::{Device, Kind, Tensor};

use super::card::{FeatureSet, ModelCard, WeightsFormat};
use super::lstm_cpu::CpuLstm;
use super::{PowerModel, Prediction};
use crate::features::{idx, N_FEATURES};
use crate::telemetry::TelemetryConfig;
use crate::window::Window;

/// The default model's folder, relative to a checkout or install root.
pub const DEFAULT_MODEL_DIR: &str = "config/models/lstm-m100";

/// The `[models.lstm]` table.
#[derive(Debug, Clone, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LstmConfig {
    /// Run the LSTM. Default: true (skipped with a warning when no model is found).
    pub enabled: bool,
    /// A model folder (holding `card.toml`), a card, or a weights file with `card.toml`
    /// beside it; relative to the working directory. Default: the shipped model (see the
    /// module docs for the search order).
    pub path: Option<PathBuf>,
}

impl Default for LstmConfig {
    fn default() -> Self {
        Self { enabled: true, path: None }
    }
}

/// The paper's network: two stacked bidirectional LSTM layers, dropout, dense, tanh.
#[derive(Debug)]
pub struct Net {
    lstm: nn::LSTM,
    head: nn::Linear,
    dropout: f64,
}

impl Net {
    /// Build the network's variables under `p` (`p/lstm`, `p/head`).
    pub fn new(p: &nn::Path, hidden: i64, layers: i64, dropout: f64) -> Net {
        let cfg = nn::RNNConfig { num_layers: layers, bidirectional: true, batch_first: true, ..Default::default() };
        let lstm = nn::lstm(p / "lstm", N_FEATURES as i64, hidden, cfg);
        let head = nn::linear(p / "head", 2 * hidden, 3, Default::default());
        Net { lstm, head, dropout }
    }

    /// `x`: `[batch, T, 21]` standardised → `[batch, 3]` tanh-scaled (point, low, high).
    /// `train` turns dropout on.
    pub fn forward_t(&self, x: &Tensor, train: bool) -> Tensor {
        let (_, nn::LSTMState((h, _))) = self.lstm.seq(x);
        let n = h.size()[0];
        // h: [layers × 2, batch, hidden]; the last two are the top layer's forward/backward.
        let last = Tensor::cat(&[h.get(n - 2), h.get(n - 1)], 1);
        self.head.forward(&last.dropout(self.dropout, train)).tanh()
    }
}

/// Append window `w`'s raw (unstandardised) inputs for `set` to `out`: T × 21 values,
/// oldest sample first. A window shorter than `t` is padded with its oldest sample, a
/// longer one keeps its newest `t` samples. Shared by training and inference so the two
/// cannot drift apart.
pub fn push_inputs(w: &Window, set: FeatureSet, t: usize, out: &mut Vec<f32>) {
    let s = &w.samples;
    if s.is_empty() {
        out.extend(std::iter::repeat_n(0.0, t * N_FEATURES));
        return;
    }
    let z0 = s[s.len().saturating_sub(t)].features[idx::POS_Z];
    for k in 0..t {
        let i = (s.len() + k).saturating_sub(t);
        let sample = &s[i];
        let mut f = sample.features;
        if set == FeatureSet::Home {
            let (d, h) = sample.home.map(|h| (h.distance_m, h.height_m)).unwrap_or((0.0, 0.0));
            f[idx::POS_X] = d;
            f[idx::POS_Y] = h;
            f[idx::POS_Z] = sample.features[idx::POS_Z] - z0;
        }
        out.extend_from_slice(&f);
    }
}

enum Backend {
    /// Our own network: on the CPU the hand-written forward ([`CpuLstm`]) for every batch;
    /// libtorch on CUDA (or when asked, [`LstmModel::set_libtorch_only`]).
    Native { _vs: nn::VarStore, net: Net, cpu: Option<Box<CpuLstm>> },
    Script(tch::CModule),
}

/// The LSTM as a [`PowerModel`]: a card, weights, and a scratch buffer.
pub struct LstmModel {
    card: ModelCard,
    backend: Backend,
    device: Device,
    buf: Vec<f32>,
    out: Vec<f32>,
    libtorch_only: bool,
    warned: bool,
}

impl LstmModel {
    /// Load a model from a folder holding `card.toml`, a card file, or a weights file with
    /// `card.toml` beside it, and check the card against the ingest path's settings.
    pub fn load(path: &Path, cfg: &TelemetryConfig) -> anyhow::Result<LstmModel> {
        let (card_path, weights_override) = if path.is_dir() {
            (path.join("card.toml"), None)
        } else if path.extension().is_some_and(|e| e == "toml") {
            (path.to_path_buf(), None)
        } else {
            (path.with_file_name("card.toml"), Some(path.to_path_buf()))
        };
        let card = ModelCard::load(&card_path)?;
        card.check(cfg).map_err(|e| anyhow::anyhow!("{}: model card does not match the ingest path: {e}", card_path.display()))?;
        let dir = card_path.parent().unwrap_or(Path::new("."));
        let weights = weights_override.unwrap_or_else(|| dir.join(&card.weights));
        let device = Device::cuda_if_available();
        let backend = match card.weights_format {
            WeightsFormat::Safetensors => {
                let mut vs = nn::VarStore::new(device);
                let net = Net::new(&vs.root(), card.hidden, card.layers, card.training.dropout);
                vs.load(&weights).with_context(|| format!("{}: cannot load LSTM weights", weights.display()))?;
                let cpu = if device == Device::Cpu { CpuLstm::from_var_store(&vs, card.layers as usize, card.hidden as usize).map(Box::new) } else { None };
                Backend::Native { _vs: vs, net, cpu }
            }
            WeightsFormat::Torchscript => {
                let mut m = tch::CModule::load_on_device(&weights, device)
                    .with_context(|| format!("{}: cannot load TorchScript module", weights.display()))?;
                m.set_eval();
                Backend::Script(m)
            }
        };
        Ok(LstmModel { card, backend, device, buf: Vec::new(), out: Vec::new(), libtorch_only: false, warned: false })
    }

    /// Run every batch on libtorch, never the hand-written forward (benchmarks, checks).
    pub fn set_libtorch_only(&mut self, on: bool) {
        self.libtorch_only = on;
    }

    /// The card this model was loaded with.
    pub fn card(&self) -> &ModelCard {
        &self.card
    }

    /// Run the network on `windows` (one batch); rows of `[point, low, high]` in watts.
    pub fn forward_w(&mut self, windows: &[Window]) -> anyhow::Result<Vec<[f32; 3]>> {
        let t = self.card.window;
        self.buf.clear();
        for w in windows {
            let start = self.buf.len();
            push_inputs(w, self.card.feature_set, t, &mut self.buf);
            for (i, v) in self.buf[start..].iter_mut().enumerate() {
                let f = i % N_FEATURES;
                *v = (*v - self.card.feature_mean[f]) / self.card.feature_std[f];
            }
        }
        let b = windows.len();
        self.out.clear();
        let cols = match &mut self.backend {
            Backend::Native { cpu: Some(cpu), .. } if !self.libtorch_only => {
                let cols = cpu.outputs();
                self.out.resize(b * cols, 0.0);
                cpu.forward_batch(&self.buf, t, &mut self.out);
                cols
            }
            backend => {
                let x = Tensor::from_slice(&self.buf).view([b as i64, t as i64, N_FEATURES as i64]).to_device(self.device);
                let y = tch::no_grad(|| match backend {
                    Backend::Native { net, .. } => Ok(net.forward_t(&x, false)),
                    Backend::Script(m) => m.forward_ts(&[&x]),
                })?;
                let y = y.to_device(Device::Cpu).to_kind(Kind::Float).contiguous();
                self.out = Vec::<f32>::try_from(y.view([-1]))?;
                if y.dim() == 2 { y.size()[1] as usize } else { 1 }
            }
        };
        let s = self.card.power_scale_w;
        Ok(self
            .out
            .chunks(cols)
            .map(|r| {
                let p = r[0] * s;
                if r.len() >= 3 {
                    [p, (r[1] * s).min(p), (r[2] * s).max(p)]
                } else {
                    [p, p, p]
                }
            })
            .collect())
    }
}

/// How far outside its training data (in training standard deviations) an input may lie
/// for a window to still teach online adaptation ([`super::adapt`]).
pub const TRAINING_RANGE_SIGMAS: f32 = 6.0;

impl PowerModel for LstmModel {
    fn name(&self) -> &str {
        &self.card.name
    }

    fn target_lag(&self) -> usize {
        self.card.target_lag
    }

    /// False when an input of the window's newest sample lies more than
    /// [`TRAINING_RANGE_SIGMAS`] training standard deviations from the training mean.
    fn in_training_range(&self, window: &Window) -> bool {
        let mut x = Vec::with_capacity(N_FEATURES);
        push_inputs(window, self.card.feature_set, 1, &mut x);
        x.iter().zip(&self.card.feature_mean).zip(&self.card.feature_std).all(|((v, m), s)| {
            let z = (v - m) / s;
            z.is_finite() && z.abs() <= TRAINING_RANGE_SIGMAS
        })
    }

    fn predict(&mut self, windows: &[Window], out: &mut Vec<Prediction>) {
        out.clear();
        if windows.is_empty() {
            return;
        }
        match self.forward_w(windows) {
            Ok(rows) if rows.len() == windows.len() => out.extend(rows.iter().map(|r| Prediction {
                power_w: r[0],
                band_w: (r[1] != r[2]).then_some((r[1], r[2])),
            })),
            other => {
                if !self.warned {
                    let why = other.err().map(|e| format!("{e:#}")).unwrap_or_else(|| "wrong output size".into());
                    tracing::warn!("lstm: inference failed, emitting NaN: {why}");
                    self.warned = true;
                }
                out.extend(windows.iter().map(|_| Prediction { power_w: f32::NAN, band_w: None }));
            }
        }
    }
}

/// Find the model to load: the configured path, else the shipped model (search order in
/// the module docs). `None` when no shipped model is found.
pub fn resolve_model_path(configured: Option<&Path>) -> Option<PathBuf> {
    if let Some(p) = configured {
        return Some(p.to_path_buf());
    }
    let mut candidates = Vec::new();
    if let Ok(exe) = std::env::current_exe() {
        for dir in exe.ancestors().skip(1).take(4) {
            candidates.push(dir.join(DEFAULT_MODEL_DIR));
        }
    }
    candidates.push(Path::new(env!("CARGO_MANIFEST_DIR")).join(DEFAULT_MODEL_DIR));
    candidates.into_iter().find(|c| c.join("card.toml").is_file())
}

/// The LSTM a configuration asks for, or `None` when it is disabled or (default path
/// only) no shipped model is found. A configured path that fails, or a card that does not
/// match `telemetry`, is an error.
pub fn from_config(cfg: &LstmConfig, telemetry: &TelemetryConfig) -> anyhow::Result<Option<LstmModel>> {
    if !cfg.enabled {
        return Ok(None);
    }
    // One intra-op thread: this network is small, and at batch 1 libtorch's thread pool
    // costs more than it gains (20× slower measured on a busy 2-core machine).
    tch::set_num_threads(1);
    match resolve_model_path(cfg.path.as_deref()) {
        Some(p) => Ok(Some(LstmModel::load(&p, telemetry)?)),
        None => {
            tracing::warn!("lstm: no model found (looked for {DEFAULT_MODEL_DIR} near the executable and the source tree); running without it");
            Ok(None)
        }
    }
}
