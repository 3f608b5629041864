//! Scoring a trained model directory: the P90 band calibrated on the validation flights (or
//! from a cross-validation), then the test flights through the ingest path and the live chain.

use super::*;

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
pub(super) fn add_trees(
    dir: &Path,
    file: &Path,
    w: f64,
    tcfg: &TelemetryConfig,
) -> anyhow::Result<()> {
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
pub(super) fn band_from_cv(
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
pub(super) fn calibrate_band(
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
