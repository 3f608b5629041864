//! Sensitivity analysis of the trained LSTM (the paper's Table 3 and its diverging bar
//! chart).
//!
//! Method: the base windows are the in-flight windows ([`in_flight`]) of the chosen flights
//! (default: the test flights, never trained on), built by the ingest path from the
//! configuration's `[telemetry]` and `[mission]`. For one
//! mission input at a time (commanded altitude, payload, commanded speed) the input is set
//! to each of the paper's five steps (minimum, half step, middle, half step, maximum) in
//! every sample of every base window, all other inputs kept as flown, and the mean
//! predicted power over the base windows is recorded. The chart shows each step's change
//! against step 0 (the middle value), in watts. Only the mission inputs change: the flown
//! trajectory (position, velocity, attitude) stays, so this measures how much power the
//! network attributes to each mission parameter, as the paper's analysis does.

use std::path::PathBuf;

use anyhow::Context;

use dronewatt::features::idx;
use dronewatt::model::lstm::{resolve_model_path, LstmModel};
use dronewatt::offline::args::{help, ConfigArg, DataArg};
use dronewatt::offline::data::{list_flights, load_flights, TEST_FLIGHTS};
use dronewatt::offline::metrics::in_flight;
use dronewatt::offline::plot;
use dronewatt::telemetry::window::Window;

/// The paper's Table 3: input index, label, and the five steps (−1, −½, 0, +½, +1).
pub const STEPS: [(usize, &str, [f32; 5]); 3] = [
    (
        idx::ALTITUDE,
        "Altitude (m)",
        [25.0, 43.75, 62.5, 81.25, 100.0],
    ),
    (
        idx::PAYLOAD,
        "Payload (g)",
        [0.0, 187.5, 375.0, 562.5, 750.0],
    ),
    (idx::SPEED, "Speed (m/s)", [4.0, 6.0, 8.0, 10.0, 12.0]),
];

/// Arguments of `dronewatt-lab sensitivity`.
#[derive(Debug, Clone, clap::Args)]
#[command(mut_arg(
    "config",
    help(
        "Configuration file (`[telemetry]`, `[mission]`, `[models.lstm]`). Default: built-in \
         defaults"
    )
))]
pub struct SensitivityArgs {
    #[command(flatten)]
    pub data: DataArg,
    /// Model folder, card or weights file. Default: `[models.lstm] path` of the
    /// configuration, else the shipped model.
    #[arg(long, value_name = "PATH")]
    pub model: Option<PathBuf>,
    #[command(flatten)]
    pub config: ConfigArg,
    /// Base flights (comma-separated). Default: the test flights.
    #[arg(long, value_delimiter = ',')]
    pub flights: Option<Vec<u32>>,
    /// Folder for `sensitivity.csv` and `sensitivity.png`.
    #[arg(long, value_name = "DIR", default_value = "out/sensitivity")]
    pub out: PathBuf,
}

/// Mean predicted power (W) over `windows` with input `feature` set to `value` throughout.
fn mean_power(
    model: &mut LstmModel,
    windows: &[Window],
    feature: usize,
    value: f32,
) -> anyhow::Result<f64> {
    let (mut sum, mut n) = (0.0, 0usize);
    for chunk in windows.chunks(1024) {
        let mut c = chunk.to_vec();
        for w in &mut c {
            for s in &mut w.samples {
                s.features[feature] = value;
            }
        }
        for r in model.forward_w(&c)? {
            sum += r[0] as f64;
            n += 1;
        }
    }
    Ok(sum / n.max(1) as f64)
}

/// Run `dronewatt-lab sensitivity`.
pub fn run(args: SensitivityArgs) -> anyhow::Result<()> {
    let cfg = args.config.load()?;
    let model_path = resolve_model_path(args.model.as_deref().or(cfg.models.lstm.path.as_deref()))
        .context("no model found: pass --model")?;
    let mut model = LstmModel::load(&model_path, &cfg.telemetry)?;
    let data = args.data.path();
    let flights = match args.flights.clone() {
        Some(f) => f,
        None => {
            let held: Vec<u32> = list_flights(&data)?.iter().map(|f| f.flight).collect();
            TEST_FLIGHTS
                .into_iter()
                .filter(|t| held.contains(t))
                .collect()
        }
    };
    let loaded = load_flights(&data, Some(&flights), &cfg.telemetry, &cfg.mission)?;
    let windows: Vec<Window> = loaded
        .iter()
        .flat_map(|f| {
            f.windows
                .iter()
                .filter(|w| w.last().measured_w.is_some_and(|p| in_flight(p.into())))
                .cloned()
        })
        .collect();
    anyhow::ensure!(
        !windows.is_empty(),
        "{}: no windows with measured power in flights {flights:?}",
        data.display()
    );
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create", args.out.display()))?;

    let mut csv = String::from("feature,step,value,mean_power_w,change_w\n");
    println!("| | Step −1 | Step −½ | Step 0 | Step +½ | Step +1 |\n|---|---|---|---|---|---|");
    let mut bars = Vec::new();
    for (feature, label, steps) in STEPS {
        let powers: Vec<f64> = steps
            .iter()
            .map(|v| mean_power(&mut model, &windows, feature, *v))
            .collect::<anyhow::Result<_>>()?;
        let mid = powers[2];
        let names = ["-1", "-1/2", "0", "+1/2", "+1"];
        let mut cells = Vec::new();
        for (i, (v, p)) in steps.iter().zip(&powers).enumerate() {
            csv.push_str(&format!("{label},{},{v},{p:.2},{:.2}\n", names[i], p - mid));
            cells.push(format!("{v} → {p:.1} W ({:+.1})", p - mid));
            if i != 2 {
                bars.push((
                    format!("{} {}", label.split(' ').next().unwrap_or(label), names[i]),
                    p - mid,
                ));
            }
        }
        println!("| {label} | {} |", cells.join(" | "));
    }
    let path = args.out.join("sensitivity.csv");
    std::fs::write(&path, csv).with_context(|| format!("{}: cannot write", path.display()))?;
    plot::diverging_bars(
        &args.out.join("sensitivity.png"),
        "Sensitivity of predicted power to mission inputs",
        "change in mean predicted power vs step 0 (W)",
        &bars,
    )?;
    println!(
        "base: {} windows of flights {flights:?}; model {}; wrote {} and sensitivity.png",
        windows.len(),
        model_path.display(),
        path.display()
    );
    Ok(())
}
