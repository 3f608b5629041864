//! By-flight K-fold cross-validation, scored the way the model card scores the test flights.
//!
//! Each fold's held-out flights never choose anything: the fold's network is early-stopped
//! on an inner validation split of the fold's *training* flights ([`split_by_flight`], the
//! final run's rule and `--val-frac`), then its held-out flights run, every window, through
//! the live chain and [`score`] (MAE and RMSE pooled, in-flight MAPE, energy error), as
//! `scripts/lgbm_cv.py` scores LightGBM on the same folds ([`cv_folds`]).

use std::collections::BTreeMap;
use std::time::Instant;

use anyhow::Context;
use tch::Device;

use dronewatt::config::Config;
use dronewatt::model::card::Metrics;
use dronewatt::model::lstm::LstmModel;
use dronewatt::offline::data::{cv_folds, cv_k, FlightWindows};
use dronewatt::offline::train::TrainArgs;

use super::{ensemble, model_card, run_alone, score, split_by_flight, Fit, FlightData, Hyper};

/// What the folds are cut from: the loaded flights, their windows as training data, and the
/// configuration the live chain runs with.
pub(super) struct FoldData<'a> {
    pub(super) flights: &'a [FlightWindows],
    pub(super) per_flight: &'a BTreeMap<u32, FlightData>,
    pub(super) cfg: &'a Config,
}

/// One fold's figures on its held-out flights.
struct FoldScore {
    /// The fold's index in `cv_folds` (0-based).
    fold: usize,
    held_out: Vec<u32>,
    best_epoch: usize,
    inner_val_mae_w: f64,
    m: Metrics,
}

/// A row of `cv.csv`: a setting, the init seeds of the networks scored (an ensemble's, or
/// its first member alone), and their folds.
struct CvRow {
    hp: Hyper,
    seeds: Vec<u64>,
    folds: Vec<FoldScore>,
}

/// Mean and median of `v` (NaN when empty).
fn mean_median(v: &[f64]) -> (f64, f64) {
    if v.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    let median = if n % 2 == 1 {
        s[n / 2]
    } else {
        (s[n / 2 - 1] + s[n / 2]) / 2.0
    };
    (mean, median)
}

/// By-flight K-fold cross-validation of every setting asked for (the grid or the one
/// given); writes `cv.csv` and prints the paper's Table 1 with the held-out figures;
/// returns the setting with the lowest mean held-out MAE.
pub(super) fn cross_validate(
    args: &TrainArgs,
    pool: &[u32],
    data: &FoldData,
    base: Hyper,
    t: usize,
    device: Device,
) -> anyhow::Result<Hyper> {
    let k = cv_k(args.cv, pool.len());
    let settings: Vec<Hyper> = if args.grid {
        let mut v = Vec::new();
        for dropout in [0.2, 0.5] {
            for lr in [1e-2, 1e-3, 1e-4] {
                for batch in [64, 128] {
                    v.push(Hyper { dropout, lr, batch });
                }
            }
        }
        v
    } else {
        vec![base]
    };
    // The shared fold assignment (also the `fold` column of `--export-csv`).
    let folds = cv_folds(pool, k, args.seed);
    if let Some(bad) = args.cv_folds.iter().find(|f| **f >= k) {
        anyhow::bail!("--cv-folds {bad}: the folds of --cv {k} are 0 to {}", k - 1);
    }
    let seeds = ensemble::init_seeds(args);
    let mut rows: Vec<CvRow> = Vec::new();
    for (si, hp) in settings.iter().enumerate() {
        let (mut scores, mut alone) = (Vec::new(), Vec::new());
        for fold in (0..k).filter(|f| args.cv_folds.is_empty() || args.cv_folds.contains(f)) {
            let pick = |held_out: bool| -> Vec<u32> {
                folds
                    .iter()
                    .filter(|(_, g)| (*g == fold) == held_out)
                    .map(|(f, _)| *f)
                    .collect()
            };
            let (held_out, fold_train) = (pick(true), pick(false));
            let label = format!(
                "setting {}/{} fold {}/{}",
                si + 1,
                settings.len(),
                fold + 1,
                k
            );
            anyhow::ensure!(
                fold_train.len() >= 2,
                "{label}: {} training flight(s), need two to hold out an inner validation split",
                fold_train.len()
            );
            let (train, inner_val) = split_by_flight(&fold_train, args.val_frac, args.seed);
            let started = Instant::now();
            let (scaling, members, n_train) = ensemble::train_members(
                args,
                &train,
                &inner_val,
                data.per_flight,
                *hp,
                t,
                device,
                &label,
            )?;
            let outcome = &members[0].1;
            let fit = Fit {
                hp: *hp,
                scaling,
                outcome,
                n_train,
                train_flights: train,
                val_flights: inner_val,
                train_time_s: started.elapsed().as_secs_f64(),
                device,
            };
            let (m, first) = score_fold(args, data, fit, &members, &held_out)
                .with_context(|| format!("{label}: scoring the held-out flights"))?;
            println!(
                "{label}: held out {held_out:?}: MAE {:.2} W, RMSE {:.2} W, in-flight MAPE {:.2} %, energy error {:.2} % (best epoch {} on inner validation, MAE {:.2} W)",
                m.mae_w, m.rmse_w, m.mape_in_flight_pct, m.energy_error_pct, outcome.best_epoch, outcome.best_val_mae_w
            );
            let fold_score = |m| FoldScore {
                fold,
                held_out: held_out.clone(),
                best_epoch: outcome.best_epoch,
                inner_val_mae_w: outcome.best_val_mae_w,
                m,
            };
            alone.extend(first.map(fold_score));
            scores.push(fold_score(m));
        }
        rows.push(CvRow {
            hp: *hp,
            seeds: seeds.clone(),
            folds: scores,
        });
        if !alone.is_empty() {
            rows.push(CvRow {
                hp: *hp,
                seeds: seeds[..1].to_vec(),
                folds: alone,
            });
        }
    }
    write_cv_csv(args, k, &rows)?;
    let mean_mae =
        |s: &[FoldScore]| mean_median(&s.iter().map(|f| f.m.mae_w).collect::<Vec<_>>()).0;
    // The settings are ranked on what they train: the ensemble, not its first member.
    let best = rows
        .iter()
        .filter(|r| r.seeds == seeds)
        .min_by(|a, b| mean_mae(&a.folds).total_cmp(&mean_mae(&b.folds)))
        .map(|r| r.hp)
        .unwrap_or(base);
    println!(
        "best setting: dropout {} lr {} batch {} ({k}-fold by-flight CV, held-out flights through the live chain)",
        best.dropout, best.lr, best.batch
    );
    Ok(best)
}

/// Save `fit`'s network to a scratch folder under `--out`, load it as the binary does, run
/// the `held_out` flights through the live chain and score them as the card scores the test
/// flights.
fn score_fold(
    args: &TrainArgs,
    data: &FoldData,
    fit: Fit,
    members: &[ensemble::Member],
    held_out: &[u32],
) -> anyhow::Result<(Metrics, Option<Metrics>)> {
    let dir = args.out.join(".cv-fold");
    std::fs::create_dir_all(&dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    let files = ensemble::save_members(&dir, members)?;
    let mut card = model_card(
        args,
        &data.cfg.telemetry,
        fit,
        &files[0],
        String::new(),
        String::new(),
    );
    ensemble::describe(&mut card, args, members, &files);
    card.save(&dir.join("card.toml"))?;
    let model = LstmModel::load(&dir, &data.cfg.telemetry)?;
    let held: Vec<&FlightWindows> = data
        .flights
        .iter()
        .filter(|f| held_out.contains(&f.flight))
        .collect();
    let series = run_alone(model, data.cfg, &held)?;
    // A weights file named on its own runs alone: the ensemble's first member, for the
    // paired comparison in `cv.csv`.
    let first = if files.len() > 1 {
        let alone = LstmModel::load(&dir.join(&files[0]), &data.cfg.telemetry)?;
        Some(score(&run_alone(alone, data.cfg, &held)?)?.0)
    } else {
        None
    };
    std::fs::remove_dir_all(&dir).with_context(|| format!("{}: cannot remove", dir.display()))?;
    Ok((score(&series)?.0, first))
}

/// `cv.csv`: one row per setting. The first six columns are the paper's Table 1 (now the
/// held-out flights' figures through the live chain); then the median MAE, mean and median
/// in-flight MAPE and energy error, the per-fold figures as `;`-separated lists in fold
/// order, and the network (hidden cells, the ensemble's init seeds, the training stride), the
/// loss options, the target lag and the readout.
fn write_cv_csv(args: &TrainArgs, k: usize, rows: &[CvRow]) -> anyhow::Result<()> {
    let mut csv = String::from(
        "dropout,learning_rate,batch_size,folds,avg_rmse_w,avg_mae_w,median_mae_w,\
         avg_mape_in_flight_pct,median_mape_in_flight_pct,avg_energy_error_pct,\
         median_energy_error_pct,fold_held_out,fold_best_epoch,fold_inner_val_mae_w,\
         fold_mae_w,fold_rmse_w,fold_mape_in_flight_pct,fold_energy_error_pct,hidden,\
         init_seeds,stride,fold_index,relative_loss,plateau_decay,target_lag,readout\n",
    );
    println!(
        "| Dropout | Learning rate | Batch | Init seeds | Avg. RMSE (W) | Avg. MAE (W) | Median MAE (W) | Avg. MAPE (%) | Median MAPE (%) | Avg. energy error (%) | Median energy error (%) |\n|---|---|---|---|---|---|---|---|---|---|---|"
    );
    for CvRow { hp, seeds, folds } in rows {
        let seeds = seeds
            .iter()
            .map(u64::to_string)
            .collect::<Vec<_>>()
            .join(";");
        let col = |f: fn(&FoldScore) -> f64| folds.iter().map(f).collect::<Vec<f64>>();
        let list = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x:.3}"))
                .collect::<Vec<_>>()
                .join(";")
        };
        let (mae, rmse) = (col(|f| f.m.mae_w), col(|f| f.m.rmse_w));
        let (mape, energy) = (
            col(|f| f.m.mape_in_flight_pct),
            col(|f| f.m.energy_error_pct),
        );
        let ((mae_avg, mae_med), (rmse_avg, _)) = (mean_median(&mae), mean_median(&rmse));
        let ((mape_avg, mape_med), (en_avg, en_med)) = (mean_median(&mape), mean_median(&energy));
        let held: Vec<String> = folds
            .iter()
            .map(|f| {
                f.held_out
                    .iter()
                    .map(u32::to_string)
                    .collect::<Vec<_>>()
                    .join(" ")
            })
            .collect();
        let epochs: Vec<String> = folds.iter().map(|f| f.best_epoch.to_string()).collect();
        csv.push_str(&format!(
            "{},{},{},{k},{rmse_avg:.3},{mae_avg:.3},{mae_med:.3},{mape_avg:.3},{mape_med:.3},{en_avg:.3},{en_med:.3},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{:?}\n",
            hp.dropout,
            hp.lr,
            hp.batch,
            held.join(";"),
            epochs.join(";"),
            list(&col(|f| f.inner_val_mae_w)),
            list(&mae),
            list(&rmse),
            list(&mape),
            list(&energy),
            args.hidden,
            seeds,
            args.stride,
            folds
                .iter()
                .map(|f| f.fold.to_string())
                .collect::<Vec<_>>()
                .join(";"),
            args.relative_loss,
            args.plateau_decay,
            args.target_lag,
            args.readout,
        ));
        println!(
            "| {} | {} | {} | {seeds} | {rmse_avg:.2} | {mae_avg:.2} | {mae_med:.2} | {mape_avg:.2} | {mape_med:.2} | {en_avg:.2} | {en_med:.2} |",
            hp.dropout, hp.lr, hp.batch
        );
    }
    let path = args.out.join("cv.csv");
    std::fs::write(&path, csv).with_context(|| format!("{}: cannot write", path.display()))
}
