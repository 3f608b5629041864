//! `dronewatt-lab battery-eval`: the pack model of [`dronewatt::battery`] (its shipped TB48D
//! constants, fitted on the training flights by `lab/scripts/battery/fit.py`) scored on the
//! M100 data set, training and test flights ([`TEST_FLIGHTS`]) apart, beside what the
//! autopilots do. A port of fit.py's evaluation: rest voltages and pack chains in [`prep`],
//! one flight's figures in [`score`]; the figures should match the script's `results.json`,
//! but for the autopilots at landing, which run as they do today ([`autopilots`]) where the
//! script has simpler stand-ins (a fixed 5 mΩ a cell for PX4, a take-off-step R for ArduPilot).
//!
//! Figures (median over flights of |error|; volts are pack volts, 6S):
//! - energy between the start and end rest voltages on the OCV curve vs measured ∫V·I, Wh;
//!   end rest V from the start rest V and the measured energy, V;
//! - loaded-voltage RMSE on rows with I > 3 A: open loop (current in, voltage out) and the
//!   online estimator (one step a-priori; 10 s ahead with the measured current), V;
//! - lowest loaded voltage forecast pre-flight **along the plan** as `plan-eval` builds it
//!   (route flights; [`plan`]) from the start resting voltage, with the sag term of
//!   [`dronewatt::battery::forecast::dip`]; beside it, and from half the airborne time, the same
//!   given the flight's **measured** power profile (a perfect power forecast: this isolates
//!   the pack model from the power model), and the first 3.5 V/cell crossing;
//! - baselines ([`autopilots`], as PX4 and ArduPilot run today): PX4's linear rules (3.6
//!   and older 3.5 → 4.05 V/cell, × 129.96 Wh rated) and its estimator (RLS resistance for
//!   the load compensation, τ = 1 s, the voltage alone for 2 s, then fused with coulomb
//!   counting), "full pack at take-off", ArduPilot (full at boot, mAh counting,
//!   `voltage_resting_estimate`); each at take-off, at the last in-flight sample (the
//!   resting voltage it reads, the energy it leaves) and between the rest voltages. Each
//!   row of the table names its truth.
//!
//! Heat carry-over: a flight flown minutes after the previous one on the same pack starts
//! with that flight's heat proxy, decayed over the gap (dates/times from `flights.csv`,
//! which carries parameters.csv's), as in fit.py.

pub mod autopilots;
pub mod plan;
pub mod prep;
pub mod score;
mod table;
pub use table::table;

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;

use dronewatt::battery::forecast::{SAG_IN_FLIGHT, SAG_PREFLIGHT};
use dronewatt::battery::{forecast, CircuitParams, OcvCurve, PACK_SCALE_CARRY};
use dronewatt::offline::args::{help, CalibratedArg, DataArg, JsonArg};
use dronewatt::offline::data::TEST_FLIGHTS;
use dronewatt::source::logs::dataset;

use prep::{
    fill_grid, heat_carry, link_chains, median, prepare, previous_pack_scale, Prepared, DT,
    RELAX_C_V, RELAX_K_S,
};
use score::{score_flight, FlightFigures, Traces, THR_V};

/// Targets (test figures should meet them): energy Wh, end V, open-loop V, pre-flight V, half-time V.
pub const TARGETS: [(&str, f64); 5] = [
    ("ocv_energy_mae_wh", 1.0),
    ("ocv_end_v_mae_v", 0.05),
    ("ecm_median_rmse_v", 0.20),
    ("preflight_plan_min_v_mae", 0.30),
    ("halftime_min_v_mae", 0.15),
];

/// Arguments of `dronewatt-lab battery-eval`.
#[derive(Debug, Clone, clap::Args)]
#[command(mut_arg(
    "calibrated",
    help("Calibrated vehicle profile for the pre-flight plan's power (`plan-eval`'s models)")
))]
pub struct BatteryEvalArgs {
    #[command(flatten)]
    pub data: DataArg,
    /// Score these flights only (comma separated; training or test by their number). Default: all.
    #[arg(long, value_delimiter = ',')]
    pub flights: Option<Vec<u32>>,
    #[command(flatten)]
    pub json: JsonArg,
    /// Write a PNG of one test flight: measured and open-loop loaded voltage, and the forecast from half time.
    #[arg(long, value_name = "PNG")]
    pub plot: Option<PathBuf>,
    #[command(flatten)]
    pub calibrated: CalibratedArg,
}

/// Medians over one set of flights (names as in fit.py's results.json).
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct SetSummary {
    /// Flights scored under load (routes, not hover/A) and with both rest voltages.
    pub n_flights: usize,
    pub n_rest: usize,
    pub ocv_energy_mae_wh: f64,
    pub ocv_end_v_mae_v: f64,
    pub px4_36_energy_mae_wh: f64,
    pub px4_35_energy_mae_wh: f64,
    pub full_pack_start_energy_err_wh: f64,
    pub px4_start_energy_err_wh: f64,
    pub ardupilot_start_mah_err: f64,
    pub ecm_median_rmse_v: f64,
    pub online_onestep_rmse_v: f64,
    pub online_10s_rmse_v: f64,
    pub preflight_min_v_mae: f64,
    pub preflight_ma5_min_v_mae: f64,
    /// Route flights with a plan scored under load, and the median |error| of the lowest
    /// loaded voltage forecast pre-flight along the plan (`plan-eval`'s power), V.
    pub n_plan: usize,
    pub preflight_plan_min_v_mae: f64,
    pub halftime_min_v_mae: f64,
    /// From half time along the rest of the plan (× the live factor), V.
    pub halftime_plan_min_v_mae: f64,
    /// Flights that cross 3.5 V/cell under load; median |error| over those where a crossing
    /// was forecast; how many crossings were not forecast at all.
    pub n_cross: usize,
    pub cross35_preflight_mae_s: f64,
    pub cross35_preflight_missed: usize,
    pub n_cross_after_half: usize,
    pub cross35_halftime_mae_s: f64,
    pub cross35_halftime_missed: usize,
    /// The autopilots on the same crossings: median |when raised − crossing| where raised,
    /// and how many crossings each never answered (PX4's low warning, ArduPilot's failsafe).
    pub cross35_px4_low_mae_s: f64,
    pub cross35_px4_low_missed: usize,
    pub cross35_ardupilot_fs_mae_s: f64,
    pub cross35_ardupilot_fs_missed: usize,
    pub rest_under_load_ours_mae_v: f64,
    pub rest_under_load_px4_mae_v: f64,
    pub rest_under_load_ardupilot_mae_v: f64,
    /// Energy left at the last in-flight sample, median |error| against our curve at the
    /// end rest voltage, Wh: ours, PX4, ArduPilot, full pack at take-off.
    pub landing_energy_ours_mae_wh: f64,
    pub landing_energy_px4_mae_wh: f64,
    pub landing_energy_ardupilot_mae_wh: f64,
    pub landing_energy_full_pack_mae_wh: f64,
}

/// The relaxation correction refitted here on the training pairs (a check of the port:
/// it should give the shipped constants) and its error on the test pairs.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RelaxCheck {
    pub shipped_k_s: f64,
    pub shipped_c_v: f64,
    pub refit_k_s: f64,
    pub refit_c_v: f64,
    pub n_pairs: usize,
    /// Next flight's start rest V − this flight's corrected end rest V, test pairs, V.
    pub test_pairs_err_v: Vec<f64>,
}

/// Everything `battery-eval` computes.
#[derive(Debug, Clone, serde::Serialize)]
pub struct BatteryEvalReport {
    pub data: String,
    pub params: ParamsOut,
    pub curve_v_cell: Vec<f64>,
    pub curve_energy_wh: Vec<f64>,
    pub relax: RelaxCheck,
    pub heat_carry_over: String,
    pub power_profile: String,
    pub targets: std::collections::BTreeMap<String, f64>,
    pub train: SetSummary,
    pub test: SetSummary,
    pub test_flights: Vec<u32>,
    pub flights: Vec<FlightFigures>,
}

/// [`CircuitParams`] as written to JSON.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ParamsOut {
    pub n_cells: u32,
    pub r0_ohm: f64,
    pub r1_ohm: f64,
    pub tau1_s: f64,
    pub warm_a: f64,
    pub heat_scale_a2s: f64,
    pub tau_heat_s: f64,
    pub bias_v: f64,
    pub lambda: f64,
}

fn abs_median<'a>(fl: &'a [&'a FlightFigures], f: impl Fn(&FlightFigures) -> f64 + 'a) -> f64 {
    median(fl.iter().map(|x| f(x).abs()))
}

fn summarise(fl: &[&FlightFigures]) -> SetSummary {
    let ecm: Vec<&FlightFigures> = fl
        .iter()
        .copied()
        .filter(|f| f.ecm_rmse_v.is_finite())
        .collect();
    let rest: Vec<&FlightFigures> = fl
        .iter()
        .copied()
        .filter(|f| f.ocv_energy_err_wh.is_finite())
        .collect();
    let cross: Vec<&FlightFigures> = ecm
        .iter()
        .copied()
        .filter(|f| f.cross35_measured_s.is_finite())
        .collect();
    let m = |f: fn(&FlightFigures) -> f64| abs_median(&ecm, f);
    let r = |f: fn(&FlightFigures) -> f64| abs_median(&rest, f);
    SetSummary {
        n_flights: ecm.len(),
        n_rest: rest.len(),
        ocv_energy_mae_wh: r(|f| f.ocv_energy_err_wh),
        ocv_end_v_mae_v: r(|f| f.ocv_end_v_err_v),
        px4_36_energy_mae_wh: r(|f| f.px4_36_energy_err_wh),
        px4_35_energy_mae_wh: r(|f| f.px4_35_energy_err_wh),
        full_pack_start_energy_err_wh: r(|f| f.full_pack_start_energy_err_wh),
        px4_start_energy_err_wh: r(|f| f.px4_start_energy_err_wh),
        ardupilot_start_mah_err: r(|f| f.ardupilot_start_mah_err),
        ecm_median_rmse_v: m(|f| f.ecm_rmse_v),
        online_onestep_rmse_v: m(|f| f.online_onestep_rmse_v),
        online_10s_rmse_v: m(|f| f.online_10s_rmse_v),
        preflight_min_v_mae: m(|f| f.preflight_min_v_err),
        preflight_ma5_min_v_mae: m(|f| f.preflight_ma5_min_v_err),
        n_plan: ecm
            .iter()
            .filter(|f| f.preflight_plan_min_v_err.is_finite())
            .count(),
        preflight_plan_min_v_mae: m(|f| f.preflight_plan_min_v_err),
        halftime_min_v_mae: m(|f| f.halftime_min_v_err),
        halftime_plan_min_v_mae: m(|f| f.halftime_plan_min_v_err),
        n_cross: cross.len(),
        cross35_preflight_mae_s: abs_median(&cross, |f| f.cross35_preflight_err_s),
        cross35_preflight_missed: cross.iter().filter(|f| f.cross35_preflight_missed).count(),
        n_cross_after_half: cross
            .iter()
            .filter(|f| f.cross35_halftime_err_s.is_finite() || f.cross35_halftime_missed)
            .count(),
        cross35_halftime_mae_s: abs_median(&cross, |f| f.cross35_halftime_err_s),
        cross35_halftime_missed: cross.iter().filter(|f| f.cross35_halftime_missed).count(),
        cross35_px4_low_mae_s: abs_median(&cross, |f| f.cross35_px4_low_err_s),
        cross35_px4_low_missed: cross.iter().filter(|f| f.cross35_px4_low_missed).count(),
        cross35_ardupilot_fs_mae_s: abs_median(&cross, |f| f.cross35_ardupilot_fs_err_s),
        cross35_ardupilot_fs_missed: cross
            .iter()
            .filter(|f| f.cross35_ardupilot_fs_missed)
            .count(),
        rest_under_load_ours_mae_v: m(|f| f.rest_under_load_ours_v),
        rest_under_load_px4_mae_v: m(|f| f.rest_under_load_px4_v),
        rest_under_load_ardupilot_mae_v: m(|f| f.rest_under_load_ardupilot_v),
        landing_energy_ours_mae_wh: m(|f| f.landing_energy_ours_err_wh),
        landing_energy_px4_mae_wh: m(|f| f.landing_energy_px4_err_wh),
        landing_energy_ardupilot_mae_wh: m(|f| f.landing_energy_ardupilot_err_wh),
        landing_energy_full_pack_mae_wh: m(|f| f.landing_energy_full_pack_err_wh),
    }
}

/// Refit v_next_start − v_end_meas = k·slope + c on the training pairs (2×2 normal equations).
fn relax_check(all: &[Prepared]) -> RelaxCheck {
    let by: HashMap<u32, &Prepared> = all.iter().map(|p| (p.flight, p)).collect();
    let pairs = |test: bool| {
        all.iter()
            .filter(move |p| p.test == test)
            .filter_map(|p| Some((p, *by.get(&p.next?)?)))
            .filter(move |(_, q)| q.test == test || test)
            .filter(|(p, _)| p.end_slope.is_finite())
            .collect::<Vec<_>>()
    };
    let tr = pairs(false);
    let (mut sxx, mut sx, mut sxy, mut sy, n) = (0.0, 0.0, 0.0, 0.0, tr.len() as f64);
    for (p, q) in &tr {
        let (x, y) = (p.end_slope, q.v_start - p.v_end_meas);
        (sxx, sx, sxy, sy) = (sxx + x * x, sx + x, sxy + x * y, sy + y);
    }
    let det = sxx * n - sx * sx;
    RelaxCheck {
        shipped_k_s: RELAX_K_S,
        shipped_c_v: RELAX_C_V,
        refit_k_s: (sxy * n - sx * sy) / det,
        refit_c_v: (sxx * sy - sx * sxy) / det,
        n_pairs: tr.len(),
        test_pairs_err_v: pairs(true)
            .iter()
            .map(|(p, q)| q.v_start - p.v_end_rest)
            .collect(),
    }
}

/// Score the shipped model on the data set (`only`: these flights; chains use every flight).
/// Returns the report and, for the plot, each scored flight's traces.
pub fn battery_eval(
    data: &Path,
    only: Option<&[u32]>,
    calibrated: &CalibratedArg,
) -> anyhow::Result<(BatteryEvalReport, Vec<Prepared>, HashMap<u32, Traces>)> {
    let ds = dataset::read_flights(data, None)
        .with_context(|| format!("{}: cannot read the data set", data.display()))?;
    if !ds.skipped.is_empty() {
        tracing::warn!(
            "{}: {} rows skipped while reading",
            data.display(),
            ds.skipped.len()
        );
    }
    if let Some(want) = only {
        dronewatt::offline::data::require_flights(&ds.flights, want, data)?;
    }
    let mut all: Vec<Prepared> = ds
        .flights
        .iter()
        .map(|f| prepare(f, TEST_FLIGHTS.contains(&f.flight)))
        .collect();
    let plans = plan::plan_powers(&ds.flights, calibrated)?;
    drop(ds);
    link_chains(&mut all);
    for p in all.iter_mut().filter(|p| p.ecm_ok()) {
        fill_grid(p);
    }
    let relax = relax_check(&all);
    let params = CircuitParams::default();
    let curve = OcvCurve::tb48d();
    let prev: HashMap<u32, u32> = all
        .iter()
        .filter_map(|p| Some((p.next?, p.flight)))
        .collect();
    let by_id: HashMap<u32, &Prepared> = all.iter().map(|p| (p.flight, p)).collect();
    let mut cache = HashMap::new();
    let chosen: Vec<&Prepared> = all
        .iter()
        .filter(|p| only.is_none_or(|w| w.contains(&p.flight)))
        .collect();
    let bar = if chosen.len() > 4 {
        indicatif::ProgressBar::new(chosen.len() as u64)
    } else {
        indicatif::ProgressBar::hidden()
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "scoring flights {bar:30} {pos}/{len} [{elapsed}<{eta}]",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut flights = Vec::new();
    let mut traces = HashMap::new();
    for p in &chosen {
        let h0 = heat_carry(p.flight, &by_id, &prev, params.tau_heat_s, &mut cache);
        // The pack's resistance as its previous flight showed it, when there was one.
        let k_prev = previous_pack_scale(p.flight, &by_id, &prev, params, &curve, &mut cache);
        let flight_params = k_prev.map_or(params, |k| params.carried_over(k, PACK_SCALE_CARRY));
        let (mut f, tr) = score_flight(p, h0, flight_params, &curve, plans.get(&p.flight));
        f.k_prev = k_prev;
        if f.ecm_rmse_v.is_finite() || f.ocv_energy_err_wh.is_finite() {
            traces.insert(p.flight, tr);
            flights.push(f);
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    let set = |test: bool| {
        flights
            .iter()
            .filter(|f| f.test == test)
            .collect::<Vec<_>>()
    };
    let (train, test) = (summarise(&set(false)), summarise(&set(true)));
    let test_flights = flights
        .iter()
        .filter(|f| f.test && f.ecm_rmse_v.is_finite())
        .map(|f| f.flight)
        .collect();
    let report = BatteryEvalReport {
        data: data.display().to_string(),
        params: ParamsOut {
            n_cells: params.n_cells,
            r0_ohm: params.r0,
            r1_ohm: params.r1,
            tau1_s: params.tau1_s,
            warm_a: params.warm_a,
            heat_scale_a2s: params.heat_scale,
            tau_heat_s: params.tau_heat_s,
            bias_v: params.bias_v,
            lambda: params.lambda,
        },
        curve_v_cell: dronewatt::battery::ocv::TB48D_V.to_vec(),
        curve_energy_wh: dronewatt::battery::ocv::TB48D_E_WH.to_vec(),
        relax,
        heat_carry_over: "from the previous flight on the same pack (consecutive flight, same date, start ≤ 25 min later, rest voltages consistent), decayed over the gap; so is the pack's resistance scale k, R·(1 + 0.555·(k − 1))".into(),
        power_profile: format!(
            "pre-flight along the plan as plan-eval builds it (route flights: {} training, {} test), the smooth path's sag deepened by {SAG_PREFLIGHT} (from half time {SAG_IN_FLIGHT}) for the transients it lacks; the rows marked 'measured power' are given the flight's own measured power (a perfect power forecast: the pack model alone, no sag term)",
            train.n_plan, test.n_plan
        ),
        targets: TARGETS.iter().map(|(k, v)| ((*k).to_string(), *v)).collect(),
        train,
        test,
        test_flights,
        flights,
    };
    Ok((report, all, traces))
}

/// The plot: measured and open-loop loaded voltage over one flight, and the half-time forecast.
fn plot(path: &Path, p: &Prepared, tr: &Traces) -> anyhow::Result<()> {
    let pts = |v: &[f64]| {
        p.tg.iter()
            .zip(v)
            .filter(|(_, y)| y.is_finite())
            .map(|(&t, &y)| (t, y))
            .collect::<Vec<_>>()
    };
    let mut fc = Vec::new();
    if let Some((sm, j)) = &tr.mid {
        let prof: Vec<(f64, f64)> = p.vg.iter().zip(&p.ig).map(|(v, i)| (DT, v * i)).collect();
        for n in (*j..prof.len()).step_by(10) {
            fc.push((p.tg[n], forecast(sm, &prof[*j..=n], &[]).v_end));
        }
    }
    let thr = vec![(0.0, THR_V), (p.tg.last().copied().unwrap_or(1.0), THR_V)];
    let title = format!("flight {} ({}): loaded voltage, 6S pack", p.flight, p.route);
    dronewatt::offline::plot::lines(
        path,
        &title,
        "time (s)",
        "voltage (V)",
        &[
            ("measured", pts(&p.vg)),
            ("model, open loop (current in)", pts(&tr.open_loop_v)),
            ("forecast from half time (measured power)", fc),
            ("3.5 V/cell", thr),
        ],
    )
}

/// `dronewatt-lab battery-eval`.
pub fn run(a: BatteryEvalArgs) -> anyhow::Result<()> {
    let data = a.data.path();
    let (report, all, traces) = battery_eval(&data, a.flights.as_deref(), &a.calibrated)?;
    if let Some(png) = &a.plot {
        let pick = report.test_flights.first().or_else(|| {
            report
                .flights
                .iter()
                .find(|f| f.ecm_rmse_v.is_finite())
                .map(|f| &f.flight)
        });
        match pick.and_then(|f| Some((all.iter().find(|p| p.flight == *f)?, traces.get(f)?))) {
            Some((p, tr)) => {
                plot(png, p, tr)?;
                tracing::info!("wrote {} (flight {})", png.display(), p.flight);
            }
            None => tracing::warn!("no flight scored under load: no plot written"),
        }
    }
    a.json.publish(&report, || table(&report))
}
