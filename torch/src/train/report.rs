//! The held-out flights' scores and what training writes besides the weights: the per-flight
//! test table, the learning curve, the flight plots and the windows as CSV.

use std::path::Path;

use anyhow::Context;

use dronewatt::model::card::Metrics;
use dronewatt::offline::chain::FlightSeries;
use dronewatt::offline::data::{FlightWindows, TEST_FLIGHTS};
use dronewatt::offline::{metrics, plot};

use super::CurvePoint;

/// Per-flight scores on held-out flights.
#[derive(Debug, Clone)]
pub struct FlightScore {
    pub flight: u32,
    pub windows: usize,
    pub mae_w: f64,
    pub mape_in_flight_pct: f64,
    pub energy_error_pct: f64,
    pub band_coverage_pct: f64,
}

/// Score the first model of each flight's series (the LSTM, alone in its chain) the way
/// `eval --all-windows` scores it ([`metrics::score_over`]: every window with a measured
/// power at the model's instant, MAPE in flight, energy from the energy tracker), pooled
/// over the flights ([`metrics::pooled`]), with the share of windows inside its band.
pub fn score(series: &[FlightSeries]) -> anyhow::Result<(Metrics, Vec<FlightScore>)> {
    let (mut per, mut scores, mut inside, mut banded) = (Vec::new(), Vec::new(), 0usize, 0usize);
    for s in series.iter().filter(|s| !s.pred_w.is_empty()) {
        let Some(sc) = metrics::score_over(&s.aligned(0), true) else {
            continue;
        };
        let (mut fin, mut n) = (0usize, 0usize);
        for ((p, m), band) in s.pred_w[0].iter().zip(&s.measured_w).zip(&s.band_w[0]) {
            if p.is_finite() && m.is_finite() {
                n += 1;
                fin += usize::from(band.is_some_and(|(lo, hi)| lo <= *m && *m <= hi));
            }
        }
        inside += fin;
        banded += n;
        scores.push(sc);
        per.push(FlightScore {
            flight: s.flight,
            windows: sc.windows,
            mae_w: sc.mae_w,
            mape_in_flight_pct: sc.mape_pct,
            energy_error_pct: sc.energy_err_pct,
            band_coverage_pct: 100.0 * fin as f64 / n.max(1) as f64,
        });
    }
    let pooled = metrics::pooled(&scores).context("no scorable windows in the test flights")?;
    let metrics = Metrics {
        test_flights: per.iter().map(|p| p.flight).collect(),
        mae_w: pooled.mae_w,
        rmse_w: pooled.rmse_w,
        mape_in_flight_pct: pooled.mape_pct,
        energy_error_pct: pooled.energy_err_pct,
        flight_276_mae_w: per.iter().find(|p| p.flight == 276).map(|p| p.mae_w),
        band_coverage_pct: 100.0 * inside as f64 / banded.max(1) as f64,
    };
    Ok((metrics, per))
}

pub(super) fn write_test_table(out: &Path, per: &[FlightScore]) -> anyhow::Result<()> {
    let mut s = String::from(
        "flight,windows,mae_w,mape_in_flight_pct,energy_error_pct,band_coverage_pct\n",
    );
    for p in per {
        s.push_str(&format!(
            "{},{},{:.3},{:.3},{:.3},{:.2}\n",
            p.flight,
            p.windows,
            p.mae_w,
            p.mape_in_flight_pct,
            p.energy_error_pct,
            p.band_coverage_pct
        ));
    }
    let path = out.join("test_flights.csv");
    std::fs::write(&path, s).with_context(|| format!("{}: cannot write", path.display()))
}

pub(super) fn write_curve(out: &Path, curve: &[CurvePoint]) -> anyhow::Result<()> {
    let mut s = String::from("epoch,step,train_loss,val_loss,val_mae_w\n");
    for c in curve {
        s.push_str(&format!(
            "{},{},{:.6},{:.6},{:.3}\n",
            c.epoch, c.step, c.train_loss, c.val_loss, c.val_mae_w
        ));
    }
    let path = out.join("loss.csv");
    std::fs::write(&path, s).with_context(|| format!("{}: cannot write", path.display()))?;
    let train: Vec<(f64, f64)> = curve
        .iter()
        .map(|c| (c.epoch as f64, c.train_loss))
        .collect();
    let val: Vec<(f64, f64)> = curve.iter().map(|c| (c.epoch as f64, c.val_loss)).collect();
    plot::lines(
        &out.join("loss.png"),
        "Training and validation loss",
        "epoch",
        "loss (scaled)",
        &[("training", train), ("validation", val)],
    )
}

/// Plot the first model of `s` (its estimate and band) against measured power, each
/// estimate at the instant it is for.
pub(super) fn plot_flight(s: &FlightSeries, path: &Path) -> anyhow::Result<()> {
    let t0 = s.t_s.first().copied().unwrap_or(0.0);
    let points = |v: &mut dyn Iterator<Item = f64>| -> Vec<(f64, f64)> {
        s.t_s
            .iter()
            .zip(v)
            .filter(|(_, y)| y.is_finite())
            .map(|(t, y)| (t - t0, y))
            .collect()
    };
    let band = |hi: bool| {
        points(
            &mut s.band_w[0]
                .iter()
                .map(|b| b.map_or(f64::NAN, |(lo, h)| if hi { h } else { lo })),
        )
    };
    plot::lines(
        path,
        &format!("Flight {}: LSTM vs measured power", s.flight),
        "time (s)",
        "power (W)",
        &[
            ("measured", points(&mut s.measured_w.iter().copied())),
            ("LSTM", points(&mut s.pred_w[0].iter().copied())),
            ("band low", band(false)),
            ("band high", band(true)),
        ],
    )
}

/// The samples exported (how many before the newest): the rows a model card's `[trees]`
/// read (`train --trees` records these).
pub(super) const EXPORT_LAGS: [usize; 4] = [0, 1, 3, 9];

/// Write each window's newest sample and lagged copies to a CSV for the LightGBM baseline.
/// `folds` ([`dronewatt::offline::data::cv_folds`]) fill the `fold` column; flights outside
/// them get -1. The features are `set`'s (`train --features`), as the LSTM sees them. Last,
/// `phys_<model>_w`: each physics model's estimate of the window with the
/// vehicle's published parameters (`physics`: nothing fitted on any flight), which the
/// LightGBM scripts read only when asked (`--physics`).
pub(super) fn export_csv(
    flights: &[FlightWindows],
    path: &Path,
    t: usize,
    folds: &[(u32, usize)],
    set: dronewatt::model::card::FeatureSet,
    physics: &mut [Box<dyn dronewatt::model::PowerModel>],
) -> anyhow::Result<()> {
    use std::io::Write;
    let file = std::fs::File::create(path)
        .with_context(|| format!("{}: cannot create", path.display()))?;
    let mut w = std::io::BufWriter::new(file);
    let mut header = vec![
        "flight".to_string(),
        "route".into(),
        "test".into(),
        "fold".into(),
        "t_s".into(),
        "measured_w".into(),
    ];
    header.extend(dronewatt::model::card::TreesBlend::input_names(
        set,
        &EXPORT_LAGS,
    ));
    header.extend(physics.iter().map(|m| format!("phys_{}_w", m.name())));
    writeln!(w, "{}", header.join(","))?;
    let mut rows = 0usize;
    let (mut est, mut inputs) = (Vec::new(), Vec::new());
    let mut per_model: Vec<Vec<f32>> = vec![Vec::new(); physics.len()];
    for f in flights {
        for (m, out) in physics.iter_mut().zip(&mut per_model) {
            m.predict(&f.windows, &mut est);
            out.clear();
            out.extend(est.iter().map(|p| p.power_w));
        }
        let test = TEST_FLIGHTS.contains(&f.flight) as u8;
        // -1: outside the training pool (a test flight, a ground test, no measured power).
        let fold = folds
            .iter()
            .find(|(g, _)| *g == f.flight)
            .map_or(-1, |(_, k)| *k as i64);
        for (i, win) in f.windows.iter().enumerate() {
            let Some(p) = win.last().measured_w.filter(|p| p.is_finite()) else {
                continue;
            };
            let s = &win.samples;
            if s.len() < t {
                continue;
            }
            write!(
                w,
                "{},{},{},{},{:.2},{:.3}",
                f.flight,
                f.route,
                test,
                fold,
                win.t_s(),
                p
            )?;
            // The inputs as the LSTM sees them (`push_inputs`: the home set's position slots
            // relative to home and to the window's first sample), newest row last.
            inputs.clear();
            dronewatt::model::lstm::push_inputs(win, set, s.len(), &mut inputs);
            for v in dronewatt::model::lstm::tree_rows(&inputs, &EXPORT_LAGS).flatten() {
                write!(w, ",{v}")?;
            }
            for est in &per_model {
                write!(w, ",{:.2}", est.get(i).copied().unwrap_or(f32::NAN))?;
            }
            writeln!(w)?;
            rows += 1;
        }
    }
    w.flush()?;
    eprintln!("{}: {rows} windows written", path.display());
    Ok(())
}
