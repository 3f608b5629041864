//! The stacked bidirectional LSTM power model of the paper (Section 3).
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
//! L steps before the window's newest ([`crate::telemetry::window::Window::back`]). A card
//! may also set `readout = "instant"`: the head then reads the top layer's forward and
//! backward states at that instant instead of the final ones
//! ([`super::card::Readout`]).
//!
//! The cell count is the card's `hidden` (the paper: 128), and a card may list an
//! ensemble's further `members`: networks trained on the same flights from other initial
//! weights, whose outputs (point and band) are averaged. The shipped model is an ensemble of
//! three 64-cell networks.
//!
//! A card may blend gradient-boosted trees in (`[trees]`, [`super::card::TreesBlend`],
//! evaluated by [`super::trees`]): the estimate is then w × network + (1 − w) × trees, the
//! band moved with it, except where the window is not [`PowerModel::in_training_range`],
//! where the network runs alone.
//!
//! Every batch, one window (the live case) or thousands (a replay flat out, `eval`), runs
//! through the batched hand-written forward of [`super::lstm_cpu`], with no libtorch in
//! the process: `dronewatt` starts in milliseconds. TorchScript models, CUDA and training
//! need libtorch: the `dronewatt-torch` binary (crate `torch/`) registers an
//! [`ExternalLoader`] for them ([`set_external_loader`]), and `dronewatt` hands such work
//! to it ([`super::NeedsLibtorch`]). The network itself, in tch, is `dronewatt_torch::Net` (the
//! reference the kernel is tested against).
//!
//! Variable names follow PyTorch's `nn.LSTM` (`lstm.weight_ih_l0_reverse` …) and
//! `nn.Linear` (`head.weight`), so the same `.safetensors` loads in PyTorch.
//!
//! Where the default model is found (first hit wins):
//! 1. `[models.lstm] path` in the configuration (or `--model`);
//! 2. the shipped model, through the one resolver ([`crate::assets::model_dir`]):
//!    `config/models/lstm-m100` beside the executable or up to three folders above it
//!    (covers `target/{debug,release}` and `target/*/deps` of a checkout), else the copy
//!    compiled into the binary; never the current directory.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use anyhow::Context;

use super::card::{FeatureSet, ModelCard, TreesBlend, WeightsFormat};
use super::lstm_cpu::CpuLstm;
use super::{PowerModel, Prediction};
use crate::features::{idx, N_FEATURES};
use crate::telemetry::window::Window;
use crate::telemetry::TelemetryConfig;

/// The default model's folder, relative to a checkout or install root.
pub const DEFAULT_MODEL_DIR: &str = "config/models/lstm-m100";

/// The paper's network (one, 128 cells), shipped before the ensemble: what `learn
/// --fine-tune` starts from unless told otherwise (one network to tune, and the one whose
/// fine-tuning on other airframes was measured).
pub const PAPER_MODEL_DIR: &str = "config/models/lstm-m100-h128";

/// The `[models.lstm]` table.
#[derive(Debug, Clone, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LstmConfig {
    /// Run the LSTM. Default: true (skipped with a warning when no model is found).
    pub enabled: bool,
    /// A model folder (holding `card.toml`), a card, or a weights file with `card.toml`
    /// beside it; relative to the config file. Default: the shipped model (see the
    /// module docs for the search order).
    pub path: Option<PathBuf>,
}

impl Default for LstmConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            path: None,
        }
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
            let (d, h) = sample
                .home
                .map(|h| (h.distance_m, h.height_m))
                .unwrap_or((0.0, 0.0));
            f[idx::POS_X] = d;
            f[idx::POS_Y] = h;
            f[idx::POS_Z] = sample.features[idx::POS_Z] - z0;
        }
        out.extend_from_slice(&f);
    }
}

/// A network run outside the hand-written kernel (libtorch: TorchScript, CUDA), supplied
/// by `dronewatt-torch`.
pub trait ExternalNet: Send {
    /// Forward `b` standardised windows (`x`: `[b][t][21]`, row-major) → the outputs,
    /// row-major, and the number of columns (3: point, low, high; 1: point only).
    fn forward(&mut self, x: &[f32], b: usize, t: usize) -> anyhow::Result<(Vec<f32>, usize)>;
    /// What runs it, for the log (e.g. "libtorch TorchScript on Cpu").
    fn describe(&self) -> String;
}

/// Loads a model the kernel cannot run (TorchScript), or claims one it could (CUDA);
/// `Ok(None)` leaves it to the kernel.
pub type ExternalLoader =
    fn(weights: &Path, card: &ModelCard) -> anyhow::Result<Option<Box<dyn ExternalNet>>>;

static EXTERNAL: OnceLock<ExternalLoader> = OnceLock::new();

/// Register the loader of external networks (once per process; `dronewatt-torch` calls it
/// at start). Later calls are ignored.
pub fn set_external_loader(loader: ExternalLoader) {
    let _ = EXTERNAL.set(loader);
}

enum Backend {
    /// The hand-written batched forward ([`CpuLstm`]).
    Kernel(Box<CpuLstm>),
    /// A network on libtorch.
    External(Box<dyn ExternalNet>),
}

impl Backend {
    /// The network's raw outputs for `b` standardised windows `x` into `out`; the columns a
    /// row.
    fn forward(
        &mut self,
        x: &[f32],
        b: usize,
        t: usize,
        out: &mut Vec<f32>,
    ) -> anyhow::Result<usize> {
        out.clear();
        Ok(match self {
            Backend::Kernel(cpu) => {
                let cols = cpu.outputs();
                out.resize(b * cols, 0.0);
                cpu.forward_batch(x, t, out);
                cols
            }
            Backend::External(net) => {
                let (o, cols) = net.forward(x, b, t)?;
                anyhow::ensure!(
                    cols > 0 && o.len() == b * cols,
                    "{}: {} outputs for {b} windows",
                    net.describe(),
                    o.len()
                );
                *out = o;
                cols
            }
        })
    }
}

/// The LSTM as a [`PowerModel`]: a card, weights, and a scratch buffer.
pub struct LstmModel {
    card: ModelCard,
    /// One network, or an ensemble's members (`card.members`), whose outputs are averaged.
    backends: Vec<Backend>,
    buf: Vec<f32>,
    sum: Vec<f32>,
    warned: bool,
    /// The card's trees, when it blends them in.
    trees: Option<Blend>,
    /// The raw inputs the trees read, and each member's outputs (scratch of the forward).
    raw: Vec<f32>,
    outs: Vec<Vec<f32>>,
}

/// Trees blended with the network (the card's `[trees]`), and their scratch.
struct Blend {
    trees: super::trees::Trees,
    weight: f32,
    lags: Vec<usize>,
    /// Each window's tree estimate, NaN where the network runs alone.
    est: Vec<f32>,
    row: Vec<f64>,
    newest: Vec<f32>,
    /// Whether the log has said that the trees sat a window out (outside the training range).
    told: bool,
}

#[path = "lstm_forward.rs"]
mod forward;
pub use forward::PARALLEL_WINDOWS;

/// The samples the card's trees read from one window's raw inputs (`push_inputs`: rows of
/// 21, newest last): for each of `lags`, the row that many before the newest (the oldest
/// where the window is shorter), in order. `train --export-csv` writes the same rows.
pub fn tree_rows<'a>(inputs: &'a [f32], lags: &'a [usize]) -> impl Iterator<Item = &'a [f32]> + 'a {
    let rows = inputs.len() / N_FEATURES;
    lags.iter().filter(move |_| rows > 0).map(move |&lag| {
        let r = rows - 1 - lag.min(rows - 1);
        &inputs[r * N_FEATURES..(r + 1) * N_FEATURES]
    })
}

/// Whether every raw input of one sample lies within [`TRAINING_RANGE_SIGMAS`] of the
/// card's training mean.
fn within_training_range(card: &ModelCard, x: &[f32]) -> bool {
    x.iter()
        .zip(&card.feature_mean)
        .zip(&card.feature_std)
        .all(|((v, m), s)| {
            let z = (v - m) / s;
            z.is_finite() && z.abs() <= TRAINING_RANGE_SIGMAS
        })
}

impl LstmModel {
    /// Load a model from a folder holding `card.toml`, a card file, or a weights file with
    /// `card.toml` beside it, and check the card against the ingest path's settings. A
    /// registered [`ExternalLoader`] gets the first say.
    pub fn load(path: &Path, cfg: &TelemetryConfig) -> anyhow::Result<LstmModel> {
        Self::load_with(path, cfg, EXTERNAL.get().copied())
    }

    /// [`Self::load`] with this loader (or none: the kernel only).
    pub fn load_with(
        path: &Path,
        cfg: &TelemetryConfig,
        external: Option<ExternalLoader>,
    ) -> anyhow::Result<LstmModel> {
        let (card_path, weights_override) = if path.is_dir() {
            (path.join("card.toml"), None)
        } else if path.extension().is_some_and(|e| e == "toml") {
            (path.to_path_buf(), None)
        } else {
            (path.with_file_name("card.toml"), Some(path.to_path_buf()))
        };
        let card = ModelCard::load(&card_path)?;
        card.check(cfg).map_err(|e| {
            anyhow::anyhow!(
                "{}: model card does not match the ingest path: {e}",
                card_path.display()
            )
        })?;
        let dir = card_path.parent().unwrap_or(Path::new("."));
        // A weights file named on its own runs alone; a folder or card runs every member.
        let files: Vec<PathBuf> = match &weights_override {
            Some(w) => vec![w.clone()],
            None => std::iter::once(&card.weights)
                .chain(&card.members)
                .map(|m| dir.join(m))
                .collect(),
        };
        let mut backends = Vec::with_capacity(files.len());
        for weights in &files {
            backends.push(Self::backend(weights, &card, external)?);
        }
        if backends.len() > 1 {
            tracing::info!("lstm: an ensemble of {} members", backends.len());
        }
        // A weights file named on its own is that network alone, without the trees.
        let trees = match (&card.trees, &weights_override) {
            (Some(t), None) => Some(Self::load_trees(t, &card, dir)?),
            _ => None,
        };
        Ok(LstmModel {
            card,
            backends,
            buf: Vec::new(),
            sum: Vec::new(),
            warned: false,
            trees,
            raw: Vec::new(),
            outs: Vec::new(),
        })
    }

    /// The card's trees, checked against the inputs the card names.
    fn load_trees(t: &TreesBlend, card: &ModelCard, dir: &Path) -> anyhow::Result<Blend> {
        let path = dir.join(&t.file);
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("{}: cannot read the card's trees", path.display()))?;
        let trees = super::trees::Trees::parse(&text)
            .with_context(|| format!("{}: not a model dronewatt can run", path.display()))?;
        let want = TreesBlend::input_names(card.feature_set, &t.lags);
        if trees.feature_names() != want.as_slice() {
            let i = trees
                .feature_names()
                .iter()
                .zip(&want)
                .position(|(a, b)| a != b)
                .unwrap_or(want.len().min(trees.feature_names().len()));
            anyhow::bail!(
                "{}: input {i} is '{}' but the card's {:?} inputs at lags {:?} have '{}' there ({} inputs, expected {})",
                path.display(),
                trees.feature_names().get(i).map(String::as_str).unwrap_or("none"),
                card.feature_set,
                t.lags,
                want.get(i).map(String::as_str).unwrap_or("none"),
                trees.feature_names().len(),
                want.len()
            );
        }
        tracing::info!(
            "lstm: blends {} trees ({}), the network's share {}",
            trees.len(),
            path.display(),
            t.weight_lstm
        );
        Ok(Blend {
            trees,
            weight: t.weight_lstm as f32,
            lags: t.lags.clone(),
            est: Vec::new(),
            row: Vec::new(),
            newest: Vec::new(),
            told: false,
        })
    }

    /// The network in `weights`: a registered external loader's when it claims it, else the
    /// kernel's.
    fn backend(
        weights: &Path,
        card: &ModelCard,
        external: Option<ExternalLoader>,
    ) -> anyhow::Result<Backend> {
        let claimed = match external {
            Some(load) => load(weights, card)?,
            None => None,
        };
        Ok(match (claimed, card.weights_format) {
            (Some(net), _) => {
                tracing::info!("lstm: {} runs on {}", weights.display(), net.describe());
                Backend::External(net)
            }
            (None, WeightsFormat::Safetensors) => {
                let (layers, hidden) =
                    (usize::try_from(card.layers)?, usize::try_from(card.hidden)?);
                let mut k = CpuLstm::from_safetensors(weights, layers, hidden)?;
                k.set_readout(card.readout_step());
                Backend::Kernel(Box::new(k))
            }
            (None, WeightsFormat::Torchscript) => {
                return Err(super::NeedsLibtorch {
                    what: format!("{}: a TorchScript model", weights.display()),
                }
                .into())
            }
        })
    }

    /// Whether the hand-written kernel runs this model (not libtorch).
    pub fn on_kernel(&self) -> bool {
        self.backends
            .iter()
            .all(|b| matches!(b, Backend::Kernel(_)))
    }

    /// The card this model was loaded with.
    pub fn card(&self) -> &ModelCard {
        &self.card
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

    fn heavy(&self) -> bool {
        true
    }

    /// False when an input of the window's newest sample lies more than
    /// [`TRAINING_RANGE_SIGMAS`] training standard deviations from the training mean.
    fn in_training_range(&self, window: &Window) -> bool {
        let mut x = Vec::with_capacity(N_FEATURES);
        push_inputs(window, self.card.feature_set, 1, &mut x);
        within_training_range(&self.card, &x)
    }

    fn predict(&mut self, windows: &[Window], out: &mut Vec<Prediction>) {
        out.clear();
        if windows.is_empty() {
            return;
        }
        match self.forward_w(windows) {
            Ok(rows) if rows.len() == windows.len() => {
                let widen = self.card.band_widen_w;
                out.extend(rows.iter().map(|r| Prediction {
                    power_w: r[0],
                    band_w: (r[1] != r[2]).then_some((r[1] - widen, r[2] + widen)),
                }))
            }
            other => {
                if !self.warned {
                    let why = other
                        .err()
                        .map(|e| format!("{e:#}"))
                        .unwrap_or_else(|| "wrong output size".into());
                    tracing::warn!("lstm: inference failed, emitting NaN: {why}");
                    self.warned = true;
                }
                out.extend(windows.iter().map(|_| Prediction {
                    power_w: f32::NAN,
                    band_w: None,
                }));
            }
        }
    }
}

/// Find the model to load: the configured path, else the shipped model (search order in
/// the module docs). `None` when no shipped model is found.
pub fn resolve_model_path(configured: Option<&Path>) -> Option<PathBuf> {
    match configured {
        Some(p) => Some(p.to_path_buf()),
        None => find_model_dir(DEFAULT_MODEL_DIR),
    }
}

/// The folder `rel` (e.g. [`PAPER_MODEL_DIR`]) found as the shipped model is (search order
/// in the module docs), holding a `card.toml`.
pub fn find_model_dir(rel: &str) -> Option<PathBuf> {
    crate::assets::model_dir(rel)
}

/// The LSTM a configuration asks for, or `None` when it is disabled or (default path
/// only) no shipped model is found. A configured path that fails, or a card that does not
/// match `telemetry`, is an error.
pub fn from_config(
    cfg: &LstmConfig,
    telemetry: &TelemetryConfig,
) -> anyhow::Result<Option<LstmModel>> {
    if !cfg.enabled {
        return Ok(None);
    }
    match resolve_model_path(cfg.path.as_deref()) {
        Some(p) => Ok(Some(LstmModel::load(&p, telemetry)?)),
        None => {
            tracing::warn!("lstm: no model found (looked for {DEFAULT_MODEL_DIR} beside the executable and for the compiled-in copy); running without it");
            Ok(None)
        }
    }
}
