//! By-flight K-fold cross-validation, scored the way the model card scores the test flights.
//!
//! Each fold's held-out flights never choose anything: the fold's network is early-stopped
//! on an inner validation split of the fold's *training* flights ([`split_by_flight`], the
//! final run's rule and `--val-frac`), then its held-out flights run, every window, through
//! the live chain and [`score`] (MAE and RMSE pooled, in-flight MAPE, energy error), as
//! `lab/scripts/lgbm_cv.py` scores LightGBM on the same folds ([`cv_folds`]).

use std::collections::BTreeMap;
use std::time::Instant;

use anyhow::Context;
use tch::Device;

use dronewatt::config::Config;
use dronewatt::model::card::{Metrics, ModelCard};
use dronewatt::model::lstm::LstmModel;
use dronewatt::offline::chain::FlightSeries;
use dronewatt::offline::data::{cv_folds, cv_k, FlightWindows};
use dronewatt::offline::metrics::conformal_quantile;
use dronewatt_lab::train::TrainArgs;

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
    /// The signed split-conformal widening at which the band covers its nominal share of
    /// the held-out windows ([`conformal_quantile`]; NaN without a banded window).
    band_q_w: f64,
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
            let ((m, band_q_w), first) =
                score_fold(args, data, fit, &members, (fold, &held_out))
                    .with_context(|| format!("{label}: scoring the held-out flights"))?;
            println!(
                "{label}: held out {held_out:?}: MAE {:.2} W, RMSE {:.2} W, in-flight MAPE {:.2} %, energy error {:.2} %, band coverage {:.1} % (widening to nominal {:.1} W) (best epoch {} on inner validation, MAE {:.2} W)",
                m.mae_w, m.rmse_w, m.mape_in_flight_pct, m.energy_error_pct, m.band_coverage_pct, band_q_w, outcome.best_epoch, outcome.best_val_mae_w
            );
            let fold_score = |(m, band_q_w)| FoldScore {
                fold,
                held_out: held_out.clone(),
                best_epoch: outcome.best_epoch,
                inner_val_mae_w: outcome.best_val_mae_w,
                m,
                band_q_w,
            };
            alone.extend(first.map(fold_score));
            scores.push(fold_score((m, band_q_w)));
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

/// A fold's figures on its held-out flights and its band's signed conformal widening there.
type Scored = (Metrics, f64);

/// Save `fit`'s network to a scratch folder under `--out`, load it as the binary does, run
/// the `held_out` flights through the live chain and score them as the card scores the test
/// flights; with each score, the band's signed conformal widening on those flights.
fn score_fold(
    args: &TrainArgs,
    data: &FoldData,
    fit: Fit,
    members: &[ensemble::Member],
    (fold, held_out): (usize, &[u32]),
) -> anyhow::Result<(Scored, Option<Scored>)> {
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
    let (lo, hi) = card.band_quantiles;
    let scored = |series: Vec<FlightSeries>| -> anyhow::Result<Scored> {
        let mut excess: Vec<f64> = series.iter().flat_map(|s| s.band_excess(0)).collect();
        let q = conformal_quantile(&mut excess, f64::from(hi - lo)).unwrap_or(f64::NAN);
        Ok((score(&series)?.0, q))
    };
    let series = run_alone(model, data.cfg, &held)?;
    if args.cv_predictions {
        write_predictions(
            &args.out.join(format!("cv-predictions-{fold}.csv")),
            fold,
            &series,
        )?;
    }
    // A weights file named on its own runs alone: the ensemble's first member, for the
    // paired comparison in `cv.csv`.
    let first = if files.len() > 1 {
        let alone = LstmModel::load(&dir.join(&files[0]), &data.cfg.telemetry)?;
        Some(scored(run_alone(alone, data.cfg, &held)?)?)
    } else {
        None
    };
    std::fs::remove_dir_all(&dir).with_context(|| format!("{}: cannot remove", dir.display()))?;
    Ok((scored(series)?, first))
}

/// `train --cv-predictions`: one fold's held-out windows that [`score`] counts, as the chain
/// lined them up (the instant each estimate is for, its measured power, the estimate and its
/// band; NaN where it has none).
fn write_predictions(
    path: &std::path::Path,
    fold: usize,
    series: &[FlightSeries],
) -> anyhow::Result<()> {
    use std::io::Write;
    let file = std::fs::File::create(path)
        .with_context(|| format!("{}: cannot create", path.display()))?;
    let mut w = std::io::BufWriter::new(file);
    writeln!(w, "flight,fold,t_s,measured_w,pred_w,low_w,high_w")?;
    for s in series.iter().filter(|s| !s.pred_w.is_empty()) {
        let windows = s.t_s.iter().zip(&s.measured_w);
        for ((t, m), (p, band)) in windows.zip(s.pred_w[0].iter().zip(&s.band_w[0])) {
            // As `score` counts them: a window with an estimate and a measured power.
            if !(p.is_finite() && m.is_finite()) {
                continue;
            }
            let (lo, hi) = band.unwrap_or((f64::NAN, f64::NAN));
            writeln!(
                w,
                "{},{fold},{t:.2},{m:.3},{p:.3},{lo:.3},{hi:.3}",
                s.flight
            )?;
        }
    }
    w.flush()
        .with_context(|| format!("{}: cannot write", path.display()))
}

/// The band's widening a cross-validation gives: the mean over its folds of each fold's
/// signed widening ([`conformal_quantile`] on its held-out windows), floored at 0 as
/// [`conformal_widening`](dronewatt::offline::metrics::conformal_widening) floors one
/// split's; NaN when a fold had no banded window. `lab/scripts/merge-cv.py` recomputes it so.
pub(super) fn cv_band_widening(fold_q_w: &[f64]) -> f64 {
    let mean = mean_median(fold_q_w).0;
    if mean.is_nan() {
        mean
    } else {
        mean.max(0.0)
    }
}

/// `cv.csv`: one row per setting. The first six columns are the paper's Table 1 (now the
/// held-out flights' figures through the live chain); then the median MAE, mean and median
/// in-flight MAPE and energy error, the per-fold figures as `;`-separated lists in fold
/// order, and the network (hidden cells, the ensemble's init seeds, the training stride), the
/// loss options, the target lag and the readout; then the band: its mean coverage of the
/// held-out windows, per fold its coverage and signed conformal widening, and the widening
/// `train --band-from-cv` gives ([`cv_band_widening`]).
fn write_cv_csv(args: &TrainArgs, k: usize, rows: &[CvRow]) -> anyhow::Result<()> {
    let mut csv = String::from(
        "dropout,learning_rate,batch_size,folds,avg_rmse_w,avg_mae_w,median_mae_w,\
         avg_mape_in_flight_pct,median_mape_in_flight_pct,avg_energy_error_pct,\
         median_energy_error_pct,fold_held_out,fold_best_epoch,fold_inner_val_mae_w,\
         fold_mae_w,fold_rmse_w,fold_mape_in_flight_pct,fold_energy_error_pct,hidden,\
         init_seeds,stride,fold_index,relative_loss,plateau_decay,target_lag,readout,\
         avg_band_coverage_pct,fold_band_coverage_pct,fold_band_q_w,cv_band_widen_w\n",
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
        let (band_cov, band_q) = (col(|f| f.m.band_coverage_pct), col(|f| f.band_q_w));
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
            "{},{},{},{k},{rmse_avg:.3},{mae_avg:.3},{mae_med:.3},{mape_avg:.3},{mape_med:.3},{en_avg:.3},{en_med:.3},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{:?},{:.3},{},{},{:.3}\n",
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
            mean_median(&band_cov).0,
            list(&band_cov),
            list(&band_q),
            cv_band_widening(&band_q),
        ));
        println!(
            "| {} | {} | {} | {seeds} | {rmse_avg:.2} | {mae_avg:.2} | {mae_med:.2} | {mape_avg:.2} | {mape_med:.2} | {en_avg:.2} | {en_med:.2} |",
            hp.dropout, hp.lr, hp.batch
        );
    }
    let path = args.out.join("cv.csv");
    std::fs::write(&path, csv).with_context(|| format!("{}: cannot write", path.display()))
}

/// What `train --band-from-cv` takes from a `cv.csv`: the widening, and what it rests on.
pub(super) struct CvBand {
    /// Watts a side: [`cv_band_widening`] of the row's folds.
    pub(super) widen_w: f64,
    /// The folds' mean signed widening, before the floor at 0.
    pub(super) mean_q_w: f64,
    /// How many folds, and how many flights they held out between them.
    pub(super) folds: usize,
    pub(super) held_out_flights: usize,
    /// The heads' band's mean coverage of the folds' held-out windows, %.
    pub(super) coverage_pct: f64,
}

/// The band's widening from the `cv.csv` at `path` for the model `card` describes: the row
/// whose network, training options and number of init seeds match the card's. The error
/// names the file and what is missing or ambiguous.
pub(super) fn band_from_cv(path: &std::path::Path, card: &ModelCard) -> anyhow::Result<CvBand> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines
        .next()
        .with_context(|| format!("{}: empty, no cv.csv header", path.display()))?
        .split(',')
        .collect();
    let col = |name: &str| {
        header.iter().position(|h| *h == name).with_context(|| {
            format!(
                "{}: no column `{name}` (a cv.csv from before the band was recorded? rerun the cross-validation)",
                path.display()
            )
        })
    };
    let t = &card.training;
    let members = 1 + card.members.len();
    let want: [(&str, String); 9] = [
        ("hidden", card.hidden.to_string()),
        ("stride", t.stride.to_string()),
        ("dropout", t.dropout.to_string()),
        ("learning_rate", t.learning_rate.to_string()),
        ("batch_size", t.batch_size.to_string()),
        ("relative_loss", t.relative_loss.to_string()),
        ("plateau_decay", t.plateau_decay.unwrap_or(1.0).to_string()),
        ("target_lag", card.target_lag.to_string()),
        ("readout", format!("{:?}", card.readout)),
    ];
    let idx = want
        .iter()
        .map(|(name, _)| col(name))
        .collect::<anyhow::Result<Vec<usize>>>()?;
    let (seeds, cov, q, folds) = (
        col("init_seeds")?,
        col("fold_band_coverage_pct")?,
        col("fold_band_q_w")?,
        col("fold_held_out")?,
    );
    let same = |a: &str, b: &str| match (a.parse::<f64>(), b.parse::<f64>()) {
        (Ok(x), Ok(y)) => x == y,
        _ => a == b,
    };
    let rows: Vec<Vec<&str>> = lines
        .map(|l| l.split(',').collect::<Vec<&str>>())
        .filter(|r| r.len() == header.len())
        .filter(|r| r[seeds].split(';').count() == members)
        .filter(|r| idx.iter().zip(&want).all(|(i, (_, v))| same(r[*i], v)))
        .collect();
    let recipe = want
        .iter()
        .map(|(n, v)| format!("{n} {v}"))
        .collect::<Vec<_>>()
        .join(", ");
    let row = match rows.as_slice() {
        [row] => row,
        [] => anyhow::bail!(
            "{}: no row for this model ({members} init seed(s), {recipe})",
            path.display()
        ),
        _ => anyhow::bail!(
            "{}: {} rows match this model ({members} init seed(s), {recipe}): keep one",
            path.display(),
            rows.len()
        ),
    };
    let list = |c: usize| -> anyhow::Result<Vec<f64>> {
        row[c]
            .split(';')
            .map(|x| {
                x.parse::<f64>().with_context(|| {
                    format!(
                        "{}: column `{}`: `{x}` is not a number",
                        path.display(),
                        header[c]
                    )
                })
            })
            .collect()
    };
    let (q, cov) = (list(q)?, list(cov)?);
    let widen_w = cv_band_widening(&q);
    anyhow::ensure!(
        widen_w.is_finite(),
        "{}: a fold of this model's row has no banded window: no widening to take",
        path.display()
    );
    Ok(CvBand {
        widen_w,
        mean_q_w: mean_median(&q).0,
        folds: q.len(),
        held_out_flights: row[folds]
            .split(';')
            .map(|f| f.split_whitespace().count())
            .sum(),
        coverage_pct: mean_median(&cov).0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `cv.csv` of two rows, the columns `band_from_cv` reads (plus one it ignores).
    fn cv_csv(dir: &std::path::Path, rows: &[(&str, &str, &str)]) -> std::path::PathBuf {
        let mut s = String::from(
            "dropout,learning_rate,batch_size,hidden,init_seeds,stride,relative_loss,plateau_decay,\
             target_lag,readout,fold_held_out,fold_band_coverage_pct,fold_band_q_w,avg_mae_w\n",
        );
        for (seeds, readout, q) in rows {
            s.push_str(&format!(
                "0.5,0.001,128,64,{seeds},2,1,1,3,{readout},1 2;3;4 5 6,91.0;88.0;93.0,{q},25\n"
            ));
        }
        let path = dir.join("cv.csv");
        std::fs::write(&path, s).unwrap();
        path
    }

    /// The row is the one whose recipe and number of init seeds match the card's; its
    /// widening is the folds' mean, floored at 0; no row, two rows, a fold without a band,
    /// or a file from before the band was recorded is refused, naming the file.
    #[test]
    fn band_from_cv_takes_the_matching_rows_folds() {
        // The shipped card, set to the recipe the rows below describe.
        let mut card = ModelCard::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../config/models/lstm-m100/card.toml"),
        )
        .unwrap();
        card.members = vec![
            "member-11.safetensors".into(),
            "member-13.safetensors".into(),
        ];
        (card.hidden, card.target_lag) = (64, 3);
        card.readout = dronewatt::model::card::Readout::Instant;
        let t = &mut card.training;
        (t.stride, t.dropout, t.learning_rate, t.batch_size) = (2, 0.5, 0.001, 128);
        (t.relative_loss, t.plateau_decay) = (1.0, None);
        let dir = tempfile::tempdir().unwrap();
        // The first member alone and the final readout are other models.
        let path = cv_csv(
            dir.path(),
            &[
                ("7", "Instant", "9;9;9"),
                ("7;11;13", "Final", "8;8;8"),
                ("7;11;13", "Instant", "-2;4;7"),
            ],
        );
        let band = band_from_cv(&path, &card).unwrap();
        assert!((band.widen_w - 3.0).abs() < 1e-12, "{}", band.widen_w);
        assert_eq!((band.folds, band.held_out_flights), (3, 6));
        assert!((band.coverage_pct - 272.0 / 3.0).abs() < 1e-9);
        // Folds that over-cover on average do not narrow the band.
        let path = cv_csv(dir.path(), &[("7;11;13", "Instant", "-2;-4;1")]);
        assert_eq!(band_from_cv(&path, &card).unwrap().widen_w, 0.0);

        let err = |rows: &[(&str, &str, &str)]| {
            let path = cv_csv(dir.path(), rows);
            let e = band_from_cv(&path, &card)
                .err()
                .expect("refused")
                .to_string();
            assert!(e.contains(&path.display().to_string()), "{e}");
            e
        };
        assert!(err(&[("7;11;13", "Final", "1;1;1")]).contains("no row for this model"));
        assert!(err(&[
            ("7;11;13", "Instant", "1;1;1"),
            ("7;11;13", "Instant", "2;2;2")
        ])
        .contains("2 rows match"));
        assert!(err(&[("7;11;13", "Instant", "1;NaN;1")]).contains("no banded window"));
        let old = dir.path().join("old.csv");
        std::fs::write(&old, "hidden,init_seeds\n64,7;11;13\n").unwrap();
        let e = band_from_cv(&old, &card).err().unwrap().to_string();
        assert!(e.contains("no column") && e.contains("old.csv"), "{e}");
    }
}
