//! `dronewatt plan FILE`: the pre-flight forecast of a plan (table, `--json`, plot).

use std::path::{Path, PathBuf};

use anyhow::Context;

use crate::config::Config;
use crate::mission::forecast::{forecast, MissionForecast};
use crate::mission::plan::Plan;
use crate::mission::trajectory::{fly, Conditions, Trajectory, Wind};
use crate::model::profile::VehicleProfile;
use crate::model::PowerModel;
use crate::offline::plan_eval::publish;

/// Arguments of `dronewatt plan`.
#[derive(Debug, Clone, clap::Args)]
pub struct PlanArgs {
    /// The plan: a QGroundControl `.plan` or a `QGC WPL 110` `.waypoints` file.
    pub file: PathBuf,
    /// Vehicle profile (`config/vehicles/*.toml`). Default: the config's, else the M100.
    #[arg(long, value_name = "PROFILE")]
    pub vehicle: Option<PathBuf>,
    /// Wind, SPEED@FROM_DEG (m/s, bearing it blows from), e.g. 5@270. Default: calm.
    #[arg(long, value_name = "SPEED@FROM_DEG")]
    pub wind: Option<Wind>,
    /// Payload, g. Default: the config's `[mission] payload_g`, else 0.
    #[arg(long, value_name = "G")]
    pub payload_g: Option<f64>,
    /// Cruise speed until the plan changes it, m/s. Default: the plan's, else 10.
    #[arg(long, value_name = "M_S")]
    pub speed: Option<f64>,
    /// Configuration file (battery `[energy]`, `[forecast]`, models). Default: built-in defaults.
    #[arg(long, short = 'c', value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Calibrated vehicle profile for the `<model>_cal` physics models (the default forecast
    /// model is one). Skipped with a warning when missing.
    #[arg(long, value_name = "FILE", default_value = "config/vehicles/m100-calibrated.toml")]
    pub calibrated: PathBuf,
    /// Write the forecast as JSON to PATH, or to standard output with '-' (then no table).
    #[arg(long, value_name = "PATH|-")]
    pub json: Option<String>,
    /// Write a PNG of cumulative energy along the route (P50, P90 band, reserve line).
    #[arg(long, value_name = "PNG")]
    pub plot: Option<PathBuf>,
}

pub(crate) fn load_config(path: Option<&Path>) -> anyhow::Result<Config> {
    Ok(match path {
        Some(p) => Config::load(p)?,
        None => Config::default(),
    })
}

pub(crate) fn models_for(cfg: &Config, calibrated: &Path) -> anyhow::Result<Vec<Box<dyn PowerModel>>> {
    let cal = if calibrated.exists() {
        Some(VehicleProfile::load(calibrated)?)
    } else {
        tracing::warn!("{}: no calibrated profile; only the published physics parameters run", calibrated.display());
        None
    };
    crate::offline::eval::eval_models(cfg, cal.as_ref())
}

/// What `plan --json` writes.
#[derive(Debug, serde::Serialize)]
struct PlanReport<'a> {
    plan: &'a str,
    items: usize,
    not_modelled: Vec<String>,
    terrain_frame_items: Vec<usize>,
    speed_m_s: f64,
    payload_g: f64,
    wind: Wind,
    capacity_wh: f64,
    reserve_pct: f64,
    margin_p50_wh: f64,
    margin_p90_wh: f64,
    forecast: &'a MissionForecast,
}

/// `dronewatt plan FILE`.
pub fn run_plan(a: PlanArgs) -> anyhow::Result<()> {
    let mut cfg = load_config(a.config.as_deref())?;
    if let Some(v) = &a.vehicle {
        cfg.vehicle = Some(v.clone());
    }
    let plan = Plan::load(&a.file)?;
    let payload_g = a.payload_g.or(cfg.mission.payload_g.map(f64::from)).unwrap_or(0.0);
    if !(payload_g.is_finite() && payload_g >= 0.0) {
        anyhow::bail!("--payload-g {payload_g}: must be ≥ 0");
    }
    if let Some(s) = a.speed {
        if !(s.is_finite() && s > 0.0) {
            anyhow::bail!("--speed {s}: must be > 0 m/s");
        }
    }
    let cond = Conditions { wind: a.wind.unwrap_or_default(), payload_g, speed_m_s: a.speed, rate_hz: cfg.telemetry.rate_hz };
    let tr = fly(&plan, &cfg.forecast.kinematics, &cond);
    if tr.samples.is_empty() {
        anyhow::bail!("{}: the plan flies nowhere (no take-off, no waypoint)", a.file.display());
    }
    let mut models = models_for(&cfg, &a.calibrated)?;
    let f = forecast(&tr, &mut models, &cfg.forecast.calibration, cfg.telemetry.window, crate::mission::MODEL_STRIDE);
    let wanted = cfg.forecast.calibration.name();
    if f.model != wanted {
        tracing::warn!("forecast models {wanted:?} did not all run; the P50 follows {:?}", f.model);
    }
    // Offline no vehicle answers: the configured capacity, else the default (said in the log).
    let battery = crate::vehicle::battery_from_config(&cfg.energy.battery());
    let capacity_wh = battery.capacity_wh.value;
    if battery.capacity_wh.source != crate::vehicle::Provenance::Config {
        tracing::info!("capacity {capacity_wh:.2} Wh ({}): set [energy] capacity_wh for your own pack", battery.capacity_wh.source);
    }
    let (m50, m90) = f.margins_wh(capacity_wh, cfg.energy.reserve_pct);
    let speed_m_s = a.speed.or(plan.hover_speed_m_s).unwrap_or(cfg.forecast.kinematics.default_speed_m_s);
    let report = PlanReport {
        plan: &plan.source,
        items: plan.items.len(),
        not_modelled: plan.not_modelled().iter().map(|i| format!("item {} ({}): MAV_CMD {}", i.index, i.origin, i.command)).collect(),
        terrain_frame_items: plan.terrain_items().iter().map(|i| i.index).collect(),
        speed_m_s,
        payload_g,
        wind: cond.wind,
        capacity_wh,
        reserve_pct: cfg.energy.reserve_pct,
        margin_p50_wh: m50,
        margin_p90_wh: m90,
        forecast: &f,
    };
    if let Some(png) = &a.plot {
        plot_plan(png, &plan.source, &tr, &f, capacity_wh, cfg.energy.reserve_pct)?;
    }
    publish(a.json.as_deref(), &report, || plan_table(&report))
}

fn plan_table(r: &PlanReport) -> String {
    use std::fmt::Write;
    let f = r.forecast;
    let mut s = String::new();
    let _ = writeln!(s, "{}: {} items, {:.1} m/s, payload {:.0} g, wind {:.1} m/s from {:.0}°", r.plan, r.items, r.speed_m_s, r.payload_g, r.wind.speed_m_s, r.wind.from_deg);
    let _ = writeln!(s, "P50: {} (P90 = {:.3} × P50)", if f.model.contains(" + ") { format!("the mean of {}", f.model) } else { f.model.clone() }, f.p90_ratio);
    let _ = writeln!(s, "{:>4} {:<18} {:>8} {:>8} {:>9} {:>9}", "item", "leg", "time s", "dist m", "P50 Wh", "P90 Wh");
    for l in &f.legs {
        let _ = writeln!(s, "{:>4} {:<18} {:>8.1} {:>8.0} {:>9.2} {:>9.2}", l.item, l.label, l.duration_s, l.distance_m, l.energy_p50_wh, l.energy_p90_wh);
    }
    let _ = writeln!(s, "{:>4} {:<18} {:>8.1} {:>8.0} {:>9.2} {:>9.2}", "", "total", f.duration_s, f.distance_m, f.energy_p50_wh, f.energy_p90_wh);
    let _ = writeln!(
        s,
        "battery {:.1} Wh, reserve {:.0} %: margin over reserve {:.1} Wh at P50, {:.1} Wh at P90{}",
        r.capacity_wh,
        r.reserve_pct,
        r.margin_p50_wh,
        r.margin_p90_wh,
        if r.margin_p90_wh < 0.0 { "  — the mission may not finish above reserve" } else { "" }
    );
    for n in &r.not_modelled {
        let _ = writeln!(s, "not modelled: {n}");
    }
    if !r.terrain_frame_items.is_empty() {
        let _ = writeln!(s, "terrain-relative altitudes flown as above home (flat terrain): items {:?}", r.terrain_frame_items);
    }
    let _ = writeln!(s, "models (uncorrected, whole plan): {}", f.models_raw_wh.iter().map(|(n, e)| format!("{n} {e:.1}")).collect::<Vec<_>>().join(", "));
    s
}

/// Cumulative energy along the route: P50 line, P50–P90 band, the usable-energy line
/// (capacity − reserve), leg boundaries.
fn plot_plan(path: &Path, title: &str, tr: &Trajectory, f: &MissionForecast, capacity_wh: f64, reserve_pct: f64) -> anyhow::Result<()> {
    use plotters::prelude::*;
    crate::offline::plot::register_font();
    let t: Vec<f64> = (0..f.cum_p50_wh.len()).map(|i| (i + 1) as f64 * f.dt_s).collect();
    let usable = capacity_wh * (1.0 - reserve_pct / 100.0);
    let ymax = (f.energy_p90_wh.max(usable) * 1.08).max(1.0);
    let xmax = t.last().copied().unwrap_or(1.0).max(1.0);
    let root = BitMapBackend::new(path, (1200, 700)).into_drawing_area();
    let draw = || -> Result<(), Box<dyn std::error::Error>> {
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(format!("{title}: cumulative energy along the plan"), ("sans-serif", 24))
            .margin(14)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..xmax, 0.0..ymax)?;
        chart.configure_mesh().x_desc("time from the motors' start (s)").y_desc("energy (Wh)").label_style(("sans-serif", 16)).axis_desc_style(("sans-serif", 18)).draw()?;
        let band: Vec<(f64, f64)> = t.iter().zip(&f.cum_p50_wh).map(|(&x, &e)| (x, e * f.p90_ratio)).chain(t.iter().zip(&f.cum_p50_wh).rev().map(|(&x, &e)| (x, e))).collect();
        chart.draw_series(std::iter::once(Polygon::new(band, BLUE.mix(0.2))))?.label("P50–P90").legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], BLUE.mix(0.2).filled()));
        chart.draw_series(LineSeries::new(t.iter().zip(&f.cum_p50_wh).map(|(&x, &e)| (x, e)), BLUE.stroke_width(2)))?.label("P50").legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE.stroke_width(3)));
        chart.draw_series(LineSeries::new([(0.0, usable), (xmax, usable)], RED.stroke_width(2)))?.label(format!("capacity − {reserve_pct:.0} % reserve")).legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(3)));
        for l in &tr.legs {
            chart.draw_series(LineSeries::new([(l.t_end_s, 0.0), (l.t_end_s, ymax * 0.03)], BLACK))?;
        }
        chart.configure_series_labels().position(SeriesLabelPosition::UpperLeft).background_style(WHITE.mix(0.85)).border_style(BLACK).label_font(("sans-serif", 16)).draw()?;
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| anyhow::anyhow!("{e}")).with_context(|| format!("{}: cannot write plot", path.display()))
}
