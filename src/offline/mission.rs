//! The mission commands: `dronewatt plan FILE` (pre-flight forecast of a plan) and
//! `dronewatt plan-eval` (the forecast judged on the data set's route flights).
//!
//! ## `plan-eval`: how each flight's plan is built, as a planner would have had it
//!
//! The M100 flights fly fixed delivery routes: take off at home, fly to the route's
//! waypoints, return, land. For each route flight:
//! - **home** is the flight's own first GPS fix (where it stood before take-off);
//! - **waypoints** (geometry only) come from the nearest-numbered *training* flight of the
//!   same route (test flights excluded, and never the flight itself); routes with no
//!   other training flight (R2, R3, R4, and the test-only R6 and R7) use the flight's own
//!   track: the part above 50 % of the first/last commanded altitude (GPS altitude drifts: flight 275 cruises at 18 m by it, commanded 25), reduced to its
//!   corners by Ramer–Douglas–Peucker on the horizontal track (tolerance `RDP_TOL_M`),
//!   corners within `HOME_RADIUS_M` of home dropped (take-off and landing are there).
//!   Nothing of the track's timing, speed profile or power is used;
//! - **altitudes** are the flight's commanded ones (`parameters.csv`): one altitude, or
//!   for multi-stage routes (R7, `25-50-100-25`) each corner gets the stage nearest to the
//!   track's height there, and a last waypoint over home at the last stage before landing;
//! - **speed** and **payload** are the commanded ones; **wind** is the anemometer's mean
//!   over the rows before take-off (the ground wind a planner would look up), unless
//!   `--no-ground-wind`.
//!
//! ## Scores
//!
//! - **pre-flight**: the plan's P50 against the measured ∫V·I of the whole recording;
//!   the P90 covers a flight when measured ≤ P90;
//! - **live at 50 %**: at the middle of the airborne time (first to last row above
//!   `AIRBORNE_W`), the flight's own first half is replayed (position tracked along the
//!   plan with [`Trajectory::locate`], the measured energy so far known) and the rest of
//!   the plan forecast from there; scored against the measured energy of the rest;
//! - **baseline** (what autopilots do): mean power since the motors started × the time
//!   left, scored the same way, with two clocks: the ground station's (QGroundControl's
//!   mission time, [`gcs_left_s`], the only one a pilot has today) and dronewatt's own (the
//!   plan's time left as flown on paper, which isolates the power model).
//!
//! The forecast's correction (its members — the vehicle's own models that tie for the best
//! fit, each with its weighting: one weight on the model's power plus one on the climbing
//! work m·g·v_z ([`BASES`]), and its scale — the P90 ratio, the live weight) is fitted on the
//! training flights only (route flights not in [`TEST_FLIGHTS`]) by rolling validation and
//! then applied to the test flights; `--json` writes everything, the fit and the training
//! flights' own scores included.

use std::path::{Path, PathBuf};

use anyhow::Context;

use crate::config::Config;
use crate::mission::forecast::{forecast, Calibration, Member, MissionForecast};
use crate::mission::plan::{GeoPoint, Plan};
use crate::mission::trajectory::{enu_of, fly, Conditions, Trajectory, Wind};
use crate::model::profile::VehicleProfile;
use crate::model::PowerModel;
use crate::offline::data::TEST_FLIGHTS;
use crate::source::dataset::{self, Flight};

/// Corner tolerance of the track reduction, m.
pub const RDP_TOL_M: f64 = 10.0;
/// Corners this close to home (horizontally) are take-off/landing, not waypoints, m.
pub const HOME_RADIUS_M: f64 = 15.0;
/// Electrical power above which the vehicle counts as flying (motors spun up), W.
pub const AIRBORNE_W: f64 = 150.0;

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

/// Arguments of `dronewatt plan-eval`.
#[derive(Debug, Clone, clap::Args)]
pub struct PlanEvalArgs {
    /// The data set (`flights.csv` or `.csv.gz`). Default: `DRONEWATT_DATA` or `../shared/data/m100/flights.csv.gz`.
    #[arg(long, value_name = "FILE")]
    pub data: Option<PathBuf>,
    /// Score these test flights only (comma separated). Default: every test flight present.
    #[arg(long, value_delimiter = ',')]
    pub flights: Option<Vec<u32>>,
    /// Fit on these training flights only (comma separated). Default: every route flight not in the test set.
    #[arg(long, value_delimiter = ',')]
    pub train: Option<Vec<u32>>,
    /// Plan every flight in calm air instead of the anemometer's pre-take-off wind.
    #[arg(long)]
    pub no_ground_wind: bool,
    /// Configuration file (models, `[forecast.kinematics]`). Default: built-in defaults.
    #[arg(long, short = 'c', value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Calibrated vehicle profile for the `<model>_cal` physics models.
    #[arg(long, value_name = "FILE", default_value = "config/vehicles/m100-calibrated.toml")]
    pub calibrated: PathBuf,
    /// Print one JSON object to PATH, or to standard output with '-' (then no table).
    #[arg(long, value_name = "PATH|-")]
    pub json: Option<String>,
}

fn load_config(path: Option<&Path>) -> anyhow::Result<Config> {
    Ok(match path {
        Some(p) => Config::load(p)?,
        None => Config::default(),
    })
}

fn models_for(cfg: &Config, calibrated: &Path) -> anyhow::Result<Vec<Box<dyn PowerModel>>> {
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

// ---------------------------------------------------------------- plan-eval

/// Ramer–Douglas–Peucker: indices of the corners of a polyline kept within `tol` (m).
pub fn rdp(points: &[(f64, f64)], tol: f64) -> Vec<usize> {
    fn rec(p: &[(f64, f64)], a: usize, b: usize, tol: f64, keep: &mut Vec<usize>) {
        let (ax, ay) = p[a];
        let (bx, by) = p[b];
        let (dx, dy) = (bx - ax, by - ay);
        let len = dx.hypot(dy);
        let mut worst = (0.0, a);
        for (i, &(x, y)) in p.iter().enumerate().take(b).skip(a + 1) {
            let d = if len > 1e-9 { ((x - ax) * dy - (y - ay) * dx).abs() / len } else { (x - ax).hypot(y - ay) };
            if d > worst.0 {
                worst = (d, i);
            }
        }
        if worst.0 > tol {
            rec(p, a, worst.1, tol, keep);
            keep.push(worst.1);
            rec(p, worst.1, b, tol, keep);
        }
    }
    if points.len() < 2 {
        return (0..points.len()).collect();
    }
    let mut keep = vec![0];
    rec(points, 0, points.len() - 1, tol, &mut keep);
    keep.push(points.len() - 1);
    keep
}

fn stages(f: &Flight) -> Vec<f64> {
    let s: Vec<f64> = f.altitude_text.split('-').filter_map(|x| x.trim().parse::<f64>().ok()).filter(|v| v.is_finite() && *v > 0.0).collect();
    if s.is_empty() {
        vec![f.altitude_m]
    } else {
        s
    }
}

fn home_of(f: &Flight) -> Option<GeoPoint> {
    let r = f.rows.iter().find(|r| r.lat_deg != 0.0 || r.lon_deg != 0.0)?;
    Some(GeoPoint { lat_deg: r.lat_deg, lon_deg: r.lon_deg, alt_m: r.alt_m })
}

/// The route's waypoints (lat, lon, and the height above home there, m) from a flight's
/// track: the part above 50 % of the first/last stage, reduced to its corners.
fn route_corners(f: &Flight) -> Option<Vec<(f64, f64, f64)>> {
    let home = home_of(f)?;
    let st = stages(f);
    let (first, last) = (st[0], st[st.len() - 1]);
    let h = |r: &dataset::Row| r.alt_m - home.alt_m;
    let a = f.rows.iter().position(|r| h(r) > 0.5 * first)?;
    let b = f.rows.iter().rposition(|r| h(r) > 0.5 * last)?;
    if b <= a {
        return None;
    }
    let pts: Vec<(f64, f64)> = f.rows[a..=b].iter().map(|r| enu_of(&home, r.lat_deg, r.lon_deg)).collect();
    let keep = rdp(&pts, RDP_TOL_M);
    Some(
        keep.into_iter()
            .filter(|&i| pts[i].0.hypot(pts[i].1) > HOME_RADIUS_M)
            .map(|i| {
                let r = &f.rows[a + i];
                (r.lat_deg, r.lon_deg, h(r))
            })
            .collect(),
    )
}

/// The plan a planner would have had for flight `f`, with waypoints from `geometry`'s
/// track (another training flight of the route, or `f` itself).
pub fn flight_plan(f: &Flight, geometry: &Flight) -> anyhow::Result<Plan> {
    let home = home_of(f).with_context(|| format!("flight {}: no GPS fix", f.flight))?;
    let corners = route_corners(geometry).with_context(|| format!("flight {}: no cruise part to take waypoints from", geometry.flight))?;
    let st = stages(f);
    let nearest = |h: f64| st.iter().copied().fold(st[0], |b, s| if (s - h).abs() < (b - h).abs() { s } else { b });
    let single = st.len() == 1;
    let mut wps: Vec<GeoPoint> = corners.iter().map(|&(lat, lon, h)| GeoPoint { lat_deg: lat, lon_deg: lon, alt_m: if single { st[0] } else { nearest(h) } }).collect();
    let last = st[st.len() - 1];
    if wps.last().is_some_and(|w| (w.alt_m - last).abs() > 0.5) {
        wps.push(GeoPoint { alt_m: last, ..home });
    }
    let mut plan = Plan::from_waypoints(&format!("flight {} ({}, waypoints from flight {})", f.flight, f.route, geometry.flight), home, &wps, f.speed_m_s);
    // take-off to the first stage (the first waypoint may be at a later stage)
    for it in plan.items.iter_mut() {
        if let crate::mission::plan::ItemKind::Takeoff { alt_m } = &mut it.kind {
            *alt_m = st[0];
        }
    }
    Ok(plan)
}

/// The flight whose track gives `f`'s waypoints: the nearest-numbered training flight of
/// the same route other than `f`, else `f` itself.
fn geometry_for<'a>(f: &'a Flight, all_train: &[&'a Flight]) -> &'a Flight {
    all_train.iter().filter(|g| g.route == f.route && g.flight != f.flight).min_by_key(|g| g.flight.abs_diff(f.flight)).copied().unwrap_or(f)
}

/// Mean anemometer reading before take-off, as the wind (the ground wind a planner looks up).
fn ground_wind(f: &Flight) -> Wind {
    let pre: Vec<&dataset::Row> = f.rows.iter().take_while(|r| r.voltage_v * r.current_a < AIRBORNE_W).collect();
    if pre.is_empty() {
        return Wind::default();
    }
    // average as a vector (bearing the wind comes from)
    let (mut e, mut n) = (0.0, 0.0);
    for r in &pre {
        let b = r.wind_angle.to_radians();
        e += r.wind_speed * b.sin();
        n += r.wind_speed * b.cos();
    }
    let k = pre.len() as f64;
    let (e, n) = (e / k, n / k);
    Wind { speed_m_s: e.hypot(n).min(40.0), from_deg: e.atan2(n).to_degrees().rem_euclid(360.0) }
}

/// One flight's scores.
#[derive(Debug, Clone, serde::Serialize)]
pub struct FlightScore {
    pub flight: u32,
    pub route: String,
    pub speed_m_s: f64,
    pub payload_g: f64,
    pub altitude: String,
    /// Which flight's track gave the waypoints.
    pub geometry_from: u32,
    pub waypoints: usize,
    pub wind: Wind,
    /// Recording length and planned flight time, s.
    pub measured_s: f64,
    pub planned_s: f64,
    /// Airborne time (first to last row above `AIRBORNE_W`), s.
    pub airborne_s: f64,
    /// Live: where the vehicle was found on the plan at half time (planned time, s) and
    /// the half time itself (from the motors' start, s).
    pub live_plan_t_s: f64,
    /// The plan's legs as flown on paper: label, start and end (s from the motors' start), horizontal
    /// distance (m): where the plan's clock can be set beside the flight's.
    pub plan_legs: Vec<(String, f64, f64, f64)>,
    pub live_t_s: f64,
    /// Measured ∫V·I, Wh.
    pub measured_wh: f64,
    /// Every model's uncorrected forecast of the whole plan, Wh.
    pub models_raw_wh: Vec<(String, f64)>,
    pub p50_wh: f64,
    pub p90_wh: f64,
    /// |P50 − measured| / measured, %.
    pub preflight_err_pct: f64,
    /// measured ≤ P90.
    pub p90_covers: bool,
    /// Live at 50 %: measured energy of the rest, dronewatt's and the baseline's forecast, Wh.
    pub live_measured_rest_wh: f64,
    pub live_forecast_rest_wh: f64,
    /// Live at 50 %: measured energy so far (from the recording's start; from take-off)
    /// and the forecast of the part of the plan flown, Wh.
    pub live_measured_done_wh: f64,
    pub live_measured_airborne_done_wh: f64,
    pub live_forecast_done_wh: f64,
    pub live_err_pct: f64,
    pub baseline_rest_wh: f64,
    pub baseline_err_pct: f64,
    /// Live baseline with the ground station's clock: mean power so far × QGroundControl's
    /// mission time left ([`gcs_left_s`]), Wh, and its error, %.
    pub gcs_left_s: f64,
    pub baseline_gcs_rest_wh: f64,
    pub baseline_gcs_err_pct: f64,
    /// Pre-flight baseline: the training flights' median mean power × the planned time, Wh.
    pub baseline_preflight_wh: f64,
    pub baseline_preflight_err_pct: f64,
}

/// One model's uncorrected forecast of a flight's plan, split for fitting: energy by
/// phase ([`phase_of`]) up to the live point and after it, Wh.
struct ModelRaw {
    name: String,
    total_wh: f64,
    first_wh: Terms,
    rest_wh: Terms,
    planned_left_s: f64,
}

/// A forecast's energy split into what the calibration weighs ([`Calibration::weights`]):
/// the model's energy in vertical climb, vertical descent and the rest, and the vertical
/// work m·g·v_z up and down, Wh.
pub type Terms = [f64; 5];

/// Phase of a trajectory sample: 0 vertical climb, 1 vertical descent, 2 anything else.
pub use crate::mission::forecast::phase_of;

fn dot5(a: &Terms, b: &Terms) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Inputs of one flight kept for fitting.
struct Prepared {
    flight: u32,
    route: String,
    speed_m_s: f64,
    payload_g: f64,
    altitude: String,
    geometry_from: u32,
    waypoints: usize,
    wind: Wind,
    measured_s: f64,
    measured_wh: f64,
    traj: Trajectory,
    /// Per model, uncorrected.
    raw: Vec<ModelRaw>,
    /// Live: the trajectory sample reached at half time, energy measured so far, energy
    /// measured after, mean power since the motors started.
    live_k: usize,
    /// The ground station's mission time left from the live point ([`gcs_left_s`]), s.
    live_gcs_left_s: f64,
    live_so_far_wh: f64,
    /// Energy measured from take-off (first row above `AIRBORNE_W`) to the live point, Wh.
    live_airborne_so_far_wh: f64,
    live_rest_wh: f64,
    live_mean_w: f64,
    airborne_s: f64,
    live_t_s: f64,
    /// Mean power over the airborne time (first to last row above `AIRBORNE_W`), W.
    flight_mean_w: f64,
}

fn prepare(f: &Flight, geometry: &Flight, ground: bool, cfg: &Config, models: &mut [Box<dyn PowerModel>]) -> anyhow::Result<Prepared> {
    let plan = flight_plan(f, geometry)?;
    let wind = if ground { ground_wind(f) } else { Wind::default() };
    let cond = Conditions { wind, payload_g: f.payload_g, speed_m_s: Some(f.speed_m_s), rate_hz: cfg.telemetry.rate_hz };
    let traj = fly(&plan, &cfg.forecast.kinematics, &cond);
    let mut fcs = Vec::new();
    for m in models.iter_mut() {
        let cal = Calibration::uncorrected(m.name());
        fcs.push(forecast(&traj, std::slice::from_mut(m), &cal, cfg.telemetry.window, crate::mission::MODEL_STRIDE));
    }
    // measured energy, cumulative by row (rectangle rule to the next row)
    let rows = &f.rows;
    let mut cum = vec![0.0f64; rows.len()];
    for i in 1..rows.len() {
        let dt = (rows[i].time_s - rows[i - 1].time_s).max(0.0);
        cum[i] = cum[i - 1] + rows[i - 1].voltage_v * rows[i - 1].current_a * dt / 3600.0;
    }
    let measured_wh = cum.last().copied().unwrap_or(0.0);
    let on = |r: &dataset::Row| r.voltage_v * r.current_a > AIRBORNE_W;
    let i0 = rows.iter().position(on).with_context(|| format!("flight {}: never above {AIRBORNE_W} W", f.flight))?;
    let i1 = rows.iter().rposition(on).unwrap_or(i0);
    let t_half = 0.5 * (rows[i0].time_s + rows[i1].time_s);
    let ih = rows.iter().position(|r| r.time_s >= t_half).unwrap_or(i1);
    let home = plan.home;
    let mut k = 0usize;
    let horizon = (15.0 / traj.dt_s) as usize;
    for r in &rows[i0..=ih] {
        let (e, n) = enu_of(&home, r.lat_deg, r.lon_deg);
        k = traj.locate(k, horizon, [e as f32, n as f32, (r.alt_m - home.alt_m) as f32]);
    }
    let so_far = cum[ih];
    let vehicle_kg = VehicleProfile::m100().mass_kg(0.0);
    let raw = fcs
        .into_iter()
        .map(|fc| {
            let (mut first_wh, mut rest_wh) = ([0.0; 5], [0.0; 5]);
            let mut prev = 0.0;
            for (j, &c) in fc.cum_p50_wh.iter().enumerate() {
                let e = c - prev;
                prev = c;
                let ph = phase_of(&traj.samples[j]);
                let x = if j <= k { &mut first_wh } else { &mut rest_wh };
                x[ph] += e;
                let [up, down] = crate::mission::forecast::vertical_work_w(&traj.samples[j], vehicle_kg);
                x[3] += up * traj.dt_s / 3600.0;
                x[4] += down * traj.dt_s / 3600.0;
            }
            ModelRaw { name: fc.model.clone(), total_wh: fc.energy_p50_wh, first_wh, rest_wh, planned_left_s: fc.remaining_from(k, None, 0.0).time_s }
        })
        .collect();
    let gcs_left = gcs_left_s(&traj, k, f.speed_m_s, &cfg.forecast.kinematics);
    let span = rows[ih].time_s - rows[i0].time_s;
    let live_mean_w = if span > 0.0 { (cum[ih] - cum[i0]) * 3600.0 / span } else { 0.0 };
    let air_s = rows[i1].time_s - rows[i0].time_s;
    let flight_mean_w = if air_s > 0.0 { (cum[i1] - cum[i0]) * 3600.0 / air_s } else { 0.0 };
    Ok(Prepared {
        flight: f.flight,
        route: f.route.clone(),
        speed_m_s: f.speed_m_s,
        payload_g: f.payload_g,
        altitude: f.altitude_text.clone(),
        geometry_from: geometry.flight,
        waypoints: plan.items.len().saturating_sub(3),
        wind,
        measured_s: rows.last().map_or(0.0, |r| r.time_s),
        measured_wh,
        traj,
        raw,
        live_k: k,
        live_gcs_left_s: gcs_left,
        live_so_far_wh: so_far,
        live_airborne_so_far_wh: cum[ih] - cum[i0],
        live_rest_wh: measured_wh - so_far,
        live_mean_w,
        airborne_s: air_s,
        live_t_s: span,
        flight_mean_w,
    })
}

/// QGroundControl's mission time for what is left of `traj` from sample `k`, s: the rule of
/// its plan view (`MissionController`), which is the only mission clock a pilot has today:
/// horizontal distance at the plan's speed, the take-off's height at the ascent speed, the
/// final descent at the descent speed, holds (`loiter` legs) at their length; no
/// accelerations, stops or spin-up, and a leg's climb or descent costs no time. The ascent
/// and descent speeds are the vehicle's own (`climb_m_s`, `descent_m_s`), kinder to the
/// baseline than QGroundControl's offline defaults.
fn gcs_left_s(traj: &Trajectory, k: usize, speed_m_s: f64, kin: &crate::mission::trajectory::KinematicsConfig) -> f64 {
    let n = traj.enu_m.len();
    if k + 1 >= n {
        return 0.0;
    }
    let horizontal: f64 = traj.enu_m[k..].windows(2).map(|w| f64::from(w[1][0] - w[0][0]).hypot(f64::from(w[1][1] - w[0][1]))).sum();
    let z = |j: usize| f64::from(traj.enu_m[j.min(n - 1)][2]);
    let leg_at = traj.leg_of.get(k).map_or(0, |&l| l as usize);
    let mut t = horizontal / speed_m_s.max(0.1);
    for (i, l) in traj.legs.iter().enumerate().skip(leg_at) {
        let from = if i == leg_at { k } else { l.samples.start };
        let label = l.label.as_str();
        if label == "takeoff" {
            t += (z(l.samples.end.saturating_sub(1)) - z(from)).max(0.0) / kin.climb_m_s.max(0.1);
        } else if label == "rtl" || label.starts_with("land") {
            t += z(from).max(0.0) / kin.descent_m_s.max(0.1);
        } else if label == "loiter" {
            t += l.samples.end.saturating_sub(from) as f64 * traj.dt_s;
        }
    }
    t
}

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

fn quantile(v: &mut [f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let pos = q * (v.len() - 1) as f64;
    let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
    v[lo] + (v[hi] - v[lo]) * (pos - lo as f64)
}

/// Flight `p` forecast with `cal`, each member `i` with the scale `scales[i]` (the one
/// fitted before the flight) in place of its own.
fn score(p: &Prepared, cal: &Calibration, scales: &[f64], baseline_w: f64) -> FlightScore {
    let (mut done, mut left, mut n) = (0.0f64, 0.0f64, 0.0f64);
    let mut planned_left_s = 0.0;
    for (c, scale) in cal.members.iter().zip(scales) {
        let Some(m) = p.raw.iter().find(|m| m.name == c.model) else { continue };
        let ks = c.weights();
        done += scale * dot5(&ks, &m.first_wh);
        left += scale * dot5(&ks, &m.rest_wh);
        planned_left_s = m.planned_left_s;
        n += 1.0;
    }
    let (done, mut left) = (done / n.max(1.0), left / n.max(1.0));
    let p50 = done + left;
    let p90 = p50 * cal.p90_ratio;
    if done > 0.05 * p50 && p.live_so_far_wh > 0.0 {
        let s = (p.live_so_far_wh / done).clamp(0.8, 1.25);
        left *= 1.0 + cal.live_weight * (s - 1.0);
    }
    let baseline = p.live_mean_w * planned_left_s / 3600.0;
    let baseline_gcs = p.live_mean_w * p.live_gcs_left_s / 3600.0;
    let err = |f: f64, m: f64| 100.0 * (f - m).abs() / m.max(1e-9);
    let baseline_preflight_wh = baseline_w * p.traj.duration_s() / 3600.0;
    FlightScore {
        flight: p.flight,
        route: p.route.clone(),
        speed_m_s: p.speed_m_s,
        payload_g: p.payload_g,
        altitude: p.altitude.clone(),
        geometry_from: p.geometry_from,
        waypoints: p.waypoints,
        wind: p.wind,
        measured_s: p.measured_s,
        planned_s: p.traj.duration_s(),
        airborne_s: p.airborne_s,
        live_plan_t_s: p.live_k as f64 * p.traj.dt_s,
        plan_legs: p.traj.legs.iter().map(|l| (l.label.clone(), l.t_start_s, l.t_end_s, l.distance_m)).collect(),
        live_t_s: p.live_t_s,
        measured_wh: p.measured_wh,
        models_raw_wh: p.raw.iter().map(|m| (m.name.clone(), m.total_wh)).collect(),
        p50_wh: p50,
        p90_wh: p90,
        preflight_err_pct: err(p50, p.measured_wh),
        p90_covers: p.measured_wh <= p90,
        live_measured_rest_wh: p.live_rest_wh,
        live_forecast_rest_wh: left,
        live_measured_done_wh: p.live_so_far_wh,
        live_measured_airborne_done_wh: p.live_airborne_so_far_wh,
        live_forecast_done_wh: done,
        live_err_pct: err(left, p.live_rest_wh),
        baseline_rest_wh: baseline,
        baseline_err_pct: err(baseline, p.live_rest_wh),
        gcs_left_s: p.live_gcs_left_s,
        baseline_gcs_rest_wh: baseline_gcs,
        baseline_gcs_err_pct: err(baseline_gcs, p.live_rest_wh),
        baseline_preflight_wh,
        baseline_preflight_err_pct: err(baseline_preflight_wh, p.measured_wh),
    }
}

/// The correction for flight `flight`: median measured/forecast of model `mi` over the
/// `k` training flights numbered closest before it (flight numbers follow the calendar;
/// `k` = 0: all of them), never the flight itself; all other training flights when fewer
/// than 5 come before it. The vehicle, its battery and the season drift (the test flights
/// fly in autumn, most training flights in summer): the recent flights say more.
fn recent_scale(train: &[Prepared], mi: usize, ks: &Terms, flight: u32, k: usize) -> f64 {
    let mut before: Vec<&Prepared> = train.iter().filter(|p| p.flight < flight).collect();
    if before.len() < 5 {
        before = train.iter().filter(|p| p.flight != flight).collect();
    }
    before.sort_by_key(|p| std::cmp::Reverse(p.flight));
    let take = if k == 0 { before.len() } else { k.min(before.len()) };
    let mut r: Vec<f64> = before[..take].iter().map(|p| p.measured_wh / phased_wh(p, mi, ks).max(1e-9)).collect();
    median(&mut r)
}

/// Model `mi`'s forecast of flight `p` with phase weights `ks`, Wh.
fn phased_wh(p: &Prepared, mi: usize, ks: &Terms) -> f64 {
    let m = &p.raw[mi];
    dot5(ks, &m.first_wh) + dot5(ks, &m.rest_wh)
}

/// The ways the forecast's [`Terms`] may be weighted, each row one fitted weight shared
/// by the terms the row sums; `plan-eval` keeps the one with the smallest rolling-
/// validation error on the training flights. One way today:
/// - `vertical work`: one weight on the model's power everywhere plus one on the climbing
///   work m·g·v_z, defined for any climb, vertical or slanted.
///
/// A weight per phase (vertical climb, vertical descent, the rest) fits the training
/// flights as well or slightly better, but says nothing about a slanted climb: every
/// training route climbs only vertically, so the training flights cannot tell the two
/// apart on what matters for a new route (R7 climbs on slanted legs), and only the
/// climbing work carries over. The choice is made on that physics, not on the test flights.
pub const BASES: [(&str, &[Terms]); 1] = [("vertical work", &[[1.0, 1.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0, 0.0]])];

/// Weights for model `mi`: least squares over the training flights' two halves (energy
/// to the live point, energy after it), each relative to its measured energy, so the
/// forecast's split between climb, descent and the rest follows what the training
/// flights drew. Unweighted model power when the system is singular (a phase never flown).
fn phase_weights(train: &[Prepared], mi: usize, rows: &[Terms]) -> Terms {
    let kk = rows.len();
    let mut ata = nalgebra::DMatrix::<f64>::zeros(kk, kk);
    let mut atb = nalgebra::DVector::<f64>::zeros(kk);
    for p in train {
        let m = &p.raw[mi];
        for (x, y) in [(m.first_wh, p.live_so_far_wh), (m.rest_wh, p.live_rest_wh)] {
            if y <= 0.0 {
                continue;
            }
            let v = nalgebra::DVector::from_iterator(kk, rows.iter().map(|r| dot5(r, &x) / y));
            ata += &v * v.transpose();
            atb += v;
        }
    }
    let plain = [1.0, 1.0, 1.0, 0.0, 0.0];
    match ata.try_inverse() {
        Some(inv) => {
            let k = inv * atb;
            let mut w = [0.0; 5];
            for (r, kr) in rows.iter().zip(k.iter()) {
                for j in 0..5 {
                    w[j] += r[j] * kr;
                }
            }
            if w.iter().all(|v| v.is_finite()) && w[..3].iter().all(|v| *v > 0.0) {
                w
            } else {
                plain
            }
        }
        None => plain,
    }
}

/// Whether model `name` may carry the fitted correction: only the vehicle's own models
/// (`_cal`: they run only with its calibrated profile) when any ran, since a correction of a
/// published model would follow that model onto every other vehicle (with this vehicle's
/// mass in the climbing work); any model when none of its own ran.
fn may_carry(name: &str, all: &[String]) -> bool {
    name.ends_with("_cal") || !all.iter().any(|n| n.ends_with("_cal"))
}

/// How many recent training flights the correction may be fitted on (0 = all).
const RECENT_CHOICES: [usize; 5] = [5, 10, 20, 40, 0];

/// Model `mi`'s member fitted with weighting `rows`: the weights by least squares on the
/// halves ([`phase_weights`]), the window `k` of recent flights with the smallest median
/// rolling-validation error, and the scale from the latest `k` training flights (for plans
/// flown after them). Also the candidate it makes: its median and per-flight rolling errors.
fn fit_member(train: &[Prepared], mi: usize, rows: &[Terms]) -> Candidate {
    let ks = phase_weights(train, mi, rows);
    let mut best: (f64, usize, Vec<f64>) = (f64::INFINITY, 0, Vec::new());
    for &k in &RECENT_CHOICES {
        let e: Vec<f64> = train.iter().map(|p| 100.0 * (p.measured_wh / (phased_wh(p, mi, &ks) * recent_scale(train, mi, &ks, p.flight, k)).max(1e-9) - 1.0).abs()).collect();
        let m = median(&mut e.clone());
        if m < best.0 {
            best = (m, k, e);
        }
    }
    let (err, k, errors) = best;
    let latest = train.iter().map(|p| p.flight).max().unwrap_or(0) + 1;
    let name = train.first().map_or(String::new(), |p| p.raw[mi].name.clone());
    let member = Member { model: name, scale: recent_scale(train, mi, &ks, latest, k), recent_flights: k, phase_scale: [ks[0], ks[1], ks[2]], climb_work: [ks[3], ks[4]] };
    Candidate { err, member, errors }
}

/// Each member's scale for flight `flight`: fitted on the training flights before it.
fn rolling_scales(train: &[Prepared], cal: &Calibration, flight: u32) -> Vec<f64> {
    let index = |name: &str| train.first().and_then(|p| p.raw.iter().position(|m| m.name == name));
    cal.members.iter().map(|c| index(&c.model).map_or(c.scale, |mi| recent_scale(train, mi, &c.weights(), flight, c.recent_flights))).collect()
}

/// The P90 ratio and live weight for `members`, from the training flights forecast with
/// the members' rolling scales: the 90th percentile of measured over forecast, and the
/// live weight of 0, ¼, ½, ¾, 1 with the smallest median live error.
fn finish(train: &[Prepared], members: Vec<Member>) -> Calibration {
    let mut cal = Calibration { members, p90_ratio: 1.0, live_weight: 0.0, vehicle_kg: VehicleProfile::m100().mass_kg(0.0) };
    let scales: Vec<Vec<f64>> = train.iter().map(|p| rolling_scales(train, &cal, p.flight)).collect();
    let mut res: Vec<f64> = train.iter().zip(&scales).map(|(p, sc)| p.measured_wh / score(p, &cal, sc, 0.0).p50_wh.max(1e-9)).collect();
    cal.p90_ratio = quantile(&mut res, 0.9).max(1.0);
    let mut best_w = (f64::INFINITY, 0.0);
    for w in [0.0, 0.25, 0.5, 0.75, 1.0] {
        cal.live_weight = w;
        let mut e: Vec<f64> = train.iter().zip(&scales).map(|(p, sc)| score(p, &cal, sc, 0.0).live_err_pct).collect();
        let m = median(&mut e);
        if m < best_w.0 {
            best_w = (m, w);
        }
    }
    cal.live_weight = best_w.1;
    cal
}

/// Paired bootstrap resamples of the training flights in [`tie_share`].
const BOOTSTRAP: usize = 4000;
/// A model ties with the best when its median error is no larger than the best's in at
/// least this share of the resamples (a one-sided 5 % test cannot tell them apart).
const TIE_SHARE: f64 = 0.05;

/// How far errors `e` (per training flight, %) tie with the best's `best`: resample the
/// flights with replacement, both models on the same flights, and return the share of
/// resamples in which `e`'s median is no larger (a tie from [`TIE_SHARE`] up). Seeded: the
/// same flights give the same answer.
fn tie_share(e: &[f64], best: &[f64]) -> f64 {
    use rand::{Rng, SeedableRng};
    let n = e.len().min(best.len());
    if n == 0 {
        return 0.0;
    }
    let mut rng = rand::rngs::StdRng::seed_from_u64(0x64_77_61_74_74);
    let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
    let mut no_worse = 0usize;
    for _ in 0..BOOTSTRAP {
        for j in 0..n {
            let i = rng.random_range(0..n);
            (a[j], b[j]) = (e[i], best[i]);
        }
        if median(&mut a) <= median(&mut b) {
            no_worse += 1;
        }
    }
    no_worse as f64 / BOOTSTRAP as f64
}

/// Fit the correction on training flights only, by rolling validation: each training
/// flight is forecast with the correction fitted on the training flights before it
/// ([`recent_scale`]). Every model gets its member ([`fit_member`]); the best of the
/// vehicle's own (`_cal`) models, when any ran ([`may_carry`]), and every one of them that
/// ties with it ([`tie_share`]) are the members, ordered by error; then their P90 ratio and
/// live weight ([`finish`]).
///
/// Why a tie is kept rather than decided: nearly every training flight flies one route, so
/// a model's small lead there is noise (the leaders swapped under a change as small as one
/// kinematics default) and says nothing of a route none of them flew, where models of
/// different structure err differently; their mean hedges that.
fn fit(train: &[Prepared]) -> Fitted {
    let names: Vec<String> = train.first().map(|p| p.raw.iter().map(|m| m.name.clone()).collect()).unwrap_or_default();
    let mut per_model: Vec<(String, f64, f64)> = names.iter().map(|n| (n.clone(), 0.0, f64::INFINITY)).collect();
    let mut per_basis = Vec::new();
    // (best error, basis, its candidates)
    let mut best: (f64, usize, Vec<Candidate>) = (f64::INFINITY, 0, Vec::new());
    for (bi, (basis, rows)) in BASES.iter().enumerate() {
        let mut cands = Vec::new();
        for (mi, pm) in per_model.iter_mut().enumerate() {
            let c = fit_member(train, mi, rows);
            if c.err < pm.2 {
                (pm.1, pm.2) = (c.member.recent_flights as f64, c.err);
            }
            if may_carry(&names[mi], &names) {
                cands.push(c);
            }
        }
        cands.sort_by(|a, b| a.err.total_cmp(&b.err));
        let basis_best = cands.first().map_or(f64::INFINITY, |c| c.err);
        per_basis.push((basis.to_string(), basis_best));
        if basis_best < best.0 {
            best = (basis_best, bi, cands);
        }
    }
    let (_, bi, cands) = best;
    let lead = cands.first().map(|c| c.errors.clone()).unwrap_or_default();
    let ties: Vec<(String, f64)> = cands.iter().map(|c| (c.member.model.clone(), tie_share(&c.errors, &lead))).collect();
    let members: Vec<Member> = cands.into_iter().zip(&ties).filter(|(_, t)| t.1 >= TIE_SHARE).map(|(c, _)| c.member).collect();
    Fitted { cal: finish(train, members), basis: BASES[bi].0.to_string(), per_model, per_basis, ties }
}

/// A model's member and its median and per-flight rolling errors (%), a candidate of [`fit`].
struct Candidate {
    err: f64,
    member: Member,
    errors: Vec<f64>,
}

/// What [`fit`] found.
struct Fitted {
    cal: Calibration,
    /// The [`BASES`] entry kept.
    basis: String,
    /// Per model: its best number of recent flights, its median error (%).
    per_model: Vec<(String, f64, f64)>,
    /// Per basis: its best median error (%), any model.
    per_basis: Vec<(String, f64)>,
    /// Per candidate model of the basis kept: its [`tie_share`] with the best.
    ties: Vec<(String, f64)>,
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
    /// The live baseline with the ground station's clock ([`gcs_left_s`]): median error, %,
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
            let e: Vec<f64> = cal.members.iter().filter_map(|c| x.models_raw_wh.iter().find(|(n, _)| *n == c.model).map(|(_, e)| *e)).collect();
            (!e.is_empty()).then(|| 100.0 * (e.iter().sum::<f64>() / e.len() as f64 - x.measured_wh).abs() / x.measured_wh)
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
        p90_coverage_pct: 100.0 * s.iter().filter(|x| x.p90_covers).count() as f64 / s.len().max(1) as f64,
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
    /// How the forecast's power is weighted (a [`BASES`] name), and each way's median
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
}

/// One member of the fit forecasting alone ([`PlanEvalReport::members_alone`]).
#[derive(Debug, Clone, serde::Serialize)]
pub struct Alone {
    pub model: String,
    /// Its median error on the training flights (rolling validation), %.
    pub training_err_pct: f64,
    /// Share of the paired resamples of the training flights in which its median error is
    /// no larger than the best's ([`tie_share`]), %.
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
}

/// Run the evaluation (see the module docs).
pub fn plan_eval(data: &Path, cfg: &Config, models: &mut [Box<dyn PowerModel>], opt: &PlanEvalOptions) -> anyhow::Result<PlanEvalReport> {
    let ds = dataset::read_flights(data, None)?;
    let is_route = |f: &Flight| f.route.starts_with('R');
    let test_ids: Vec<u32> = match &opt.test {
        Some(t) => t.clone(),
        None => TEST_FLIGHTS.iter().copied().filter(|t| ds.flights.iter().any(|f| f.flight == *t)).collect(),
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
    let all_train: Vec<&Flight> = ds.flights.iter().filter(|f| is_route(f) && !TEST_FLIGHTS.contains(&f.flight)).collect();
    let bar = indicatif::ProgressBar::new((train.len() + test_ids.len()) as u64);
    bar.set_style(indicatif::ProgressStyle::with_template("forecasting flights {bar:30} {pos}/{len} [{elapsed}<{eta}]").unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()));
    let mut prepared_train = Vec::new();
    for f in &train {
        match prepare(f, geometry_for(f, &all_train), opt.ground_wind, cfg, models) {
            Ok(p) => prepared_train.push(p),
            Err(e) => tracing::warn!("training flight {} skipped: {e:#}", f.flight),
        }
        bar.inc(1);
    }
    let mut prepared_test = Vec::new();
    for t in &test_ids {
        let f = ds.flights.iter().find(|f| f.flight == *t).with_context(|| format!("flight {t} missing"))?;
        prepared_test.push(prepare(f, geometry_for(f, &all_train), opt.ground_wind, cfg, models)?);
        bar.inc(1);
    }
    bar.finish_and_clear();
    let Fitted { cal, basis, per_model: models_fit, per_basis: bases_fit, ties } = fit(&prepared_train);
    let mut mean_w: Vec<f64> = prepared_train.iter().map(|p| p.flight_mean_w).collect();
    let baseline_w = median(&mut mean_w);
    let scores = |cal: &Calibration, set: &[Prepared]| -> Vec<FlightScore> { set.iter().map(|p| score(p, cal, &rolling_scales(&prepared_train, cal, p.flight), baseline_w)).collect() };
    let train_scores = scores(&cal, &prepared_train);
    let test_scores = scores(&cal, &prepared_test);
    // each member alone: the member as the fit made it, with its own P90 ratio and live weight
    let members_alone = if cal.members.len() > 1 {
        cal.members
            .iter()
            .map(|c| {
                let one = finish(&prepared_train, vec![c.clone()]);
                let training_err_pct = models_fit.iter().find(|m| m.0 == c.model).map_or(f64::NAN, |m| m.2);
                let tie_share_pct = 100.0 * ties.iter().find(|t| t.0 == c.model).map_or(f64::NAN, |t| t.1);
                Alone { model: c.model.clone(), training_err_pct, tie_share_pct, test: summarize(&scores(&one, &prepared_test), &one) }
            })
            .collect()
    } else {
        Vec::new()
    };
    Ok(PlanEvalReport {
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
        let err = r.models_fit.iter().find(|x| x.0 == m.model).map_or(f64::NAN, |x| x.2);
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

/// `dronewatt plan-eval`.
pub fn run_plan_eval(a: PlanEvalArgs) -> anyhow::Result<()> {
    let cfg = load_config(a.config.as_deref())?;
    let data = a.data.clone().unwrap_or_else(crate::default_data_path);
    let mut models = models_for(&cfg, &a.calibrated)?;
    let opt = PlanEvalOptions { test: a.flights.clone(), train: a.train.clone(), ground_wind: !a.no_ground_wind };
    let r = plan_eval(&data, &cfg, &mut models, &opt)?;
    publish(a.json.as_deref(), &r, || eval_table(&r))
}

/// `--json -`: the JSON on standard output instead of the table; `--json PATH`: the table,
/// and the JSON written to PATH; no `--json`: the table alone.
fn publish(json: Option<&str>, report: &impl serde::Serialize, table: impl FnOnce() -> String) -> anyhow::Result<()> {
    match json {
        Some("-") => println!("{}", serde_json::to_string_pretty(report)?),
        other => {
            print!("{}", table());
            if let Some(p) = other {
                std::fs::write(p, serde_json::to_string_pretty(report)?).with_context(|| format!("{p}: cannot write"))?;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rdp_keeps_the_corners_of_a_noisy_square() {
        let mut pts = Vec::new();
        for i in 0..=100 {
            pts.push((i as f64, 0.3 * ((i * 7) % 3) as f64));
        }
        for i in 1..=100 {
            pts.push((100.0 + 0.3 * ((i * 5) % 3) as f64, i as f64));
        }
        let keep = rdp(&pts, 2.0);
        assert_eq!(keep, vec![0, 100, 200]);
    }
}
