//! LSTM training on libtorch: by-flight splits, cross-validation, grid search, early
//! stopping. The arguments are [`dronewatt_lab::train::TrainArgs`].
//!
//! Every window comes from [`dronewatt::offline::data::load_flights`], the same ingest path as
//! live telemetry. Splits are by flight, never by row: the test flights
//! ([`TEST_FLIGHTS`]) never train or validate, and ground tests (routes `A*`, no GPS,
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

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use rand::seq::SliceRandom;
use rand::SeedableRng;
use tch::nn::{self, OptimizerConfig};
use tch::{Device, Kind, Tensor};

use dronewatt::config::Config;
use dronewatt::features::N_FEATURES;
use dronewatt::model::card::{
    BandCalibration, FeatureSet, Metrics, ModelCard, Readout, TrainingInfo, WeightsFormat,
};
use dronewatt::model::lstm::{push_inputs, LstmModel};
use dronewatt::model::Ensemble;
use dronewatt::offline::chain::{Chain, FlightSeries};
use dronewatt::offline::data::{
    cv_folds, load_flights, sha256_file, training_pool, FlightWindows, TEST_FLIGHTS,
};
use dronewatt::offline::metrics::conformal_widening;
use dronewatt::telemetry::TelemetryConfig;
use dronewatt_lab::train::{TrainArgs, BAND_Q};

use crate::Net;

mod cv;
mod ensemble;
mod report;
use report::{export_csv, plot_flight, write_curve, write_test_table};
pub use report::{score, FlightScore};

/// One setting of the hyper-parameters.
#[derive(Debug, Clone, Copy)]
struct Hyper {
    dropout: f64,
    lr: f64,
    batch: usize,
}

/// Inputs and targets of a set of flights, raw (unstandardised).
#[derive(Default)]
pub(crate) struct FlightData {
    /// T × 21 values per window.
    pub(crate) x: Vec<f32>,
    /// Measured power of each window's newest sample, W.
    pub(crate) y: Vec<f32>,
}

/// One epoch's point of the loss curves.
#[derive(Debug, Clone, Copy)]
pub struct CurvePoint {
    pub epoch: usize,
    pub step: usize,
    pub train_loss: f64,
    pub val_loss: f64,
    pub val_mae_w: f64,
}

/// What a training run returns.
struct RunOutcome {
    vs: nn::VarStore,
    curve: Vec<CurvePoint>,
    best_epoch: usize,
    best_val_mae_w: f64,
    steps: usize,
}

/// Standardisation and target scale of a training split.
#[derive(Debug, Clone)]
pub(crate) struct Scaling {
    pub(crate) mean: Vec<f32>,
    pub(crate) std: Vec<f32>,
    pub(crate) power_scale_w: f32,
}

/// Run `dronewatt-lab train`.
pub fn run(args: TrainArgs) -> anyhow::Result<()> {
    let data_path = args.data.path();
    let cfg = args.config.load()?;
    let tcfg = &cfg.telemetry;
    tracing::info!(
        "loading flights from {} through the ingest path",
        data_path.display()
    );
    anyhow::ensure!(
        (0.0..=1.0).contains(&args.relative_loss),
        "--relative-loss {}: must be between 0 (absolute loss) and 1 (relative)",
        args.relative_loss
    );
    anyhow::ensure!(
        args.plateau_decay > 0.0 && args.plateau_decay <= 1.0,
        "--plateau-decay {}: must be in (0, 1] (1: a constant learning rate)",
        args.plateau_decay
    );
    tch::set_num_threads(args.threads);
    if let Some(members) = &args.ensemble {
        ensemble::assemble(members, &args.out)?;
        return score_model_dir(&args.out, &data_path, &cfg, args.band_from_cv.as_deref())
            .map(|_| ());
    }
    // The chosen flights plus whichever test flights the file holds (273 is withheld from
    // the shared copy, and a file may hold none of them).
    let wanted: Option<Vec<u32>> = match &args.flights {
        Some(k) => {
            let held: Vec<u32> = dronewatt::offline::data::list_flights(&data_path)?
                .iter()
                .map(|f| f.flight)
                .collect();
            Some(
                k.iter()
                    .copied()
                    .chain(TEST_FLIGHTS.into_iter().filter(|t| held.contains(t)))
                    .collect(),
            )
        }
        None => None,
    };
    let mut flights = load_flights(&data_path, wanted.as_deref(), tcfg, &cfg.mission)
        .with_context(|| format!("{}: loading flights", data_path.display()))?;
    if let Some(keep) = &wanted {
        flights.retain(|f| keep.contains(&f.flight));
    }
    if let (Some(file), Some(w)) = (&args.trees, args.trees_weight) {
        add_trees(&args.out, file, w, tcfg)?;
    }
    if args.score_only {
        return score_model_dir(&args.out, &data_path, &cfg, args.band_from_cv.as_deref())
            .map(|_| ());
    }
    if let Some(csv) = &args.export_csv {
        // The folds `--cv K --seed S` (K = 5 when not given) would validate on, as a
        // column: the LightGBM scripts tune on the same held-out flights.
        let k = if args.cv == 0 { 5 } else { args.cv };
        let folds = cv_folds(&training_pool(&flights, args.target_lag), k, args.seed);
        let profile = dronewatt::model::load_profile(cfg.vehicle.as_deref())?;
        let mut physics = dronewatt::model::physics::models(&profile);
        return export_csv(
            &flights,
            csv,
            tcfg.window,
            &folds,
            args.features,
            &mut physics,
        );
    }
    let t = tcfg.window;
    let per_flight: BTreeMap<u32, FlightData> = flights
        .iter()
        .map(|f| (f.flight, flight_data(f, args.features, t, args.target_lag)))
        .collect();
    // Flights whose windows carry a measured power at the target lag: exactly those whose
    // `per_flight` targets are not empty.
    let pool = training_pool(&flights, args.target_lag);
    anyhow::ensure!(
        args.target_lag < t,
        "--target-lag {} must be below the window length {t}",
        args.target_lag
    );
    anyhow::ensure!(
        pool.len() >= 2,
        "{}: need at least two non-test flights with measured power to train, found {}",
        data_path.display(),
        pool.len()
    );
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create output folder", args.out.display()))?;
    let device = Device::cuda_if_available();
    tracing::info!(
        "{} training-eligible flights, device {:?}",
        pool.len(),
        device
    );

    let base = Hyper {
        dropout: args.dropout,
        lr: args.lr,
        batch: args.batch,
    };
    let chosen = if args.grid || args.cv > 0 {
        let data = cv::FoldData {
            flights: &flights,
            per_flight: &per_flight,
            cfg: &cfg,
        };
        cv::cross_validate(&args, &pool, &data, base, t, device)?
    } else {
        base
    };
    if !args.cv_folds.is_empty() {
        println!(
            "--cv-folds: {} written for folds {:?}; no final model from a partial cross-validation",
            args.out.join("cv.csv").display(),
            args.cv_folds
        );
        return Ok(());
    }

    // Final run: seeded by-flight split of the pool into training and validation flights.
    let (train_flights, val_flights) = split_by_flight(&pool, args.val_frac, args.seed);
    let started = Instant::now();
    let (scaling, members, n_train) = ensemble::train_members(
        &args,
        &train_flights,
        &val_flights,
        &per_flight,
        chosen,
        t,
        device,
        "final",
    )?;
    let train_time_s = started.elapsed().as_secs_f64();

    write_curve(&args.out, &members[0].1.curve)?;
    let files = ensemble::save_members(&args.out, &members)?;
    let data_file = data_path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let fit = Fit {
        hp: chosen,
        scaling,
        outcome: &members[0].1,
        n_train,
        train_flights,
        val_flights,
        train_time_s,
        device,
    };
    let mut card = model_card(
        &args,
        tcfg,
        fit,
        &files[0],
        data_file,
        sha256_file(&data_path)?,
    );
    ensemble::describe(&mut card, &args, &members, &files);
    let card_path = args.out.join("card.toml");
    card.save(&card_path)?;

    score_model_dir(&args.out, &data_path, &cfg, args.band_from_cv.as_deref())?;
    println!(
        "model written to {} (training took {:.0} s)",
        args.out.display(),
        train_time_s
    );
    Ok(())
}

/// A trained network and how it was trained, for its [`ModelCard`].
pub(crate) struct Fit<'a> {
    hp: Hyper,
    scaling: Scaling,
    outcome: &'a RunOutcome,
    n_train: usize,
    train_flights: Vec<u32>,
    val_flights: Vec<u32>,
    train_time_s: f64,
    device: Device,
}

/// The card of `fit`'s network, its weights in `weights` beside it (no metrics yet).
fn model_card(
    args: &TrainArgs,
    tcfg: &TelemetryConfig,
    fit: Fit,
    weights: &str,
    data_file: String,
    data_sha256: String,
) -> ModelCard {
    ModelCard {
        format: 1,
        name: "lstm".into(),
        weights: weights.into(),
        members: Vec::new(),
        weights_format: WeightsFormat::Safetensors,
        feature_set: args.features,
        feature_names: args.features.names(),
        rate_hz: tcfg.rate_hz,
        window: tcfg.window,
        feature_mean: fit.scaling.mean,
        feature_std: fit.scaling.std,
        power_scale_w: fit.scaling.power_scale_w,
        trees: None,
        target_lag: args.target_lag,
        readout: args.readout,
        band_quantiles: BAND_Q,
        band_widen_w: 0.0,
        band_calibration: Default::default(),
        hidden: args.hidden,
        layers: 2,
        training: TrainingInfo {
            data_file,
            data_sha256,
            loader: "ingest".into(),
            seed: args.seed,
            init_seed: None,
            dropout: fit.hp.dropout,
            relative_loss: args.relative_loss,
            plateau_decay: (args.plateau_decay != 1.0).then_some(args.plateau_decay),
            learning_rate: fit.hp.lr,
            batch_size: fit.hp.batch,
            epochs_run: fit.outcome.curve.len(),
            best_epoch: fit.outcome.best_epoch,
            steps: fit.outcome.steps,
            stride: args.stride,
            train_windows: fit.n_train,
            train_flights: fit.train_flights,
            validation_flights: fit.val_flights,
            train_time_s: fit.train_time_s,
            device: format!("{:?}", fit.device),
        },
        metrics: None,
        validation_metrics: None,
    }
}

/// Seeded by-flight split of `pool` into training and validation flights (each sorted):
/// `val_frac` of the flights, rounded, at least one and never all. `pool` must hold at least
/// two flights.
pub(crate) fn split_by_flight(pool: &[u32], val_frac: f64, seed: u64) -> (Vec<u32>, Vec<u32>) {
    let mut shuffled = pool.to_vec();
    shuffled.shuffle(&mut rand::rngs::StdRng::seed_from_u64(seed));
    let n_val = ((pool.len() as f64 * val_frac).round() as usize).clamp(1, pool.len().max(2) - 1);
    let mut val: Vec<u32> = shuffled[..n_val.min(pool.len())].to_vec();
    let mut train: Vec<u32> = shuffled[n_val.min(pool.len())..].to_vec();
    val.sort_unstable();
    train.sort_unstable();
    (train, val)
}

/// Score the model in `dir`, loaded the way the binary loads it, on the test flights the
/// data file holds, through the ingest path and the live chain ([`Chain`], with `cfg`'s
/// `[energy]` and `[[alerts]]`); write `test_flights.csv` and `flight276.png` there and
/// record the metrics in its card. The band is calibrated first: on the validation flights,
/// or, given `band_cv`, from that cross-validation's held-out flights (`train --band-from-cv`).
pub fn score_model_dir(
    dir: &Path,
    data_path: &Path,
    cfg: &Config,
    band_cv: Option<&Path>,
) -> anyhow::Result<Metrics> {
    let held: Vec<u32> = dronewatt::offline::data::list_flights(data_path)?
        .iter()
        .map(|f| f.flight)
        .collect();
    let tests: Vec<u32> = TEST_FLIGHTS
        .into_iter()
        .filter(|t| held.contains(t))
        .collect();
    anyhow::ensure!(
        !tests.is_empty(),
        "{}: holds none of the test flights {TEST_FLIGHTS:?}",
        data_path.display()
    );
    // The validation flights (the band's calibration) and the test flights, in one read.
    let val: Vec<u32> = ModelCard::load(&dir.join("card.toml"))?
        .training
        .validation_flights
        .into_iter()
        .filter(|f| held.contains(f) && !TEST_FLIGHTS.contains(f))
        .collect();
    let wanted: Vec<u32> = val.iter().chain(&tests).copied().collect();
    let flights = load_flights(data_path, Some(&wanted), &cfg.telemetry, &cfg.mission)?;
    let (val_flights, test_flights): (Vec<&FlightWindows>, Vec<&FlightWindows>) =
        flights.iter().partition(|f| val.contains(&f.flight));
    let calibrated = match band_cv {
        Some(cv_csv) => band_from_cv(dir, cfg, &val_flights, cv_csv)?,
        None => calibrate_band(dir, cfg, &val_flights)?,
    };
    let validation = match calibrated {
        None => None,
        Some(series) => {
            let (m, _) = score(&series)?;
            println!(
                "validation flights ({}): MAE {:.2} W, RMSE {:.2} W, in-flight MAPE {:.2} %, energy error {:.2} %, band coverage {:.1} %",
                val_flights.len(),
                m.mae_w,
                m.rmse_w,
                m.mape_in_flight_pct,
                m.energy_error_pct,
                m.band_coverage_pct
            );
            Some(m)
        }
    };
    let model = LstmModel::load(dir, &cfg.telemetry)?;
    let mut card = model.card().clone();
    card.validation_metrics = validation;
    let series = run_alone(model, cfg, &test_flights)?;
    let (metrics, per) = score(&series)?;
    write_test_table(dir, &per)?;
    if let Some(f276) = series.iter().find(|s| s.flight == 276) {
        plot_flight(f276, &dir.join("flight276.png"))?;
    }
    println!(
        "test flights {tests:?}: MAE {:.1} W, RMSE {:.1} W, in-flight MAPE {:.2} %, energy error {:.2} %, band coverage {:.1} %, flight 276 MAE {}",
        metrics.mae_w,
        metrics.rmse_w,
        metrics.mape_in_flight_pct,
        metrics.energy_error_pct,
        metrics.band_coverage_pct,
        metrics.flight_276_mae_w.map(|m| format!("{m:.1} W")).unwrap_or_else(|| "n/a".into())
    );
    card.metrics = Some(metrics.clone());
    card.save(&dir.join("card.toml"))?;
    Ok(metrics)
}

/// Copy the trees at `file` into the model folder `dir` as `trees.txt` and record them in
/// its card with the network's share `w` (the export's rows, `EXPORT_LAGS`); the card is
/// loaded back, so a model whose trees do not fit its inputs is an error here.
fn add_trees(dir: &Path, file: &Path, w: f64, tcfg: &TelemetryConfig) -> anyhow::Result<()> {
    let card_path = dir.join("card.toml");
    let mut card = ModelCard::load(&card_path)?;
    let dest = dir.join("trees.txt");
    if file != dest {
        std::fs::copy(file, &dest)
            .with_context(|| format!("{}: cannot copy to {}", file.display(), dest.display()))?;
    }
    card.trees = Some(dronewatt::model::card::TreesBlend {
        file: "trees.txt".into(),
        weight_lstm: w,
        lags: report::EXPORT_LAGS.to_vec(),
    });
    card.save(&card_path)?;
    LstmModel::load(dir, tcfg).map(|_| {
        println!(
            "{}: blends {} (network's share {w})",
            dir.display(),
            file.display()
        )
    })
}

/// `flights` run through the live chain ([`Chain`], with `cfg`'s `[energy]` and `[[alerts]]`)
/// with `model` as its only model.
pub(crate) fn run_alone(
    model: LstmModel,
    cfg: &Config,
    flights: &[&FlightWindows],
) -> anyhow::Result<Vec<FlightSeries>> {
    let mut chain = Chain::new(cfg, Ensemble::new(vec![Box::new(model)]))?;
    flights.iter().map(|f| chain.run_flight(f)).collect()
}

/// Set the band of the model in `dir` to the widening the cross-validation at `cv_csv` gives
/// ([`cv::band_from_cv`]), record it in the card, and run the validation flights with it
/// (for their scores; they calibrate nothing here).
fn band_from_cv(
    dir: &Path,
    cfg: &Config,
    val: &[&FlightWindows],
    cv_csv: &Path,
) -> anyhow::Result<Option<Vec<FlightSeries>>> {
    let mut card = ModelCard::load(&dir.join("card.toml"))?;
    let band = cv::band_from_cv(cv_csv, &card)?;
    println!(
        "band: widened by {:.1} W a side, from {}: the mean of {} folds' widenings ({:+.1} W, floored at 0) on {} held-out flights (the heads' band covered {:.1} % of them)",
        band.widen_w,
        cv_csv.display(),
        band.folds,
        band.mean_q_w,
        band.held_out_flights,
        band.coverage_pct
    );
    card.band_widen_w = band.widen_w as f32;
    card.band_calibration = BandCalibration::Cv;
    card.save(&dir.join("card.toml"))?;
    if val.is_empty() {
        return Ok(None);
    }
    let model = LstmModel::load(dir, &cfg.telemetry)?;
    run_alone(model, cfg, val).map(Some)
}

/// Widen the band of the model in `dir` so that it covers its nominal share of the
/// validation flights' windows (split-conformal, [`conformal_widening`]; never the test
/// flights), and record it in the card. Skipped, with a note, when no validation flight is
/// given (the card lists none the data file holds). Returns the validation flights as the
/// widened model runs them (the one run of them: their scores come from it), `None` without
/// validation flights.
fn calibrate_band(
    dir: &Path,
    cfg: &Config,
    val: &[&FlightWindows],
) -> anyhow::Result<Option<Vec<FlightSeries>>> {
    if val.is_empty() {
        println!("band: no validation flight in the data: the heads' band as it is");
        return Ok(None);
    }
    let model = LstmModel::load(dir, &cfg.telemetry)?;
    let mut card = model.card().clone();
    let mut series = run_alone(model, cfg, val)?;
    let excess: Vec<f64> = series.iter().flat_map(|s| s.band_excess(0)).collect();
    let (lo, hi) = card.band_quantiles;
    let share =
        |w: f64| excess.iter().filter(|e| **e <= w).count() as f64 / excess.len().max(1) as f64;
    let before = share(0.0);
    let Some(q) = conformal_widening(&mut excess.clone(), f64::from(hi - lo)) else {
        println!("band: no banded window in the validation flights: the heads' band as it is");
        return Ok(Some(series));
    };
    card.band_widen_w += q as f32;
    if q > 0.0 {
        // The widening is now (also) the validation flights'.
        card.band_calibration = BandCalibration::Validation;
    }
    println!(
        "band: widened by {q:.1} W a side (now {:.1} W; split-conformal on {} windows of {} validation flights: covers {:.1} % there, was {:.1} %)",
        card.band_widen_w,
        excess.len(),
        val.len(),
        100.0 * share(q),
        100.0 * before
    );
    card.save(&dir.join("card.toml"))?;
    // The series as the widened card runs them: every band `q` wider a side.
    for b in series
        .iter_mut()
        .flat_map(|s| s.band_w.iter_mut().flatten().flatten())
    {
        *b = (b.0 - q, b.1 + q);
    }
    Ok(Some(series))
}

/// The raw inputs and targets of one flight's windows whose target sample (`lag` before
/// the newest) carries a measured power.
pub(crate) fn flight_data(f: &FlightWindows, set: FeatureSet, t: usize, lag: usize) -> FlightData {
    let mut d = FlightData::default();
    for w in &f.windows {
        if let Some(p) = w.back(lag).measured_w.filter(|p| p.is_finite()) {
            push_inputs(w, set, t, &mut d.x);
            d.y.push(p);
        }
    }
    d
}

/// Stack these flights' windows (every `stride`-th) into raw inputs and targets.
fn gather(
    flights: &[u32],
    per_flight: &BTreeMap<u32, FlightData>,
    t: usize,
    stride: usize,
) -> (Vec<f32>, Vec<f32>) {
    let (mut x, mut y) = (Vec::new(), Vec::new());
    let w = t * N_FEATURES;
    for f in flights {
        if let Some(d) = per_flight.get(f) {
            for i in (0..d.y.len()).step_by(stride.max(1)) {
                x.extend_from_slice(&d.x[i * w..(i + 1) * w]);
                y.push(d.y[i]);
            }
        }
    }
    (x, y)
}

/// Mean/std of every input over the training windows, and the target scale.
fn fit_scaling(x: &[f32], y: &[f32]) -> Scaling {
    let n = (x.len() / N_FEATURES).max(1) as f64;
    let mut sum = [0f64; N_FEATURES];
    let mut sq = [0f64; N_FEATURES];
    for row in x.chunks(N_FEATURES) {
        for (f, v) in row.iter().enumerate() {
            sum[f] += *v as f64;
            sq[f] += (*v as f64) * (*v as f64);
        }
    }
    let mean: Vec<f32> = sum.iter().map(|s| (s / n) as f32).collect();
    let std: Vec<f32> = (0..N_FEATURES)
        .map(|f| {
            let var = (sq[f] / n - (sum[f] / n).powi(2)).max(0.0);
            let s = var.sqrt() as f32;
            if s > 1e-6 {
                s
            } else {
                1.0
            }
        })
        .collect();
    let max_p = y.iter().cloned().fold(1.0f32, f32::max);
    Scaling {
        mean,
        std,
        power_scale_w: 1.2 * max_p,
    }
}

/// Standardised `[n, T, 21]` inputs and scaled `[n]` targets on `device`.
pub(crate) fn to_tensors(
    x: &[f32],
    y: &[f32],
    s: &Scaling,
    t: usize,
    device: Device,
) -> (Tensor, Tensor) {
    let n = y.len() as i64;
    let mean = Tensor::from_slice(&s.mean).view([1, 1, N_FEATURES as i64]);
    let std = Tensor::from_slice(&s.std).view([1, 1, N_FEATURES as i64]);
    let xt = ((Tensor::from_slice(x).view([n, t as i64, N_FEATURES as i64]) - mean) / std)
        .to_device(device);
    let yt = (Tensor::from_slice(y) / s.power_scale_w as f64).to_device(device);
    (xt, yt)
}

/// Pinball loss of `pred` at quantile `q` against `y` (both `[n]`), mean.
fn pinball(pred: &Tensor, y: &Tensor, q: f64) -> Tensor {
    let e = y - pred;
    (&e * q).maximum(&(&e * (q - 1.0))).mean(Kind::Float)
}

/// The training loss of network outputs `out` (`[n, 3]`) against scaled targets `y`; `w`
/// (`[n]`, mean 1) weights the point estimate's term window by window (`--relative-loss`).
pub(crate) fn loss_fn(out: &Tensor, y: &Tensor, w: Option<&Tensor>) -> Tensor {
    let point = match w {
        None => pinball(&out.select(1, 0), y, 0.5),
        Some(w) => {
            let e = y - out.select(1, 0);
            ((&e * 0.5).maximum(&(&e * -0.5)) * w).mean(Kind::Float)
        }
    };
    2.0 * point
        + pinball(&out.select(1, 1), y, BAND_Q.0 as f64)
        + pinball(&out.select(1, 2), y, BAND_Q.1 as f64)
}

/// Per-window weights of the point loss for `--relative-loss` λ over targets `y` (W). In
/// flight (`P ≥ IN_FLIGHT_W`, the windows in-flight MAPE counts): `(1 − λ) + λ · P̄ / P`,
/// `P̄` the in-flight windows' harmonic mean, so their weights average 1 and λ = 1 is the
/// relative error's loss. On the ground (motors off or idling, where a percentage means
/// nothing) 1: the absolute loss. `None` for λ = 0.
pub(crate) fn relative_weights(y: &[f32], lambda: f64) -> Option<Vec<f32>> {
    if lambda == 0.0 || y.is_empty() {
        return None;
    }
    let in_flight = |p: f32| f64::from(p) >= dronewatt::offline::metrics::IN_FLIGHT_W;
    let (n, inv_sum) = y
        .iter()
        .filter(|&&p| in_flight(p))
        .fold((0usize, 0.0f64), |(n, s), &p| {
            (n + 1, s + 1.0 / f64::from(p))
        });
    let p_bar = if n > 0 { n as f64 / inv_sum } else { 0.0 };
    Some(
        y.iter()
            .map(|&p| {
                if in_flight(p) {
                    ((1.0 - lambda) + lambda * p_bar / f64::from(p)) as f32
                } else {
                    1.0
                }
            })
            .collect(),
    )
}

/// The windows one split trains and early-stops on, standardised, as tensors on the device:
/// built once per split and shared by every member of an ensemble.
pub(crate) struct SplitTensors {
    pub(crate) scaling: Scaling,
    x: Tensor,
    y: Tensor,
    vx: Tensor,
    vy: Tensor,
    /// The point loss's per-window weights (`--relative-loss`), when not all 1.
    weights: Option<Tensor>,
    /// Training windows.
    pub(crate) n: usize,
}

/// Gather `train` flights' windows (every `--stride`-th) and `val` flights' (every 2nd),
/// fit the scaling on the training windows and move both to `device`.
pub(crate) fn split_tensors(
    args: &TrainArgs,
    train: &[u32],
    val: &[u32],
    per_flight: &BTreeMap<u32, FlightData>,
    t: usize,
    device: Device,
    label: &str,
) -> anyhow::Result<SplitTensors> {
    let (xr, yr) = gather(train, per_flight, t, args.stride);
    let (xv, yv) = gather(val, per_flight, t, 2);
    anyhow::ensure!(
        !yr.is_empty() && !yv.is_empty(),
        "{label}: no training or validation windows"
    );
    let scaling = fit_scaling(&xr, &yr);
    let weights =
        relative_weights(&yr, args.relative_loss).map(|w| Tensor::from_slice(&w).to_device(device));
    let (x, y) = to_tensors(&xr, &yr, &scaling, t, device);
    let (vx, vy) = to_tensors(&xv, &yv, &scaling, t, device);
    Ok(SplitTensors {
        scaling,
        x,
        y,
        vx,
        vy,
        weights,
        n: yr.len(),
    })
}

/// Train one network (`init_seed`: weights, dropout, batch order) on a split with early
/// stopping on its validation windows.
fn train_split(
    args: &TrainArgs,
    init_seed: u64,
    data: &SplitTensors,
    hp: Hyper,
    device: Device,
    label: &str,
) -> anyhow::Result<RunOutcome> {
    let SplitTensors {
        scaling,
        x,
        y,
        vx,
        vy,
        weights,
        n,
    } = data;
    let n = *n;
    tch::manual_seed(init_seed as i64);
    let mut vs = nn::VarStore::new(device);
    // x: [windows, T, inputs]; `run` checked target_lag < T.
    let window = x.size()[1] as usize;
    let readout = (args.readout == Readout::Instant).then(|| window - 1 - args.target_lag);
    let net = Net::new(&vs.root(), args.hidden, 2, hp.dropout, readout);
    let mut opt = nn::Adam::default().build(&vs, hp.lr)?;
    let mut lr = hp.lr;
    let mut rng = rand::rngs::StdRng::seed_from_u64(init_seed);
    let mut order: Vec<i64> = (0..n as i64).collect();
    let steps_per_epoch = n.div_ceil(hp.batch);
    let max_steps = args.max_steps.unwrap_or(usize::MAX);
    let pb = ProgressBar::new((steps_per_epoch * args.epochs).min(max_steps) as u64);
    pb.set_style(
        ProgressStyle::with_template(
            "{prefix} [{elapsed_precise}] {wide_bar} {pos}/{len} steps ({eta}) {msg}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    pb.set_prefix(label.to_string());
    let mut curve = Vec::new();
    let mut best: Option<(f64, f64, usize, Vec<Tensor>)> = None;
    let mut steps = 0;
    let started = Instant::now();
    let out_of_time = || {
        args.time_budget_s
            .is_some_and(|b| started.elapsed().as_secs_f64() > b)
    };
    'epochs: for epoch in 1..=args.epochs {
        order.shuffle(&mut rng);
        let (mut sum, mut count) = (0.0, 0usize);
        for chunk in order.chunks(hp.batch) {
            if steps >= max_steps || out_of_time() {
                break;
            }
            let ix = Tensor::from_slice(chunk).to_device(device);
            let out = net.forward_t(&x.index_select(0, &ix), true);
            let w = weights.as_ref().map(|w| w.index_select(0, &ix));
            let loss = loss_fn(&out, &y.index_select(0, &ix), w.as_ref());
            opt.backward_step(&loss);
            sum += loss.double_value(&[]);
            count += 1;
            steps += 1;
            pb.inc(1);
        }
        let (val_loss, mae, rmse) = validate(&net, vx, vy, scaling.power_scale_w);
        let train_loss = sum / count.max(1) as f64;
        curve.push(CurvePoint {
            epoch,
            step: steps,
            train_loss,
            val_loss,
            val_mae_w: mae,
        });
        pb.set_message(format!(
            "epoch {epoch}: train {train_loss:.4} val {val_loss:.4} val MAE {mae:.1} W"
        ));
        tracing::info!("{label} epoch {epoch}: train loss {train_loss:.5} val loss {val_loss:.5} val MAE {mae:.2} W");
        if best.as_ref().is_none_or(|b| mae < b.0) {
            let snapshot = vs
                .trainable_variables()
                .iter()
                .map(|v| v.detach().copy())
                .collect();
            best = Some((mae, rmse, epoch, snapshot));
        } else if best.as_ref().is_some_and(|b| epoch - b.2 >= args.patience) {
            break 'epochs;
        } else if args.plateau_decay != 1.0 && best.as_ref().is_some_and(|b| (epoch - b.2) % 2 == 0)
        {
            lr *= args.plateau_decay;
            opt.set_lr(lr);
            tracing::info!("{label} epoch {epoch}: learning rate now {lr:.2e}");
        }
        if steps >= max_steps || out_of_time() {
            break;
        }
    }
    pb.finish_and_clear();
    let (best_mae, _, best_epoch, snapshot) = best.context("no epoch ran")?;
    tch::no_grad(|| {
        for (v, s) in vs.trainable_variables().iter_mut().zip(&snapshot) {
            v.copy_(s);
        }
    });
    vs.freeze();
    tracing::info!(
        "{label}: best validation MAE {best_mae:.2} W at epoch {best_epoch} ({steps} steps)"
    );
    Ok(RunOutcome {
        vs,
        curve,
        best_epoch,
        best_val_mae_w: best_mae,
        steps,
    })
}

/// Validation loss, MAE (W) and RMSE (W) with dropout off, in batches.
pub(crate) fn validate(net: &Net, x: &Tensor, y: &Tensor, scale: f32) -> (f64, f64, f64) {
    tch::no_grad(|| {
        let n = y.size()[0];
        let (mut loss, mut abs, mut sq) = (0.0, 0.0, 0.0);
        let mut start = 0;
        while start < n {
            let len = (n - start).min(4096);
            let out = net.forward_t(&x.narrow(0, start, len), false);
            let yy = y.narrow(0, start, len);
            loss += loss_fn(&out, &yy, None).double_value(&[]) * len as f64;
            let e = (out.select(1, 0) - &yy) * scale as f64;
            abs += e.abs().sum(Kind::Double).double_value(&[]);
            sq += (&e * &e).sum(Kind::Double).double_value(&[]);
            start += len;
        }
        let n = n.max(1) as f64;
        (loss / n, abs / n, (sq / n).sqrt())
    })
}

#[cfg(test)]
mod tests;
