//! LSTM training: by-flight splits, cross-validation, grid search, early stopping.
//!
//! Every window comes from [`dronewatt::offline::data::load_flights`], the same ingest path as
//! live telemetry. Splits are by flight, never by row: the test flights
//! ([`dronewatt::offline::data::TEST_FLIGHTS`]) never train or validate, and ground tests (routes `A*`, no GPS,
//! motors in odd states) are left out of training. The kept weights are the epoch with the
//! lowest validation MAE (early stopping with `--patience`). A seed fixes the weight init,
//! dropout and the batch order.
//!
//! Loss, on the tanh-scaled target y/P_scale: 2 × pinball₀.₅ (= MAE) for the point head,
//! plus pinball₀.₀₅ and pinball₀.₉₅ for the band heads. The paper trained with MSE; MAE is
//! the figure we are held to and is robust to the ~20 W sensor noise. `--relative-loss λ`
//! weights the point term of each in-flight window towards its relative error (λ = 1: the
//! error over the power, as in-flight MAPE counts it; the shipped model); `--plateau-decay`
//! lowers the learning rate when the validation MAE stalls.

//!
//! Training runs on libtorch, so it lives in the `dronewatt-torch` crate (`torch/src/train.rs`),
//! which registers itself here ([`set_trainer`]); `dronewatt` itself only knows the
//! arguments and hands the command over ([`dronewatt::model::NeedsLibtorch`]).

use std::path::PathBuf;
use std::sync::OnceLock;

use dronewatt::model::card::{FeatureSet, Readout};
use dronewatt::offline::args::{help, ConfigArg, DataArg};

/// Band quantiles of the low and high heads.
pub const BAND_Q: (f32, f32) = (0.05, 0.95);

/// What trains: registered by `dronewatt-torch`.
pub type Trainer = fn(TrainArgs) -> anyhow::Result<()>;

static TRAINER: OnceLock<Trainer> = OnceLock::new();

/// Register the trainer (once per process; later calls are ignored).
pub fn set_trainer(trainer: Trainer) {
    let _ = TRAINER.set(trainer);
}

/// Run `dronewatt-lab train`: the registered trainer, or [`dronewatt::model::NeedsLibtorch`].
pub fn run(args: TrainArgs) -> anyhow::Result<()> {
    match TRAINER.get() {
        Some(train) => train(args),
        None => Err(dronewatt::model::NeedsLibtorch {
            what: "training the LSTM".into(),
        }
        .into()),
    }
}

/// Arguments of `dronewatt-lab train`.
#[derive(Debug, Clone, clap::Args)]
#[command(mut_arg(
    "config",
    help(
        "Configuration file (`[telemetry]` and `[mission]` build the windows; `[energy]` and \
         `[[alerts]]` the chain the test flights are scored through). Default: built-in defaults"
    )
))]
pub struct TrainArgs {
    #[command(flatten)]
    pub data: DataArg,
    #[command(flatten)]
    pub config: ConfigArg,
    /// Folder for weights, card, loss curves and test plots.
    #[arg(long, value_name = "DIR", default_value = dronewatt::model::lstm::DEFAULT_MODEL_DIR)]
    pub out: PathBuf,
    /// Maximum epochs (an epoch is one pass over the strided training windows).
    #[arg(long, default_value_t = 12)]
    pub epochs: usize,
    /// Seed: weights init, dropout, validation split and batch order.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Seed(s) of the weights init, dropout and batch order (default: `--seed`); the
    /// validation split and the folds keep `--seed`'s. Several (comma-separated) train an
    /// ensemble: one network per seed on the same flights, the estimate their mean (the
    /// card's `members`); `--cv` then scores that ensemble on each fold.
    #[arg(long, value_delimiter = ',', value_name = "SEED,...")]
    pub init_seed: Vec<u64>,
    /// Run the paper's grid (dropout {0.2,0.5} × lr {1e-2,1e-3,1e-4} × batch {64,128})
    /// with `--cv` folds, then train the best setting.
    #[arg(long)]
    pub grid: bool,
    /// K-fold by-flight cross-validation of the setting(s) before the final run (0: none).
    /// The folds: `offline::data::cv_folds` of the training pool and `--seed`. Each fold
    /// early-stops on a `--val-frac` split of its own training flights and scores its
    /// held-out flights through the live chain (MAE, in-flight MAPE, energy error), into
    /// `cv.csv`.
    #[arg(long, default_value_t = 0)]
    pub cv: usize,
    /// Run only these folds of `--cv` (0-based, comma-separated; default: all), to spread
    /// one cross-validation over processes or machines: each writes its folds' `cv.csv`,
    /// and `lab/scripts/merge-cv.py` joins them. The folds stay those of `--cv K --seed S`.
    #[arg(long, value_delimiter = ',', value_name = "FOLD,...")]
    pub cv_folds: Vec<usize>,
    /// Use only these flights (comma-separated) for training/validation; test flights
    /// among them are still only scored.
    #[arg(long, value_delimiter = ',')]
    pub flights: Option<Vec<u32>>,
    /// Stop a run after this many optimiser steps.
    #[arg(long)]
    pub max_steps: Option<usize>,
    /// Stop a run (after validating its last, partial epoch) once it has trained this long, s.
    #[arg(long)]
    pub time_budget_s: Option<f64>,
    /// Use every N-th window of each training flight (windows overlap by T−1 samples, so
    /// neighbours are nearly duplicates); validation uses every 2nd, test every window.
    #[arg(long, default_value_t = 4)]
    pub stride: usize,
    /// Dropout after the second LSTM layer.
    #[arg(long, default_value_t = 0.2)]
    pub dropout: f64,
    /// Adam learning rate.
    #[arg(long, default_value_t = 1e-3)]
    pub lr: f64,
    /// Batch size.
    #[arg(long, default_value_t = 128)]
    pub batch: usize,
    /// Multiply the learning rate by this after every 2 epochs in a row without a better
    /// validation MAE (reduce on plateau; 1: a constant rate, as in the paper). Recorded in
    /// the card.
    #[arg(long, default_value_t = 1.0, value_name = "FACTOR")]
    pub plateau_decay: f64,
    /// Epochs without a better validation MAE before stopping.
    #[arg(long, default_value_t = 3)]
    pub patience: usize,
    /// Share of the training flights held out for validation / early stopping.
    #[arg(long, default_value_t = 0.15)]
    pub val_frac: f64,
    /// libtorch CPU threads (1 is fastest on a shared 2-core machine).
    #[arg(long, default_value_t = 1)]
    pub threads: i32,
    /// Input features: the paper's, or location-invariant (relative to home).
    #[arg(long, value_enum, default_value_t = FeatureSet::Paper)]
    pub features: FeatureSet,
    /// Train the estimate for the sample this many steps before each window's newest
    /// (fixed-lag smoothing; 0: the newest, as in the paper). Recorded in the card.
    #[arg(long, default_value_t = 0)]
    pub target_lag: usize,
    /// Weight of the relative error in the point estimate's loss, 0…1 (0: the paper's
    /// absolute loss). Each in-flight training window's (measured ≥ 100 W, the windows
    /// in-flight MAPE counts) median pinball term is weighted `(1 − λ) + λ · P̄ / P`, `P̄`
    /// making their mean weight 1, so errors at low power in flight (descents, light hover)
    /// count as MAPE counts them; ground windows and the band's quantile terms keep the
    /// absolute loss. Recorded in the card.
    #[arg(long, default_value_t = 0.0, value_name = "λ")]
    pub relative_loss: f64,
    /// Which top-layer states the head reads: `final` (the paper's: the last forward and
    /// backward states) or `instant` (both directions at the estimated instant, `window − 1
    /// − target-lag`: a fixed-lag smoother's readout). Recorded in the card.
    #[arg(long, value_enum, default_value_t = Readout::Final)]
    pub readout: Readout,
    /// Hidden cells per LSTM direction and layer (the paper: 128).
    #[arg(long, default_value_t = 128)]
    pub hidden: i64,
    /// Only score the model already in `--out` on the test flights (through the ingest
    /// path) and record the metrics in its card.
    #[arg(long, hide = true)]
    pub score_only: bool,
    /// Calibrate the band on the held-out flights of this cross-validation of the same recipe
    /// (its `cv.csv`, from `--cv`): the widening is the mean over its folds of each fold's
    /// split-conformal widening, floored at 0, instead of the validation flights' (which
    /// also early-stop the members). The row is the one whose network, training options and
    /// number of init seeds match the model's; with `--score-only`, re-calibrates a
    /// trained model.
    #[arg(long, value_name = "FILE")]
    pub band_from_cv: Option<PathBuf>,
    /// Assemble these trained model folders (comma-separated: networks trained with one
    /// `--seed` and different `--init-seed`) into one ensemble in `--out`, whose estimate is
    /// the members' mean, then score it on the validation and test flights.
    #[arg(long, value_delimiter = ',', value_name = "DIR,DIR,...")]
    pub ensemble: Option<Vec<PathBuf>>,
    /// Write every window (newest sample + lagged copies) to this CSV and stop: the
    /// LightGBM baseline reads features exactly as the models do. Its `fold` column is the
    /// flight's fold of `--cv K --seed S` (K = 5 when `--cv` is not given; -1: not in the
    /// training pool, e.g. a test flight), so LightGBM is tuned on the LSTM's folds.
    #[arg(long, hide = true, value_name = "FILE")]
    pub export_csv: Option<PathBuf>,
    /// With `--cv`: also write each fold's held-out estimates, every window, to
    /// `cv-predictions-<fold>.csv` in `--out` (flight, fold, instant, measured power, the
    /// estimate and its band), to study the out-of-fold errors beside another model's on the
    /// same folds (`lab/scripts/lgbm_cv.py cv --oof`). Cut from the data set: never commit them.
    #[arg(long, hide = true)]
    pub cv_predictions: bool,
    /// Blend these trees (LightGBM's text model, `lab/scripts/lgbm_cv.py fit` on the export of
    /// `--features`) into the model in `--out`: copied there as `trees.txt` and recorded in
    /// its card (`[trees]`, lags 0, 1, 3 and 9, the export's), before `--score-only` scores it.
    /// The trees must be trained at the card's target lag (`lgbm_cv.py --lag`): their file
    /// does not say, so it is not checked.
    #[arg(long, value_name = "FILE", requires = "trees_weight")]
    pub trees: Option<PathBuf>,
    /// With `--trees`: the network's share w of the blend, 0 to 1 (`lab/scripts/blend_cv.py`'s
    /// `weight_lstm_pooled`, chosen out of fold on the training flights).
    #[arg(long, value_name = "W", requires = "trees")]
    pub trees_weight: Option<f64>,
}
