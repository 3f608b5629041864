//! The `dronewatt` command line: parse, load config, run one command.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};

use dronewatt::config::Config;
use dronewatt::pipeline::{self, Pipeline};
use dronewatt::sink::{JsonTarget, SinkSpec};
use dronewatt::source::{SourceSpec, Speed};

/// Live drone power, energy and flight-time estimates from MAVLink telemetry.
#[derive(Debug, Parser)]
#[command(name = "dronewatt", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// What every command that runs the pipeline shares.
#[derive(Debug, Clone, clap::Args)]
struct RunArgs {
    /// Configuration file (TOML). Without one, the built-in defaults.
    #[arg(long, short = 'c', value_name = "FILE")]
    config: Option<PathBuf>,
    /// Write JSON lines to PATH, or to standard output with '-'.
    #[arg(long, value_name = "PATH|-")]
    json: Option<String>,
    /// No live terminal view.
    #[arg(long, short = 'q')]
    quiet: bool,
    /// Run this LSTM instead of the shipped one: a model folder, its card.toml, or a
    /// weights file (.safetensors, or a TorchScript .pt) with card.toml beside it.
    #[arg(long, value_name = "FILE")]
    model: Option<PathBuf>,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Replay a logged flight: a .tlog, a raw MAVLink stream, or the M100 flights.csv[.gz].
    Replay {
        /// The file to replay (.tlog, .bin/.raw/.mavlink raw stream, .csv or .csv.gz data set).
        file: PathBuf,
        /// Playback speed: 1 = real time, N = N× faster, 'max' = flat out.
        #[arg(long, default_value = "1")]
        speed: Speed,
        /// Which flight of a data-set CSV to replay.
        #[arg(long)]
        flight: Option<u32>,
        /// Treat FILE as a raw MAVLink stream (no timestamps) whatever its name.
        #[arg(long)]
        raw: bool,
        #[command(flatten)]
        run: RunArgs,
    },
    /// Watch a live link: udpin:HOST:PORT, udpout:HOST:PORT, tcpin:, tcpout:, serial:DEV:BAUD.
    Monitor {
        /// The link address, as MAVProxy and rust-mavlink spell it.
        address: String,
        #[command(flatten)]
        run: RunArgs,
    },
    /// Write one data-set flight as a .tlog.
    Convert(dronewatt::source::dataset::ConvertArgs),
    /// Fly the built-in simulator to a UDP address or a .tlog.
    Simulate(dronewatt::source::sim::SimulateArgs),
    /// Score every model on data-set flights (the paper's tables, in watts).
    Eval(dronewatt::offline::eval::EvalArgs),
    /// Fit the physics models' free parameters to training flights.
    Calibrate(dronewatt::offline::calibrate::CalibrateArgs),
    /// Train the LSTM (by-flight cross-validation, grid search, early stopping).
    Train(dronewatt::offline::train::TrainArgs),
    /// Sensitivity of the LSTM to altitude, payload and speed (the paper's Table 3).
    Sensitivity(dronewatt::offline::sensitivity::SensitivityArgs),
    /// Validate a configuration file and say what it sets up.
    CheckConfig {
        /// The TOML file.
        file: PathBuf,
    },
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "dronewatt=info,warn".into()),
        )
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    match real_main(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("dronewatt: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn real_main(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Replay { file, speed, flight, raw, run } => {
            if !file.exists() {
                anyhow::bail!("{}: no such file", file.display());
            }
            let name = file.to_string_lossy().to_ascii_lowercase();
            let source = if name.ends_with(".csv") || name.ends_with(".csv.gz") {
                let flight = flight.context("a data-set CSV holds many flights: pick one with --flight N")?;
                SourceSpec::Dataset { path: file, flight, speed }
            } else if raw || !name.ends_with(".tlog") {
                SourceSpec::Raw { path: file, speed }
            } else {
                SourceSpec::Tlog { path: file, speed }
            };
            run_pipeline(source, run)
        }
        Command::Monitor { address, run } => {
            // A malformed address fails here, before anything starts, with one line.
            address.parse::<dronewatt::source::link::LinkAddress>()?;
            run_pipeline(SourceSpec::Link(address), run)
        }
        Command::Convert(a) => dronewatt::source::dataset::run(a),
        Command::Simulate(a) => dronewatt::source::sim::run(a),
        Command::Eval(a) => dronewatt::offline::eval::run(a),
        Command::Calibrate(a) => dronewatt::offline::calibrate::run(a),
        Command::Train(a) => dronewatt::offline::train::run(a),
        Command::Sensitivity(a) => dronewatt::offline::sensitivity::run(a),
        Command::CheckConfig { file } => {
            let cfg = Config::load(&file)?;
            print!("{}", describe_config(&file, &cfg));
            Ok(())
        }
    }
}

/// What `check-config` prints: what the file sets up, in words.
fn describe_config(file: &std::path::Path, cfg: &Config) -> String {
    let e = &cfg.energy;
    let mut out = format!("{}: ok\n", file.display());
    out += &format!(
        "energy: capacity {}, {} cells, reserve {}%, forecast model {}, smoothing {} s\n",
        e.capacity_wh.map_or("from the vehicle, else 129.96 Wh".to_string(), |c| format!("{c:.2} Wh")),
        e.cell_count.map_or("from the vehicle, else 6".to_string(), |n| n.to_string()),
        e.reserve_pct,
        e.model.as_deref().unwrap_or("lstm, else measured power"),
        e.smoothing_s
    );
    out += &format!("alerts: {} rule(s)\n", cfg.alerts.len());
    for r in &cfg.alerts {
        out += &format!("  {}\n", r.describe());
    }
    let m = &cfg.sinks.mavlink;
    let mav_on = match m.enabled {
        Some(true) => "on",
        Some(false) => "off",
        None if m.address.is_some() => "on",
        None => "on when monitoring a link",
    };
    out += &format!(
        "sinks.mavlink: {mav_on}, to {}, as system {} component {}, estimates at {} Hz\n",
        m.address.as_deref().unwrap_or("the monitored link"),
        m.system_id,
        m.component_id,
        m.rate_hz
    );
    let w = &cfg.sinks.web;
    out += &format!("sinks.web: {}\n", if w.enabled { format!("on, http://{}/", w.bind) } else { "off".into() });
    out
}

fn run_pipeline(source: SourceSpec, run: RunArgs) -> Result<()> {
    let mut config = match &run.config {
        Some(p) => Config::load(p)?,
        None => Config::default(),
    };
    if let Some(m) = &run.model {
        config.models.lstm.path = Some(m.clone());
    }
    let mut sinks = Vec::new();
    if !run.quiet && run.json.as_deref() != Some("-") {
        sinks.push(SinkSpec::Terminal);
    }
    if let Some(j) = &run.json {
        sinks.push(SinkSpec::Json(if j == "-" { JsonTarget::Stdout } else { JsonTarget::File(j.into()) }));
    }
    // MAVLink back to the ground station: on by default when watching a live link (so
    // `monitor udpin:…` answers the ground station with no config at all), or wherever
    // the config gives an address.
    let mav = &config.sinks.mavlink;
    let live = matches!(source, SourceSpec::Link(_));
    if mav.enabled.unwrap_or(live || mav.address.is_some()) {
        sinks.push(SinkSpec::Mavlink(mav.clone()));
    }
    if config.sinks.web.enabled {
        sinks.push(SinkSpec::Web(config.sinks.web.clone()));
    }
    let rt = tokio::runtime::Builder::new_multi_thread().enable_all().build()?;
    rt.block_on(async move {
        let shutdown = pipeline::shutdown_on_signal();
        pipeline::run(Pipeline { config, source, sinks }, shutdown).await.map(|_| ())
    })
}
