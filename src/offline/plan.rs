//! `dronewatt plan FILE`: the pre-flight forecast of a plan (table, `--json`, plot).

use std::path::{Path, PathBuf};

use anyhow::Context;

use crate::config::Config;
use crate::features::VehicleClass;
use crate::mission::forecast::MissionForecast;
use crate::mission::plan::Plan;
use crate::mission::trajectory::{fly_as, Conditions, Trajectory, Wind};
use crate::model::profile::VehicleProfile;
use crate::model::PowerModel;
use crate::offline::args::{help, ForecastArgs};

/// Arguments of `dronewatt plan`.
#[derive(Debug, Clone, clap::Args)]
#[command(mut_arg(
    "config",
    help(
        "Configuration file (battery `[energy]`, `[forecast]`, models). Default: built-in \
         defaults"
    )
))]
#[command(mut_arg(
    "calibrated",
    help(
        "Calibrated vehicle profile for the `<model>_cal` physics models (the default forecast \
         model is one). Default: the M100's, compiled in"
    )
))]
#[command(mut_arg(
    "json",
    help("Write the forecast as JSON to PATH, or to standard output with '-' (then no table)")
))]
pub struct PlanArgs {
    /// The plan: a QGroundControl `.plan` or a `QGC WPL 110` `.waypoints` file.
    pub file: PathBuf,
    /// The vehicle: a built-in name (m100, x500, quad-3s), a profile file
    /// (`config/vehicles/*.toml`, or the `profile.toml` `learn` wrote), or a vehicle's key in
    /// the vehicle store as `dronewatt vehicles` lists it (its learned profile). Its own
    /// physics models and pack fly the plan. Default: the config's, else the M100.
    #[arg(long, value_name = "NAME|FILE|KEY")]
    pub vehicle: Option<String>,
    /// The vehicle store for `--vehicle KEY` (default as `monitor`'s: $DRONEWATT_HOME, else
    /// the XDG data directory).
    #[arg(long, value_name = "DIR")]
    pub data_dir: Option<PathBuf>,
    /// The pack's resting voltage before take-off, V (whole pack): the forecast then starts
    /// from its state of charge, and prints the landing and lowest loaded voltages and when
    /// the voltage would cross the low threshold (`BATT_LOW_VOLT`, else 3.5 V a cell).
    #[arg(long, value_name = "V")]
    pub battery_v: Option<f64>,
    /// Wind, SPEED@FROM_DEG (m/s, bearing it blows from), e.g. 5@270. Default: calm.
    #[arg(long, value_name = "SPEED@FROM_DEG")]
    pub wind: Option<Wind>,
    /// Payload, g. Default: the config's `[mission] payload_g`, else 0.
    #[arg(long, value_name = "G")]
    pub payload_g: Option<f64>,
    /// Cruise speed until the plan changes it, m/s. Default: the plan's, else 10.
    #[arg(long, value_name = "M_S")]
    pub speed: Option<f64>,
    /// The vehicle's measured hover power, W: the mean of the pack's V × I over its first
    /// ~30 s of hover. It sets the hover efficiency of the momentum-theory forecast, whose
    /// P90 then keeps only the drag's spread (a multirotor only; refused for a plane). The
    /// hover is taken as flown with the plan's payload (`--payload-g`) unless
    /// `--hover-payload-g` says otherwise.
    #[arg(long, value_name = "W")]
    pub hover_w: Option<f64>,
    /// The payload on board when `--hover-w` was measured, g. Default: the plan's payload.
    #[arg(long, value_name = "G", requires = "hover_w")]
    pub hover_payload_g: Option<f64>,
    #[command(flatten)]
    pub forecast: ForecastArgs,
    /// Write a PNG of cumulative energy along the route (P50, P90 band, reserve line).
    #[arg(long, value_name = "PNG")]
    pub plot: Option<PathBuf>,
}

/// The models `plan` (and the lab's `plan-eval`, `battery-eval`) run for the M100: the
/// configured set, then the calibrated profile's `<model>_cal` models.
pub fn models_for(
    cfg: &Config,
    calibrated: &crate::offline::args::CalibratedArg,
) -> anyhow::Result<Vec<Box<dyn PowerModel>>> {
    let cal = calibrated.profile()?;
    crate::offline::chain::eval_models(cfg, Some(&cal))
}

/// What `plan --json` writes.
#[derive(Debug, serde::Serialize)]
struct PlanReport<'a> {
    plan: &'a str,
    /// The vehicle flown, and whose forecast calibration it is.
    vehicle: String,
    forecast_from: String,
    items: usize,
    not_modelled: Vec<String>,
    terrain_frame_items: Vec<usize>,
    speed_m_s: f64,
    payload_g: f64,
    wind: Wind,
    capacity_wh: f64,
    reserve_pct: f64,
    /// Energy the plan may use before the reserve, Wh: what the pack holds at the start (full,
    /// or from `--battery-v`) less the reserve; the plot's red line, so its margin is the text's.
    usable_wh: f64,
    margin_p50_wh: f64,
    margin_p90_wh: f64,
    /// The pack along the plan, when `--battery-v` gave its start state.
    #[serde(skip_serializing_if = "Option::is_none")]
    pack: Option<PackForecast>,
    forecast: &'a MissionForecast,
}

/// The loaded voltage along the plan at its P50 power, from a resting voltage.
#[derive(Debug, serde::Serialize)]
struct PackForecast {
    rest_v: f64,
    cells: u32,
    chemistry: String,
    /// State of charge at the start, % of the pack's OCV curve.
    soc_pct: f64,
    /// Energy to the curve's floor at the start, Wh.
    start_wh: f64,
    /// The lowest loaded voltage, V, when (s from the motors' start) and on which leg: the
    /// P50 path's lowest point with the transients it lacks
    /// ([`crate::battery::forecast::SAG_PREFLIGHT`]).
    v_min_v: f64,
    v_min_at_s: f64,
    v_min_leg: Option<String>,
    /// The loaded voltage at the end of the plan, V.
    landing_v: f64,
    /// The low threshold, V, where it comes from, and when the voltage first crosses it.
    low_v: f64,
    low_source: String,
    low_crossed_at_s: Option<f64>,
    /// More power asked than the pack can give somewhere (the voltage collapses).
    power_limited: bool,
}

/// The vehicle `--vehicle` names: a built-in, a file, or a key in the vehicle store.
fn resolve_vehicle(
    name: &str,
    data_dir: Option<&Path>,
) -> anyhow::Result<(VehicleProfile, Option<PathBuf>)> {
    if crate::model::profile::BUILT_IN
        .iter()
        .any(|(n, _)| *n == name)
    {
        return Ok((VehicleProfile::named_or_file(name)?, None));
    }
    let path = Path::new(name);
    if path.exists() {
        return Ok((VehicleProfile::load(path)?, Some(path.to_path_buf())));
    }
    if let Some(dir) = crate::vehicle::store::data_dir_from_env(data_dir) {
        if dir.join(crate::vehicle::store::DB_FILE).exists() {
            let store = crate::vehicle::store::Store::open(&dir)?;
            if let Some(p) = store.learned_profile(name)? {
                return Ok((VehicleProfile::load(&p.path)?, Some(p.path)));
            }
            if store.vehicles()?.iter().any(|v| v.key == name) {
                anyhow::bail!("vehicle '{name}': in the store ({}), but no profile was learned for it yet: run `dronewatt learn` on its logs", dir.display());
            }
        }
    }
    let names: Vec<&str> = crate::model::profile::BUILT_IN
        .iter()
        .map(|b| b.0)
        .collect();
    anyhow::bail!("vehicle '{name}': neither a built-in profile ({}), nor a file, nor a vehicle in the store (`dronewatt vehicles` lists them)", names.join(", "))
}

/// `dronewatt plan FILE`.
pub fn run_plan(a: PlanArgs) -> anyhow::Result<()> {
    let mut cfg = a.forecast.config.load()?;
    let (profile, profile_path, is_m100, payload_g) = plan_vehicle(&a, &mut cfg)?;
    let plan = Plan::load(&a.file)?;
    if let Some(s) = a.speed {
        if !(s.is_finite() && s > 0.0) {
            anyhow::bail!("--speed {s}: must be > 0 m/s");
        }
    }
    let cond = Conditions {
        wind: a.wind.unwrap_or_default(),
        payload_g,
        speed_m_s: a.speed,
        rate_hz: cfg.telemetry.rate_hz,
    };
    // A plane and a VTOL fly the plan as they do ([`crate::mission::trajectory::plane`]);
    // the M100, and a profile that names no class, as a multirotor.
    let class = if is_m100 {
        VehicleClass::Multirotor
    } else {
        profile.vehicle.class.unwrap_or_default()
    };
    let flight = profile.fixed_wing_flight.unwrap_or_default();
    // a vehicle whose forecast is momentum theory with its own drag flies at its own tilt
    let kinematics = if crate::energy::hover::follows_momentum_theory(&profile) {
        cfg.forecast.kinematics.tilted_as(&profile, payload_g)
    } else {
        cfg.forecast.kinematics.clone()
    };
    let tr = fly_as(class, &plan, &kinematics, &flight, &cond);
    if tr.samples.is_empty() {
        anyhow::bail!(
            "{}: the plan flies nowhere (no take-off, no waypoint)",
            a.file.display()
        );
    }
    let vehicle = PlanVehicle {
        profile: &profile,
        profile_path: profile_path.as_deref(),
        class,
        is_m100,
    };
    let (f, forecast_from) = plan_forecast(&a, &cfg, &vehicle, &tr)?;
    let (battery, capacity_wh) = plan_capacity(&cfg, &profile, is_m100)?;
    let pack = match a.battery_v {
        Some(v) => Some(pack_forecast(v, &battery, &f, &tr)?),
        None => None,
    };
    let (start_wh, reserve_wh) =
        start_and_reserve(pack.as_ref(), &battery, capacity_wh, cfg.energy.reserve_pct);
    let (m50, m90) = (
        start_wh - f.energy_p50_wh - reserve_wh,
        start_wh - f.energy_p90_wh - reserve_wh,
    );
    let speed_m_s = plan_speed(class, a.speed, &plan, &flight, &cfg);
    let report = PlanReport {
        plan: &plan.source,
        vehicle: profile.name.clone(),
        forecast_from,
        items: plan.items.len(),
        not_modelled: plan
            .not_modelled()
            .iter()
            .map(|i| format!("item {} ({}): MAV_CMD {}", i.index, i.origin, i.command))
            .collect(),
        terrain_frame_items: plan.terrain_items().iter().map(|i| i.index).collect(),
        speed_m_s,
        payload_g,
        wind: cond.wind,
        capacity_wh,
        reserve_pct: cfg.energy.reserve_pct,
        usable_wh: start_wh - reserve_wh,
        margin_p50_wh: m50,
        margin_p90_wh: m90,
        pack,
        forecast: &f,
    };
    if let Some(png) = &a.plot {
        plot_report(png, &report, &tr)?;
    }
    a.forecast.json.publish(&report, || plan_table(&report))
}

/// The speed the plan is flown at until it changes it, m/s: `--speed`, else the plan's,
/// else the vehicle's (a plane's cruise airspeed) or the configured default.
fn plan_speed(
    class: VehicleClass,
    speed: Option<f64>,
    plan: &Plan,
    flight: &crate::model::physics::fixed_wing::Flight,
    cfg: &Config,
) -> f64 {
    match class {
        // a plane's cruise airspeed
        VehicleClass::FixedWing | VehicleClass::Vtol => {
            speed.or(plan.cruise_speed_m_s).unwrap_or(flight.cruise_m_s)
        }
        _ => speed
            .or(plan.hover_speed_m_s)
            .unwrap_or(cfg.forecast.kinematics.default_speed_m_s),
    }
}

/// The pack the plan flies and its capacity, Wh (an error when it is not known); where the
/// capacity is not the config's, where it comes from is said.
fn plan_capacity(
    cfg: &Config,
    profile: &VehicleProfile,
    is_m100: bool,
) -> anyhow::Result<(crate::report::BatteryFacts, f64)> {
    let battery = plan_battery(cfg, profile, is_m100);
    let capacity_wh = battery.capacity().with_context(|| {
        format!("the pack's capacity is not known: set [energy] capacity_wh, or give the vehicle profile ({}) a [battery]", profile.name)
    })?;
    if battery
        .capacity_wh
        .as_ref()
        .is_some_and(|c| c.source != crate::report::Provenance::Config)
    {
        tracing::info!(
            "capacity {capacity_wh:.2} Wh ({}): set [energy] capacity_wh for your own pack",
            battery.capacity_source()
        );
    }
    Ok((battery, capacity_wh))
}

/// The energy the plan starts with and the reserve, Wh: with a start state (`pack`), the
/// margins are over what the pack holds now, the reserve a share of the full pack's.
fn start_and_reserve(
    pack: Option<&PackForecast>,
    battery: &crate::report::BatteryFacts,
    capacity_wh: f64,
    reserve_pct: f64,
) -> (f64, f64) {
    let (start_wh, reserve_of) = match pack {
        Some(p) => {
            let full =
                crate::energy::pack::pack_model(battery).map_or(capacity_wh, |(c, _)| c.capacity());
            (p.start_wh, full)
        }
        None => (capacity_wh, capacity_wh),
    };
    (start_wh, reserve_of * reserve_pct / 100.0)
}

/// The vehicle that flies the plan (the config's vehicle set to its file), whether it is
/// the M100, and the payload, g; a measured hover (`--hover-w`) calibrates its profile.
fn plan_vehicle(
    a: &PlanArgs,
    cfg: &mut Config,
) -> anyhow::Result<(VehicleProfile, Option<PathBuf>, bool, f64)> {
    let (profile, profile_path) = match &a.vehicle {
        Some(v) => resolve_vehicle(v, a.data_dir.as_deref())?,
        None => match &cfg.vehicle {
            Some(p) => (VehicleProfile::load(p)?, Some(p.clone())),
            None => (VehicleProfile::m100(), None),
        },
    };
    if let Some(p) = &profile_path {
        cfg.vehicle = Some(p.clone());
    }
    let is_m100 = a.hover_w.is_none() && profile.name == VehicleProfile::m100().name;
    let payload_g = a
        .payload_g
        .or(cfg.mission.payload_g.map(f64::from))
        .unwrap_or(0.0);
    if !(payload_g.is_finite() && payload_g >= 0.0) {
        anyhow::bail!("--payload-g {payload_g}: must be ≥ 0");
    }
    let profile = match a.hover_w {
        Some(w) => {
            let hover_g = a.hover_payload_g.unwrap_or(payload_g);
            if !(hover_g.is_finite() && hover_g >= 0.0) {
                anyhow::bail!("--hover-payload-g {hover_g}: must be ≥ 0");
            }
            crate::model::spec::calibrate_hover(profile, w, hover_g / 1000.0)
                .map_err(|e| anyhow::anyhow!("--hover-w {w}: {e}"))?
        }
        None => profile,
    };
    Ok((profile, profile_path, is_m100, payload_g))
}

/// The pack the plan flies: offline no vehicle answers, so the configured pack, else the
/// profile's, else the default; the M100's own pack only for the M100.
fn plan_battery(
    cfg: &Config,
    profile: &VehicleProfile,
    is_m100: bool,
) -> crate::report::BatteryFacts {
    let mut battery_cfg = cfg.energy.battery();
    if is_m100 {
        // The M100's own pack, only for the M100.
        let mut e = cfg.energy.clone();
        e.fill_pack(&crate::vehicle::BatteryConfig::m100());
        battery_cfg = e.battery();
    }
    if let (false, Some(b)) = (is_m100, profile.battery.as_ref()) {
        battery_cfg.cell_count = battery_cfg.cell_count.or(Some(b.cells));
        if battery_cfg.capacity_wh.is_none() {
            battery_cfg.capacity_wh = Some(
                b.capacity_mah / 1000.0
                    * f64::from(b.cells)
                    * battery_cfg
                        .chemistry
                        .unwrap_or(crate::battery::Chemistry::LiPo)
                        .nominal_v(),
            );
        }
    }
    let mut battery = crate::vehicle::battery_from_config(&battery_cfg);
    if let (Some(c), true) = (
        battery.capacity_wh.as_mut(),
        !is_m100 && cfg.energy.capacity_wh.is_none() && profile.battery.is_some(),
    ) {
        c.source =
            crate::report::Provenance::Parameter(format!("{} profile [battery]", profile.name));
    }
    battery
}

/// P90 ratio of a vehicle flown on its learned forecast model, which has no fitted spread.
const OWN_MODEL_P90: f64 = 1.15;
use crate::mission::forecast::UNCALIBRATED_P90;
/// The published physics models (the `_cal` ones are the M100's).
const PUBLISHED: [&str; 5] = [
    "dandrea",
    "dorling",
    "kirschstein",
    "stolaroff",
    "tseng_solo",
];

/// The pack flown along the plan at the forecast's P50 power, from a resting voltage.
fn pack_forecast(
    rest_v: f64,
    battery: &crate::report::BatteryFacts,
    f: &MissionForecast,
    tr: &Trajectory,
) -> anyhow::Result<PackForecast> {
    let cells = battery.cell_count.value;
    let per_cell = rest_v / f64::from(cells);
    let chem = crate::battery::Chemistry::from_name(&battery.chemistry.value)
        .unwrap_or(crate::battery::Chemistry::LiPo);
    if !(rest_v.is_finite() && per_cell >= chem.floor_v() - 0.3 && per_cell <= chem.full_v() + 0.1)
    {
        anyhow::bail!(
            "--battery-v {rest_v}: {per_cell:.2} V a cell is not a resting {} voltage for {cells} cells ({:.2}-{:.2} V a cell); set [energy] cell_count / chemistry for this pack",
            battery.chemistry.value,
            chem.floor_v(),
            chem.full_v()
        );
    }
    let (curve, params) =
        crate::energy::pack::pack_model(battery).context("no pack model for this battery")?;
    let est = crate::battery::Estimator::new(params, curve.clone(), rest_v, 0.0)
        .context("--battery-v: no pack state from this voltage")?;
    let mut prev = 0.0;
    let profile: Vec<(f64, f64)> = f
        .cum_p50_wh
        .iter()
        .map(|&e| {
            let p = (e - prev) * 3600.0 / f.dt_s;
            prev = e;
            (f.dt_s, p)
        })
        .collect();
    let (low_v, low_source) = match &battery.low_voltage_v {
        Some(l) => (l.value, l.source.to_string()),
        None => (
            crate::energy::pack::DEFAULT_LOW_V_CELL * f64::from(cells),
            format!("{} V a cell", crate::energy::pack::DEFAULT_LOW_V_CELL),
        ),
    };
    let fc = crate::battery::forecast(&est, &profile, &[low_v]);
    // the lowest measured voltage: the smooth path's sag deepened by the transients it lacks
    let (v_min_v, v_min_at_s) = crate::battery::forecast::lowest_dip(
        &est,
        profile.iter().copied(),
        crate::battery::forecast::SAG_PREFLIGHT,
    )
    .map_or((fc.v_min, fc.t_v_min), |(st, v)| (v, st.t_s));
    let v_min_leg = tr
        .legs
        .iter()
        .find(|l| l.t_end_s >= v_min_at_s)
        .map(|l| l.label.clone());
    Ok(PackForecast {
        rest_v,
        cells,
        chemistry: battery.chemistry.value.clone(),
        soc_pct: 100.0 * curve.soc(per_cell),
        start_wh: est.energy_wh(),
        v_min_v,
        v_min_at_s,
        v_min_leg,
        landing_v: fc.v_end,
        low_v,
        low_source,
        low_crossed_at_s: fc.crossings.first().copied().flatten(),
        power_limited: fc.power_limited,
    })
}

#[path = "plan_render.rs"]
mod render;
use render::{plan_table, plot_report};
#[path = "plan_models.rs"]
mod models;
use models::{plan_forecast, PlanVehicle};
