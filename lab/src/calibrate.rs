//! Calibration: fit the physics models' free parameters to training flights by
//! (bounded Levenberg–Marquardt) least squares with nalgebra, and write a calibrated
//! vehicle profile whose models are named `<model>_cal`.
//!
//! Only training flights are used: the test flights of Choudhry et al.
//! ([`TEST_FLIGHTS`]) are dropped before anything is fitted, and so are the ground tests
//! (routes A1–A3, flights 211–219: motors running on the ground, no lift to model). The
//! fit sees in-flight windows only ([`in_flight`](dronewatt::offline::metrics::in_flight)): the physics models describe flight,
//! and the ground segments would otherwise pull every constant toward 0 W. Windows come
//! from the ingest path with the configuration's `[telemetry]` and `[mission]`.
//!
//! What is free per model (the rest stays as published, because it is not identifiable
//! beside what is fitted — e.g. η and r enter D'Andrea only as their product):
//!
//! | model | free parameters |
//! |---|---|
//! | dandrea, dandrea_headwind | lift_drag (r), p_avio_w |
//! | dorling | eta, p_avio_w |
//! | stolaroff | eta, drag_area_m2, p_avio_w |
//! | kirschstein | kappa, kappa2, kappa3, drag_area_m2, p_avio_w |
//! | tseng | β₁…β₉ |
//! | tseng_solo | c₁…c₃ |

use std::path::PathBuf;

use anyhow::Context;

use dronewatt::model::profile::VehicleProfile;
use dronewatt::offline::args::{help, ConfigArg, DataArg};
use dronewatt::offline::data::{load_flights, TEST_FLIGHTS};
use dronewatt::offline::fit::fit;
use dronewatt::offline::metrics::IN_FLIGHT_W;

/// Arguments of `dronewatt-lab calibrate`.
#[derive(Debug, Clone, clap::Args)]
#[command(mut_arg(
    "config",
    help("Configuration file (`vehicle`, `[telemetry]`, `[mission]`). Default: built-in defaults")
))]
pub struct CalibrateArgs {
    #[command(flatten)]
    pub data: DataArg,
    /// Where to write the calibrated profile.
    #[arg(
        long,
        short = 'o',
        value_name = "FILE",
        default_value = "config/vehicles/m100-calibrated.toml"
    )]
    pub output: PathBuf,
    /// Profile to start from (airframe facts and published parameters). Default: the
    /// configuration's `vehicle`, else the built-in M100.
    #[arg(long, value_name = "FILE")]
    pub vehicle: Option<PathBuf>,
    #[command(flatten)]
    pub config: ConfigArg,
    /// Fit on these training flights only (comma-separated). Default: every training flight.
    #[arg(long, value_delimiter = ',', value_name = "N,N,…")]
    pub flights: Option<Vec<u32>>,
    /// Most in-flight windows to fit on (evenly thinned beyond that), to bound the time.
    #[arg(long, default_value_t = 40_000)]
    pub max_windows: usize,
}

/// Run `dronewatt-lab calibrate`.
pub fn run(args: CalibrateArgs) -> anyhow::Result<()> {
    let data = args.data.path();
    let cfg = args.config.load()?;
    let base = match args.vehicle.as_ref().or(cfg.vehicle.as_ref()) {
        Some(p) => VehicleProfile::load(p)?,
        None => VehicleProfile::m100(),
    };
    if let Some(f) = &args.flights {
        if let Some(t) = f.iter().find(|n| TEST_FLIGHTS.contains(n)) {
            anyhow::bail!("--flights: {t} is a test flight (Choudhry et al.); calibration never fits on test flights");
        }
    }
    let flights = load_flights(&data, args.flights.as_deref(), &cfg.telemetry, &cfg.mission)
        .with_context(|| format!("{}: cannot load flights for calibration", data.display()))?;
    let sha = dronewatt::offline::data::sha256_file(&data)?;
    let (cal, report) = fit(&flights, &base, sha, args.max_windows)?;
    let mut text = String::from("# Written by `dronewatt-lab calibrate`: the physics models' free parameters fitted by least squares\n");
    text.push_str(&format!("# on in-flight windows (measured > {IN_FLIGHT_W} W) of training flights only. Training RMSE, W (published → calibrated):\n"));
    for r in &report {
        text.push_str(&format!(
            "#   {:<18} {:>8.1} → {:>6.1}\n",
            r.model, r.rmse_before_w, r.rmse_after_w
        ));
    }
    text.push_str(&toml::to_string(&cal).context("cannot serialise the calibrated profile")?);
    if let Some(dir) = args.output.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create folder", dir.display()))?;
    }
    std::fs::write(&args.output, text)
        .with_context(|| format!("{}: cannot write", args.output.display()))?;
    println!(
        "{:<18} {:>14} {:>14}",
        "model", "RMSE pub (W)", "RMSE cal (W)"
    );
    for r in &report {
        println!(
            "{:<18} {:>14.1} {:>14.1}",
            r.model, r.rmse_before_w, r.rmse_after_w
        );
    }
    println!(
        "calibrated profile: {} ({} flights, {} windows)",
        args.output.display(),
        cal.calibration.as_ref().map_or(0, |c| c.flights.len()),
        cal.calibration.as_ref().map_or(0, |c| c.windows)
    );
    Ok(())
}
