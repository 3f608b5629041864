//! `dronewatt learn LOG…`: learn a vehicle from the logs its users already have. Each log
//! goes through the live ingest path (tlog decoding → [`Telemetry`] → windows with the
//! measured power V·I), the physics models' free parameters are fitted to the training
//! logs with the existing calibration ([`super::fit::fit`]), and the fit is scored on
//! whole logs held out from it, through the live chain ([`super::chain`]). It writes a
//! vehicle profile (`profile.toml`, use it with `monitor --vehicle` or `vehicle = …` in the
//! config; its models are named `<model>_cal`) and a model card (`model-card.md`: what it
//! was learned from, the held-out score per log, the inputs).
//!
//! Input: `.tlog` files, ArduPilot DataFlash `.bin` and PX4 ULog `.ulg` logs
//! ([`crate::source::logs::dataflash`], [`crate::source::logs::ulog`]: turned into the same MAVLink
//! stream a tlog gives), or folders of them.
//!
//! With `--fine-tune` the LSTM is fine-tuned from the shipped weights too (on libtorch, by
//! `dronewatt-torch`: [`set_fine_tuner`]; `lstm/` beside the profile, model `lstm_ft`).
//! The forecast model is picked on the held-out score (the lowest mean MAPE) into the
//! profile's `[forecast]`, and the profile is kept in the vehicle store for the logs'
//! vehicle (`--data-dir`), so its next run starts from it.
//!
//! Held out: every `--holdout-every`-th log (whole logs, never windows of a log that also
//! trained: windows of one flight are too alike to score honestly), at least one.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use crate::config::Config;
use crate::model::physics;
use crate::model::profile::VehicleProfile;
use crate::model::Ensemble;
use crate::offline::args::{help, ConfigArg};
use crate::offline::chain::Chain;
use crate::offline::data::FlightWindows;
use crate::offline::metrics::{in_flight_above, in_flight_w_for, Scores};
use crate::telemetry::Telemetry;

/// Flight numbers given to logs (clear of the M100 data set's, whose test flights the
/// calibration refuses to fit on).
const FIRST_LOG_NUMBER: u32 = 100_000;

/// Arguments of `dronewatt learn`.
#[derive(Debug, Clone, clap::Args)]
#[command(mut_arg(
    "config",
    help("Configuration file (`[telemetry]`, `[mission]`). Default: built-in defaults")
))]
pub struct LearnArgs {
    /// `.tlog`, DataFlash `.bin` or ULog `.ulg` files, or folders holding them.
    #[arg(required = true, value_name = "LOG")]
    pub logs: Vec<PathBuf>,
    /// Folder to write `profile.toml` and `model-card.md` into.
    #[arg(long, value_name = "DIR", default_value = "learned")]
    pub out: PathBuf,
    /// Profile to start from: a built-in name (m100, x500, quad-3s) or a profile file.
    /// Default: the config's `vehicle`, else m100.
    #[arg(long, value_name = "PROFILE")]
    pub vehicle: Option<String>,
    /// Hold out every Nth log for the score (at least one log is held out).
    #[arg(long, value_name = "N", default_value_t = 4)]
    pub holdout_every: usize,
    #[command(flatten)]
    pub config: ConfigArg,
    /// Most in-flight windows the fit uses (evenly thinned beyond).
    #[arg(long, default_value_t = 20_000)]
    pub max_windows: usize,
    /// The vehicle store to keep the learned profile in for the logs' vehicle (as
    /// `monitor --data-dir`; default `$DRONEWATT_HOME`, else the XDG data directory; `off`
    /// for none): the next `monitor`/`replay` of that vehicle starts from it.
    #[arg(long, value_name = "DIR")]
    pub data_dir: Option<PathBuf>,
    /// Fine-tune the LSTM from M100 weights on the training logs, early-stopping on the
    /// held-out logs (needs libtorch: the command is handed to `dronewatt-torch`). Writes
    /// `lstm/` (weights and card) beside the profile, which refers to it.
    #[arg(long)]
    pub fine_tune: bool,
    /// The model to fine-tune from (a folder with `card.toml`; an ensemble's first member is
    /// tuned). Default: `[models.lstm] path` when configured, else the paper's network
    /// (`config/models/lstm-m100-h128`, one 128-cell network), else the shipped model.
    #[arg(long, value_name = "DIR")]
    pub ft_from: Option<PathBuf>,
    /// Most epochs of fine-tuning.
    #[arg(long, default_value_t = 30)]
    pub ft_epochs: usize,
    /// Stop fine-tuning after this many optimiser steps (smoke tests).
    #[arg(long)]
    pub ft_max_steps: Option<usize>,
    /// Fine-tuning learning rate (Adam).
    #[arg(long, default_value_t = 1e-3)]
    pub ft_lr: f64,
    /// Epochs without a better held-out MAE before fine-tuning stops.
    #[arg(long, default_value_t = 5)]
    pub ft_patience: usize,
    /// Dropout while fine-tuning (default: the shipped model's).
    #[arg(long)]
    pub ft_dropout: Option<f64>,
}

/// A fine-tuning of the LSTM that `learn` asks of `dronewatt-torch` ([`set_fine_tuner`]).
pub struct FineTuneJob<'a> {
    /// The model folder to start from (its `card.toml` and weights: the shipped M100 model).
    pub base: &'a Path,
    /// Training logs' windows (the live feature path) and the held-out logs' (early stop).
    pub train: &'a [FlightWindows],
    pub held_out: &'a [FlightWindows],
    /// The folder to write `card.toml` and `model.safetensors` into.
    pub out: &'a Path,
    pub epochs: usize,
    pub max_steps: Option<usize>,
    pub lr: f64,
    pub patience: usize,
    /// Dropout while fine-tuning (None: the shipped model's).
    pub dropout: Option<f64>,
    /// The training logs' names, for the card.
    pub logs: Vec<String>,
}

/// What fine-tuning ran.
#[derive(Debug, Clone)]
pub struct FineTuned {
    /// Epochs run, and the epoch kept (0: no epoch beat the shipped weights on the held-out
    /// logs, which are kept).
    pub epochs_run: usize,
    pub best_epoch: usize,
    /// Held-out MAE of the shipped weights and of the kept ones, W.
    pub held_out_mae_w: (f64, f64),
    pub train_windows: usize,
    pub train_time_s: f64,
}

/// Fine-tunes the LSTM: registered by `dronewatt-torch`.
pub type FineTuner = fn(&FineTuneJob) -> Result<FineTuned>;

static FINE_TUNER: std::sync::OnceLock<FineTuner> = std::sync::OnceLock::new();

/// Register the fine-tuner (once per process; later calls are ignored).
pub fn set_fine_tuner(f: FineTuner) {
    let _ = FINE_TUNER.set(f);
}

/// The fixed-wing model's (regressors, measured power) on the windows a wing flies with the
/// motor running (measured power over twice `offset_w`, the model's own teaching threshold)
/// and well above the stall (airspeed over 1.2 × the level stall speed at C_L 1.2, sea
/// level: the take-off roll at full throttle and low airspeed is no flight the model
/// describes, and would teach it a negative drag).
fn wing_data(
    p: &crate::model::physics::fixed_wing::Params,
    f: &FlightWindows,
) -> Vec<([f64; 4], f64)> {
    use crate::model::physics::fixed_wing::{airspeed, FixedWing};
    use crate::model::PowerModel;
    let m = FixedWing::new(*p);
    let v_min =
        1.2 * (2.0 * p.mass_kg * crate::features::units::G / (1.225 * p.wing_area_m2 * 1.2)).sqrt();
    f.windows
        .iter()
        .filter_map(|w| {
            let y = w
                .last()
                .measured_w
                .map(f64::from)
                .filter(|y| y.is_finite() && *y > 2.0 * p.offset_w)?;
            if airspeed(w.last()).0 < v_min {
                return None;
            }
            Some((m.regressors(w)?.0, y))
        })
        .collect()
}

/// The fixed-wing model's scores on one log's wing windows from its first window (no
/// adaptation): MAPE and MAE over the windows the motor runs in (measured over twice the
/// published `offset_w`), energy error over the same windows. None without 10 of them.
fn wing_score(
    p: &crate::model::physics::fixed_wing::Params,
    mask_w: f64,
    f: &FlightWindows,
) -> Option<crate::offline::metrics::Scores> {
    let mut m = crate::model::physics::fixed_wing::FixedWing::new(*p);
    let (mut n, mut abs, mut sq, mut pct, mut e_m, mut e_p) = (0usize, 0.0, 0.0, 0.0, 0.0, 0.0);
    for w in &f.windows {
        let pred = m.predict_window(w);
        let Some(y) = w
            .last()
            .measured_w
            .map(f64::from)
            .filter(|y| y.is_finite() && *y > mask_w)
        else {
            continue;
        };
        let e = pred - y;
        n += 1;
        abs += e.abs();
        sq += e * e;
        pct += (e / y).abs();
        e_m += y;
        e_p += pred;
    }
    (n >= 10).then(|| crate::offline::metrics::Scores {
        mae_w: abs / n as f64,
        rmse_w: (sq / n as f64).sqrt(),
        mse_w2: sq / n as f64,
        mape_pct: 100.0 * pct / n as f64,
        energy_err_pct: 100.0 * (e_p - e_m) / e_m,
        windows: n,
        in_flight_windows: n,
    })
}

/// Each model's scores on one held-out log, published and learned, by base name.
struct LogScore {
    log: String,
    in_flight_windows: usize,
    rows: Vec<(String, Option<Scores>, Option<Scores>)>,
}

/// Score the profile's physics models and the LSTM (`lstm`: a fine-tuned model folder, else
/// the configured one, when it runs) on one log through the live chain, from the first
/// window (no adaptation), by base name.
fn score(
    cfg: &Config,
    profile: &VehicleProfile,
    lstm: Option<&Path>,
    f: &FlightWindows,
    in_flight_w: f64,
) -> Result<Vec<(String, Option<Scores>)>> {
    let mut models = physics::models(profile);
    let lstm = match lstm {
        Some(p) => Some(crate::model::lstm::LstmModel::load(p, &cfg.telemetry)?),
        None => crate::model::lstm::from_config(&cfg.models.lstm, &cfg.telemetry)?,
    };
    if let Some(m) = lstm {
        models.push(Box::new(m));
    }
    let mut chain = Chain::new(cfg, Ensemble::new(models))?;
    let mut s = chain.run_flight(f)?;
    s.in_flight_w = in_flight_w;
    Ok(s.names
        .iter()
        .map(|n| {
            n.trim_end_matches("_cal")
                .trim_end_matches("_ft")
                .to_string()
        })
        .zip(s.scores(false))
        .collect())
}

/// A log's windows with a measured power above the vehicle's in-flight threshold.
fn rotor_windows(f: &FlightWindows, in_flight_w: f64) -> usize {
    let flying = |m: f32| in_flight_above(f64::from(m), in_flight_w);
    f.windows
        .iter()
        .filter(|w| w.last().measured_w.is_some_and(flying))
        .count()
}

/// Run `dronewatt learn`.
pub fn run(args: LearnArgs) -> Result<()> {
    let cfg = args.config.load()?;
    let base = base_profile(&args, &cfg)?;
    // Fine-tuning needs libtorch: ask before anything is written (the command is handed
    // to `dronewatt-torch` whole).
    let fine_tuner = fine_tuner_for(args.fine_tune)?;
    if args.holdout_every < 2 {
        bail!(
            "--holdout-every {}: must be at least 2 (one log in N is held out)",
            args.holdout_every
        );
    }
    let logs = collect_logs(&args.logs)?;
    if logs.len() < 2 {
        bail!(
            "{} log(s): learn needs at least 2 (whole logs are held out for the score)",
            logs.len()
        );
    }
    let wing0 = base.fixed_wing.unwrap_or_default();
    // in flight above the vehicle's threshold (100 W, or half its hover when that is lower)
    let in_flight_w = in_flight_w_for(&base);
    let (flights, wings) = read_logs(&logs, &cfg, &wing0, in_flight_w)?;
    let held = held_out_logs(flights.len(), args.holdout_every);
    let train: Vec<FlightWindows> = flights
        .iter()
        .enumerate()
        .filter(|(i, _)| !held.contains(i))
        .map(|(_, (_, f, _))| f.clone())
        .collect();
    let sums: Vec<String> = logs
        .iter()
        .map(|p| crate::offline::data::sha256_file(p))
        .collect::<Result<_>>()?;
    let held_out = HeldOut {
        flights: &flights,
        wings: &wings,
        held: &held,
        wing0,
        in_flight_w,
    };
    let (mut learned, fit_report) =
        fit_profile(&base, &train, &held_out, sums.join(","), args.max_windows)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create", args.out.display()))?;

    // The LSTM fine-tuned from M100 weights, early-stopping on the held-out logs.
    let tuned = match fine_tuner {
        Some(f) => Some(fine_tune_lstm(f, &args, &cfg, &flights, &held, &train)?),
        None => None,
    };
    if tuned.is_some() {
        learned.lstm = Some(PathBuf::from("lstm"));
    }

    let tuned_dir = tuned.as_ref().map(|(p, _)| p.as_path());
    let scores = score_held(&cfg, &base, &learned, tuned_dir, &held_out)?;

    // The forecast model: the lowest mean held-out MAPE of the learned models.
    set_forecast(&mut learned, &scores, tuned.is_some(), held.len());

    let header = format!(
        "# Written by `dronewatt learn` from {} log(s) ({} trained, {} held out), starting from {}.\n",
        logs.len(),
        train.len(),
        held.len(),
        base.name
    );
    let written = Learned {
        base: &base,
        logs: &logs,
        held_out: &held_out,
        scores: &scores,
        tuned: tuned.as_ref().map(|(_, t)| t),
        fit_report: &fit_report,
        learned: &learned,
    };
    write_learned(&args, header, &written)
}

/// The profile to start from: `--vehicle`, else the config's `vehicle`, else the M100.
fn base_profile(args: &LearnArgs, cfg: &Config) -> Result<VehicleProfile> {
    Ok(match (&args.vehicle, &cfg.vehicle) {
        (Some(v), _) => VehicleProfile::named_or_file(v)?,
        (None, Some(p)) => VehicleProfile::load(p)?,
        (None, None) => VehicleProfile::m100(),
    })
}

/// The registered fine-tuner when `--fine-tune` asks for one; an error naming libtorch
/// when none is registered.
fn fine_tuner_for(fine_tune: bool) -> Result<Option<FineTuner>> {
    Ok(match (fine_tune, FINE_TUNER.get()) {
        (false, _) => None,
        (true, Some(f)) => Some(*f),
        (true, None) => {
            return Err(crate::model::NeedsLibtorch {
                what: "fine-tuning the LSTM (learn --fine-tune)".into(),
            }
            .into())
        }
    })
}

/// A log read: its path, its windows, and its in-flight windows on rotors and on a wing.
type LogRead<'a> = (&'a PathBuf, FlightWindows, usize);

/// Each log read through the live ingest path: (its path, its windows, its in-flight
/// windows on rotors and on a wing), and its wing windows.
fn read_logs<'a>(
    logs: &'a [PathBuf],
    cfg: &Config,
    wing0: &physics::fixed_wing::Params,
    in_flight_w: f64,
) -> Result<(Vec<LogRead<'a>>, Vec<FlightWindows>)> {
    let mut flights = Vec::with_capacity(logs.len());
    let mut wings = Vec::with_capacity(logs.len());
    for (i, p) in logs.iter().enumerate() {
        let (f, wing) = log_windows_by_lift(p, FIRST_LOG_NUMBER + i as u32, cfg)?;
        let n = rotor_windows(&f, in_flight_w);
        let n_wing = wing_data(wing0, &wing).len();
        if n == 0 && n_wing == 0 {
            tracing::warn!("{}: no in-flight window with measured power (over {in_flight_w:.0} W on rotors, over {:.0} W on a wing): it teaches nothing", p.display(), 2.0 * wing0.offset_w);
        }
        flights.push((p, f, n + n_wing));
        wings.push(wing);
    }
    Ok((flights, wings))
}

/// The held-out logs' indices among `n`: every `every`-th, else the last.
fn held_out_logs(n: usize, every: usize) -> Vec<usize> {
    let mut held: Vec<usize> = (0..n).filter(|i| (i + 1) % every == 0).collect();
    if held.is_empty() {
        held.push(n - 1);
    }
    held
}

/// The learned profile and the fit's report: the multirotor models fitted on the training
/// windows flown on rotors, the fixed-wing model on those flown on a wing.
fn fit_profile(
    base: &VehicleProfile,
    train: &[FlightWindows],
    h: &HeldOut,
    sums: String,
    max_windows: usize,
) -> Result<(VehicleProfile, Vec<crate::offline::fit::FitReport>)> {
    // The multirotor models on the windows flown on rotors, where there are any (a plane's
    // logs have none: its profile's multirotor sections are kept as they are).
    let rotor_windows: usize = h
        .flights
        .iter()
        .enumerate()
        .filter(|(i, _)| !h.held.contains(i))
        .map(|(_, (_, f, _))| rotor_windows(f, h.in_flight_w))
        .sum();
    let (mut learned, mut fit_report) = if rotor_windows > 0 {
        super::fit::fit(train, base, sums, max_windows)?
    } else {
        tracing::info!("no training window flown on rotors: the multirotor models are not fitted");
        (base.clone(), Vec::new())
    };
    // The fixed-wing model on the windows flown on a wing.
    let wing_train: Vec<([f64; 4], f64)> = h
        .wings
        .iter()
        .enumerate()
        .filter(|(i, _)| !h.held.contains(i))
        .flat_map(|(_, w)| wing_data(&h.wing0, w))
        .collect();
    fit_wing(&h.wing0, &wing_train, &mut learned, &mut fit_report);
    Ok((learned, fit_report))
}

/// The model with the lowest mean held-out MAPE over the held-out logs (learned scores; a
/// model missing a score on any held-out log is not a candidate), and that MAPE.
/// A VTOL's rotor models and its fixed-wing model score different windows: the pick is among
/// the rotor models then (on the wing the forecast follows `fixed_wing` anyway).
fn pick_forecast(scores: &[LogScore]) -> Option<(String, f64)> {
    let first = scores.first()?;
    let rotors = first.rows.iter().any(|(n, _, _)| n != "fixed_wing");
    first
        .rows
        .iter()
        .filter(|(name, _, _)| !(rotors && name == "fixed_wing"))
        .filter_map(|(name, _, _)| {
            let per_log: Option<Vec<f64>> = scores
                .iter()
                .map(|l| {
                    l.rows
                        .iter()
                        .find(|(n, _, _)| n == name)
                        .and_then(|(_, _, a)| a.map(|a| a.mape_pct))
                        .filter(|v| v.is_finite())
                })
                .collect();
            let v = per_log?;
            Some((name.clone(), v.iter().sum::<f64>() / v.len() as f64))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// Keep the learned profile in the vehicle store for the vehicle(s) the logs were flown by
/// (identified as live: AUTOPILOT_VERSION's uid, else HEARTBEAT). Any problem is a warning:
/// the profile file stands without it.
fn remember_profile(dir: &Path, logs: &[PathBuf], profile: &Path, forecast_model: Option<&str>) {
    let profile = std::fs::canonicalize(profile).unwrap_or_else(|_| profile.to_path_buf());
    let mut ids: Vec<crate::vehicle::params::Identity> = Vec::new();
    for p in logs {
        let Ok(bytes) = std::fs::read(p) else {
            continue;
        };
        let stats = crate::report::status::IngestStats::default();
        let mut reader = crate::vehicle::params::ParamReader::passive();
        for m in crate::source::logs::tlog::decode_tlog(&bytes, &stats) {
            reader.on_message(&m);
        }
        if let Some(id) = reader.params().identity {
            if !ids.iter().any(|i| {
                crate::vehicle::store::VehicleKey::of(i)
                    == crate::vehicle::store::VehicleKey::of(&id)
            }) {
                ids.push(id);
            }
        }
    }
    if ids.is_empty() {
        tracing::warn!("vehicle store: no autopilot heartbeat in the logs, so no vehicle to keep the profile for");
        return;
    }
    if ids.len() > 1 {
        tracing::warn!(
            "vehicle store: the logs come from {} vehicles; the profile is kept for each",
            ids.len()
        );
    }
    for id in &ids {
        crate::vehicle::store::remember_profile(dir, id, &profile, forecast_model);
    }
}

mod dedup;
mod logs;
mod report;
mod steps;
use logs::collect_logs;
pub use logs::{log_windows, log_windows_by_lift};
use report::*;
use steps::{fine_tune_lstm, fit_wing, score_held, set_forecast, write_learned, HeldOut, Learned};

#[cfg(test)]
mod tests;
