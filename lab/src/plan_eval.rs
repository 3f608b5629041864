//! `dronewatt-lab plan-eval`: the mission forecast judged on the data set's route flights.
//! How each flight's plan is built: [`crate::route`].
//!
//! ## Scores
//!
//! - **pre-flight**: the plan's P50 against the measured ∫V·I of the whole recording;
//!   the P90 covers a flight when measured ≤ P90;
//! - **live at 50 %**: at the middle of the airborne time (first to last row above
//!   `AIRBORNE_W`), the flight's own first half is replayed (position tracked along the
//!   plan with [`Trajectory::locate`](dronewatt::mission::trajectory::Trajectory::locate), the measured energy so far known) and the rest of
//!   the plan forecast from there; scored against the measured energy of the rest;
//! - **baseline** (what autopilots do): mean power since the motors started × the time
//!   left, scored the same way, with two clocks: the ground station's (QGroundControl's
//!   mission time, `gcs_left_s`, the only one a pilot has today) and dronewatt's own (the
//!   plan's time left as flown on paper, which isolates the power model).
//!

use std::path::Path;

use anyhow::Context;

use crate::forecast_fit::finish;
use crate::forecast_fit::fit;
use crate::forecast_fit::prepare;
use crate::forecast_fit::rolling_scales;
use crate::forecast_fit::score::{score, FlightScore};
use crate::forecast_fit::Fitted;
use crate::forecast_fit::Prepared;
use crate::forecast_fit::BOOTSTRAP;
use crate::forecast_fit::TIE_SHARE;
use crate::route::geometry_for;
use dronewatt::config::Config;
use dronewatt::mission::forecast::Calibration;
use dronewatt::model::PowerModel;
use dronewatt::offline::args::{help, DataArg, ForecastArgs};
use dronewatt::offline::data::TEST_FLIGHTS;
use dronewatt::offline::metrics::median;
use dronewatt::offline::plan::models_for;
use dronewatt::source::logs::dataset::{self, Flight};

/// Arguments of `dronewatt-lab plan-eval`.
#[derive(Debug, Clone, clap::Args)]
#[command(mut_arg(
    "config",
    help("Configuration file (models, `[forecast.kinematics]`). Default: built-in defaults")
))]
pub struct PlanEvalArgs {
    #[command(flatten)]
    pub data: DataArg,
    /// Score these test flights only (comma separated). Default: every test flight present.
    #[arg(long, value_delimiter = ',')]
    pub flights: Option<Vec<u32>>,
    /// Fit on these training flights only (comma separated). Default: every route flight not in the test set.
    #[arg(long, value_delimiter = ',')]
    pub train: Option<Vec<u32>>,
    /// Plan every flight in calm air instead of the anemometer's pre-take-off wind.
    #[arg(long)]
    pub no_ground_wind: bool,
    /// Also write, per training flight (never a test flight), what the live-correction
    /// analysis reads (`lab/scripts/mission/lab_live.py`) as JSON into this directory.
    #[arg(long, hide = true, value_name = "DIR")]
    pub dump_live: Option<std::path::PathBuf>,
    #[command(flatten)]
    pub forecast: ForecastArgs,
}

/// Summary of one set of flights.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Summary {
    pub flights: usize,
    pub preflight_median_err_pct: f64,
    pub preflight_max_err_pct: f64,
    pub p90_coverage_pct: f64,
    pub live_median_err_pct: f64,
    pub baseline_live_median_err_pct: f64,
    /// Baseline's median live error over dronewatt's.
    pub live_advantage: f64,
    /// The live baseline with the ground station's clock (`gcs_left_s`): median error, %,
    /// and over dronewatt's.
    pub baseline_gcs_live_median_err_pct: f64,
    pub live_advantage_gcs: f64,
    /// The forecast model's uncorrected median pre-flight error, %.
    pub preflight_uncorrected_median_err_pct: f64,
    /// Pre-flight baseline (training flights' median mean power × planned time): median error, %.
    pub baseline_preflight_median_err_pct: f64,
    /// Baseline's median pre-flight error over dronewatt's.
    pub preflight_advantage: f64,
}

fn summarize(s: &[FlightScore], cal: &Calibration) -> Summary {
    let mut pre: Vec<f64> = s.iter().map(|x| x.preflight_err_pct).collect();
    let mut live: Vec<f64> = s.iter().map(|x| x.live_err_pct).collect();
    let mut base: Vec<f64> = s.iter().map(|x| x.baseline_err_pct).collect();
    // the members' own power, uncorrected, their mean
    let mut raw: Vec<f64> = s
        .iter()
        .filter_map(|x| {
            let e: Vec<f64> = cal
                .members
                .iter()
                .filter_map(|c| {
                    x.models_raw_wh
                        .iter()
                        .find(|(n, _)| *n == c.model)
                        .map(|(_, e)| *e)
                })
                .collect();
            (!e.is_empty()).then(|| {
                100.0 * (e.iter().sum::<f64>() / e.len() as f64 - x.measured_wh).abs()
                    / x.measured_wh
            })
        })
        .collect();
    let live_m = median(&mut live);
    let base_m = median(&mut base);
    let base_gcs_m = median(&mut s.iter().map(|x| x.baseline_gcs_err_pct).collect::<Vec<_>>());
    let mut base_pre: Vec<f64> = s.iter().map(|x| x.baseline_preflight_err_pct).collect();
    let pre_m = median(&mut pre);
    let base_pre_m = median(&mut base_pre);
    Summary {
        flights: s.len(),
        preflight_median_err_pct: pre_m,
        preflight_max_err_pct: pre.iter().copied().fold(0.0, f64::max),
        p90_coverage_pct: 100.0 * s.iter().filter(|x| x.p90_covers).count() as f64
            / s.len().max(1) as f64,
        live_median_err_pct: live_m,
        baseline_live_median_err_pct: base_m,
        live_advantage: base_m / live_m.max(1e-9),
        baseline_gcs_live_median_err_pct: base_gcs_m,
        live_advantage_gcs: base_gcs_m / live_m.max(1e-9),
        preflight_uncorrected_median_err_pct: median(&mut raw),
        baseline_preflight_median_err_pct: base_pre_m,
        preflight_advantage: base_pre_m / pre_m.max(1e-9),
    }
}

/// Everything `plan-eval` found.
#[derive(Debug, Clone, serde::Serialize)]
pub struct PlanEvalReport {
    /// The fitted correction (paste into `[forecast.calibration]`).
    pub calibration: Calibration,
    /// Per model on the training flights (rolling validation): name, its best number of
    /// recent flights to fit on (0 = all), its median |error| (%).
    pub models_fit: Vec<(String, f64, f64)>,
    /// How the forecast's power is weighted (a [`crate::forecast_fit::BASES`] name), and each way's median
    /// error (%) on the training flights (rolling validation, best model).
    pub basis: String,
    pub bases_fit: Vec<(String, f64)>,
    pub training_flights: Vec<u32>,
    pub training: Summary,
    pub test: Summary,
    pub test_flights: Vec<FlightScore>,
    /// The training flights scored as in the rolling validation (each with the scale of
    /// the training flights before it).
    pub training_scores: Vec<FlightScore>,
    pub ground_wind: bool,
    /// The calibration's members, each fitted and scored alone: what the mean owes to each.
    pub members_alone: Vec<Alone>,
    /// Per route: the training flights' rolling-validation figures beside the test flights'
    /// (the live forecast against both baselines' clocks among them).
    pub routes: Vec<RouteSummary>,
}

/// One route's figures ([`PlanEvalReport::routes`]); a split with no flight of the route is
/// absent.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RouteSummary {
    pub route: String,
    pub training: Option<Summary>,
    pub test: Option<Summary>,
}

/// [`RouteSummary`] for every route flown in either split, in route order.
fn by_route(train: &[FlightScore], test: &[FlightScore], cal: &Calibration) -> Vec<RouteSummary> {
    let mut routes: Vec<&str> = train.iter().chain(test).map(|f| f.route.as_str()).collect();
    routes.sort_unstable();
    routes.dedup();
    let of = |set: &[FlightScore], r: &str| {
        let v: Vec<FlightScore> = set.iter().filter(|f| f.route == r).cloned().collect();
        (!v.is_empty()).then(|| summarize(&v, cal))
    };
    routes
        .into_iter()
        .map(|r| RouteSummary {
            route: r.to_string(),
            training: of(train, r),
            test: of(test, r),
        })
        .collect()
}

/// One member of the fit forecasting alone ([`PlanEvalReport::members_alone`]).
#[derive(Debug, Clone, serde::Serialize)]
pub struct Alone {
    pub model: String,
    /// Its median error on the training flights (rolling validation), %.
    pub training_err_pct: f64,
    /// Share of the paired resamples of the training flights in which its median error is
    /// no larger than the best's (`tie_share`), %.
    pub tie_share_pct: f64,
    /// The test flights forecast with it alone.
    pub test: Summary,
}

/// Options of [`plan_eval`].
#[derive(Debug, Clone, Default)]
pub struct PlanEvalOptions {
    /// Test flights to score (default: [`TEST_FLIGHTS`] present).
    pub test: Option<Vec<u32>>,
    /// Training flights to fit on (default: every route flight not in [`TEST_FLIGHTS`]).
    pub train: Option<Vec<u32>>,
    /// Plan with the pre-take-off anemometer wind.
    pub ground_wind: bool,
    /// Write the training flights' live-correction dump here ([`crate::live_dump`]).
    pub dump_live: Option<std::path::PathBuf>,
}

/// Run the evaluation (see the module docs).
pub fn plan_eval(
    data: &Path,
    cfg: &Config,
    models: &mut [Box<dyn PowerModel>],
    opt: &PlanEvalOptions,
) -> anyhow::Result<PlanEvalReport> {
    let ds = dataset::read_flights(data, None)?;
    let is_route = |f: &Flight| f.route.starts_with('R');
    let test_ids: Vec<u32> = match &opt.test {
        Some(t) => t.clone(),
        None => TEST_FLIGHTS
            .iter()
            .copied()
            .filter(|t| ds.flights.iter().any(|f| f.flight == *t))
            .collect(),
    };
    for t in &test_ids {
        if !TEST_FLIGHTS.contains(t) {
            anyhow::bail!("flight {t} is not a test flight ({TEST_FLIGHTS:?})");
        }
        if !ds.flights.iter().any(|f| f.flight == *t) {
            anyhow::bail!("{}: flight {t} is not in this file", data.display());
        }
    }
    let train: Vec<&Flight> = ds
        .flights
        .iter()
        .filter(|f| is_route(f) && !TEST_FLIGHTS.contains(&f.flight))
        .filter(|f| opt.train.as_ref().is_none_or(|t| t.contains(&f.flight)))
        .collect();
    if train.is_empty() {
        anyhow::bail!("no training flights to fit the forecast on");
    }
    // every route flight that may lend its track: training flights of the route, never the flight itself
    let all_train: Vec<&Flight> = ds
        .flights
        .iter()
        .filter(|f| is_route(f) && !TEST_FLIGHTS.contains(&f.flight))
        .collect();
    let (prepared_train, prepared_test) = prepare_sets(
        &ds.flights,
        &train,
        &test_ids,
        &all_train,
        opt.ground_wind,
        cfg,
        models,
    )?;
    let Fitted {
        cal,
        basis,
        per_model: models_fit,
        per_basis: bases_fit,
        ties,
    } = fit(&prepared_train);
    let mut mean_w: Vec<f64> = prepared_train.iter().map(|p| p.flight_mean_w).collect();
    let baseline_w = median(&mut mean_w);
    let scores = |cal: &Calibration, set: &[Prepared]| -> Vec<FlightScore> {
        set.iter()
            .map(|p| {
                score(
                    p,
                    cal,
                    &rolling_scales(&prepared_train, cal, p.flight),
                    baseline_w,
                )
            })
            .collect()
    };
    let train_scores = scores(&cal, &prepared_train);
    let test_scores = scores(&cal, &prepared_test);
    if let Some(dir) = &opt.dump_live {
        crate::live_dump::dump_live(dir, &ds.flights, &prepared_train, &train_scores, &cal)?;
    }
    // each member alone: the member as the fit made it, with its own P90 ratio and live weight
    let members_alone = if cal.members.len() > 1 {
        cal.members
            .iter()
            .map(|c| {
                let one = finish(&prepared_train, vec![c.clone()]);
                let training_err_pct = models_fit
                    .iter()
                    .find(|m| m.0 == c.model)
                    .map_or(f64::NAN, |m| m.2);
                let tie_share_pct = 100.0
                    * ties
                        .iter()
                        .find(|t| t.0 == c.model)
                        .map_or(f64::NAN, |t| t.1);
                Alone {
                    model: c.model.clone(),
                    training_err_pct,
                    tie_share_pct,
                    test: summarize(&scores(&one, &prepared_test), &one),
                }
            })
            .collect()
    } else {
        Vec::new()
    };
    Ok(PlanEvalReport {
        routes: by_route(&train_scores, &test_scores, &cal),
        members_alone,
        training: summarize(&train_scores, &cal),
        test: summarize(&test_scores, &cal),
        calibration: cal,
        models_fit,
        basis,
        bases_fit,
        training_flights: prepared_train.iter().map(|p| p.flight).collect(),
        test_flights: test_scores,
        training_scores: train_scores,
        ground_wind: opt.ground_wind,
    })
}

/// Prepare the training flights (a flight that fails is skipped, with a warning) and the
/// test flights (one that fails fails the run), each planned along the track
/// [`geometry_for`] lends it, with a progress bar.
fn prepare_sets(
    flights: &[Flight],
    train: &[&Flight],
    test_ids: &[u32],
    all_train: &[&Flight],
    ground_wind: bool,
    cfg: &Config,
    models: &mut [Box<dyn PowerModel>],
) -> anyhow::Result<(Vec<Prepared>, Vec<Prepared>)> {
    let bar = indicatif::ProgressBar::new((train.len() + test_ids.len()) as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "forecasting flights {bar:30} {pos}/{len} [{elapsed}<{eta}]",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut prepared_train = Vec::new();
    for f in train {
        match prepare(f, geometry_for(f, all_train), ground_wind, cfg, models) {
            Ok(p) => prepared_train.push(p),
            Err(e) => tracing::warn!("training flight {} skipped: {e:#}", f.flight),
        }
        bar.inc(1);
    }
    let mut prepared_test = Vec::new();
    for t in test_ids {
        let f = flights
            .iter()
            .find(|f| f.flight == *t)
            .with_context(|| format!("flight {t} missing"))?;
        prepared_test.push(prepare(
            f,
            geometry_for(f, all_train),
            ground_wind,
            cfg,
            models,
        )?);
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok((prepared_train, prepared_test))
}

/// The table `plan-eval` prints.
pub fn eval_table(r: &PlanEvalReport) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let c = &r.calibration;
    let _ = writeln!(
        s,
        "fitted on {} training flights: weighting {:?} ({}), P90 = {:.4} × P50, live weight {:.2}{}; the P50 is the mean of {} member(s):",
        r.training_flights.len(),
        r.basis,
        r.bases_fit.iter().map(|(b, e)| format!("{b} {e:.2} %")).collect::<Vec<_>>().join(", "),
        c.p90_ratio,
        c.live_weight,
        if r.ground_wind { ", ground wind" } else { ", calm air" },
        c.members.len()
    );
    for m in &c.members {
        let err = r
            .models_fit
            .iter()
            .find(|x| x.0 == m.model)
            .map_or(f64::NAN, |x| x.2);
        let _ = writeln!(
            s,
            "  {:<16} training {:.2} %: power × {:.3}/{:.3}/{:.3} (climb/descent/other) + vertical work × {:.3}/{:.3} (up/down), × {:.4} (median measured/forecast of the {} training flights before each flight; latest)",
            m.model, err, m.phase_scale[0], m.phase_scale[1], m.phase_scale[2], m.climb_work[0], m.climb_work[1], m.scale, m.recent_flights
        );
    }
    let _ = writeln!(
        s,
        "{:>6} {:<5} {:>5} {:>6} {:<12} {:>5} {:>6} {:>6} {:>8} {:>8} {:>8} {:>7} {:>4} {:>8} {:>8} {:>7} {:>8} {:>7} {:>8} {:>7}",
        "flight", "route", "m/s", "g", "alt", "geom", "meas s", "plan s", "meas Wh", "P50 Wh", "P90 Wh", "err %", "P90", "rest Wh", "fc Wh", "err %", "gcs Wh", "err %", "base Wh", "err %"
    );
    for f in &r.test_flights {
        let _ = writeln!(
            s,
            "{:>6} {:<5} {:>5.1} {:>6.0} {:<12} {:>5} {:>6.0} {:>6.0} {:>8.2} {:>8.2} {:>8.2} {:>7.2} {:>4} {:>8.2} {:>8.2} {:>7.2} {:>8.2} {:>7.2} {:>8.2} {:>7.2}",
            f.flight,
            f.route,
            f.speed_m_s,
            f.payload_g,
            f.altitude,
            f.geometry_from,
            f.measured_s,
            f.planned_s,
            f.measured_wh,
            f.p50_wh,
            f.p90_wh,
            f.preflight_err_pct,
            if f.p90_covers { "yes" } else { "no" },
            f.live_measured_rest_wh,
            f.live_forecast_rest_wh,
            f.live_err_pct,
            f.baseline_gcs_rest_wh,
            f.baseline_gcs_err_pct,
            f.baseline_rest_wh,
            f.baseline_err_pct
        );
    }
    for (name, x) in [("test", &r.test), ("training", &r.training)] {
        let _ = writeln!(
            s,
            "{name} ({} flights): pre-flight median {:.2} % (max {:.2} %; uncorrected model {:.2} %; baseline {:.2} %, {:.1}× better), P90 covers {:.0} %; live at 50 %: median {:.2} % vs baseline {:.2} % with the ground station's clock ({:.1}× better), {:.2} % with dronewatt's ({:.1}×)",
            x.flights,
            x.preflight_median_err_pct,
            x.preflight_max_err_pct,
            x.preflight_uncorrected_median_err_pct,
            x.baseline_preflight_median_err_pct,
            x.preflight_advantage,
            x.p90_coverage_pct,
            x.live_median_err_pct,
            x.baseline_gcs_live_median_err_pct,
            x.live_advantage_gcs,
            x.baseline_live_median_err_pct,
            x.live_advantage
        );
    }
    let _ = writeln!(
        s,
        "live at 50 % by route, median error (flights): dronewatt | baseline with the ground station's clock | with dronewatt's clock"
    );
    for rs in &r.routes {
        let cell = |x: &Option<Summary>| {
            x.as_ref().map_or(String::from("—"), |x| {
                format!(
                    "{:.2} % | {:.2} % ({:.1}×) | {:.2} % ({:.1}×) ({})",
                    x.live_median_err_pct,
                    x.baseline_gcs_live_median_err_pct,
                    x.live_advantage_gcs,
                    x.baseline_live_median_err_pct,
                    x.live_advantage,
                    x.flights
                )
            })
        };
        let _ = writeln!(
            s,
            "  {:<4} test {}; training (rolling) {}",
            rs.route,
            cell(&rs.test),
            cell(&rs.training)
        );
    }
    if !r.members_alone.is_empty() {
        let _ = writeln!(s, "the members alone (each ties with the best on the training flights: no larger median error in ≥ {:.0} % of {BOOTSTRAP} paired resamples), each fitted and scored by itself:", 100.0 * TIE_SHARE);
        for t in &r.members_alone {
            let x = &t.test;
            let _ = writeln!(
                s,
                "  {:<16} training {:.2} % (no larger than the best's in {:.0} % of resamples) -> test pre-flight median {:.2} % (max {:.2} %, P90 covers {:.0} %), live {:.2} % vs baseline {:.2} %",
                t.model, t.training_err_pct, t.tie_share_pct, x.preflight_median_err_pct, x.preflight_max_err_pct, x.p90_coverage_pct, x.live_median_err_pct, x.baseline_live_median_err_pct
            );
        }
    }
    s
}

/// `dronewatt-lab plan-eval`.
pub fn run_plan_eval(a: PlanEvalArgs) -> anyhow::Result<()> {
    let cfg = a.forecast.config.load()?;
    let data = a.data.path();
    let mut models = models_for(&cfg, &a.forecast.calibrated)?;
    let opt = PlanEvalOptions {
        test: a.flights.clone(),
        train: a.train.clone(),
        ground_wind: !a.no_ground_wind,
        dump_live: a.dump_live.clone(),
    };
    let r = plan_eval(&data, &cfg, &mut models, &opt)?;
    a.forecast.json.publish(&r, || eval_table(&r))
}
