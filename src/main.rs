//! The `dronewatt` command line: parse, load config, run one command.
//!
//! This binary does not load libtorch (it starts in milliseconds; the LSTM runs on the
//! hand-written kernel). A command that needs libtorch (training, a TorchScript model) fails
//! with [`NeedsLibtorch`] and is handed, whole, to `dronewatt-torch` beside this executable
//! ([`handoff`]), which compiles this same file with the libtorch parts registered.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};

use dronewatt::config::Config;
use dronewatt::model::NeedsLibtorch;
use dronewatt::mission::guidance::{InvalidOption, Triangle};
use dronewatt::sim::{self, Autopilot, SimOptions};
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
    /// Watch only these vehicles (MAVLink system ids): ids and ranges such as `1-125` or
    /// `3,7,10-20`; the others are ignored, so several instances can split one link's
    /// fleet. Overrides `[fleet] vehicles`.
    #[arg(long, value_name = "IDS")]
    vehicles: Option<String>,
    /// Vehicle profile to run the physics models on (a `config/vehicles/*.toml` file, or the
    /// `profile.toml` that `dronewatt learn` wrote); overrides the config's `vehicle`.
    #[arg(long, value_name = "FILE")]
    vehicle: Option<PathBuf>,
    /// Keep the vehicle store (what was learned about each vehicle, its flights) in DIR;
    /// `off`: none. Default: $DRONEWATT_HOME, else $XDG_DATA_HOME/dronewatt, else
    /// ~/.local/share/dronewatt.
    #[arg(long, value_name = "DIR")]
    data_dir: Option<PathBuf>,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Replay a logged flight: a .tlog, an ArduPilot DataFlash .bin, a PX4 .ulg, a raw MAVLink
    /// stream, or the M100 flights.csv[.gz].
    Replay {
        /// The file to replay (.tlog, an ArduPilot DataFlash .bin, a PX4 .ulg, .bin/.raw/.mavlink raw stream,
        /// .csv or .csv.gz data set). A .bin is DataFlash when it starts with DataFlash's header.
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
    Simulate(SimulateArgs),
    /// Score every model on data-set flights (the paper's tables, in watts).
    Eval(dronewatt::offline::eval::EvalArgs),
    /// Learn a vehicle from its .tlog logs: the physics models fitted, scored on held-out logs; writes a profile and a model card.
    Learn(dronewatt::offline::learn::LearnArgs),
    /// Fit the physics models' free parameters to training flights.
    Calibrate(dronewatt::offline::calibrate::CalibrateArgs),
    /// Train the LSTM (by-flight cross-validation, grid search, early stopping).
    Train(dronewatt::offline::train::TrainArgs),
    /// Sensitivity of the LSTM to altitude, payload and speed (the paper's Table 3).
    Sensitivity(dronewatt::offline::sensitivity::SensitivityArgs),
    /// Forecast a mission plan's energy before flight: per leg and in all, P50/P90, margin over reserve.
    Plan(dronewatt::offline::mission::PlanArgs),
    /// Judge the mission forecast on the data set's route flights (pre-flight and live at 50 %, vs the autopilots' rule).
    PlanEval(dronewatt::offline::mission::PlanEvalArgs),
    /// List the vehicles in the vehicle store: flights, energy per minute, the pack's capacity trend.
    Vehicles {
        /// The store's folder (as `monitor --data-dir`).
        #[arg(long, value_name = "DIR")]
        data_dir: Option<PathBuf>,
        /// Print JSON instead of the table.
        #[arg(long)]
        json: bool,
    },
    /// Validate a configuration file and say what it sets up.
    CheckConfig {
        /// The TOML file.
        file: PathBuf,
    },
}

pub fn main() -> ExitCode {
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
            if e.chain().any(|c| c.is::<NeedsLibtorch>()) {
                handoff();
            }
            eprintln!("dronewatt: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// Run this command line again as `dronewatt-torch` (beside this executable), replacing
/// this process; returns only when there is none to run (the error then says how to build
/// it). `DRONEWATT_HANDOFF` marks the child, so a hand-off happens at most once.
fn handoff() {
    use std::os::unix::process::CommandExt;
    const MARK: &str = "DRONEWATT_HANDOFF";
    if std::env::var_os(MARK).is_some() {
        return;
    }
    let Some(torch) = std::env::current_exe().ok().map(|exe| exe.with_file_name("dronewatt-torch")).filter(|p| p.is_file()) else {
        return;
    };
    tracing::info!("handing the command to {} (it loads libtorch)", torch.display());
    let err = std::process::Command::new(&torch).args(std::env::args_os().skip(1)).env(MARK, "1").exec();
    tracing::warn!("{}: cannot run: {err}", torch.display());
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
            } else if !raw && (name.ends_with(".ulg") || name.ends_with(".bin") && dronewatt::source::dataflash::starts_as_dataflash(&file)) {
                SourceSpec::AutopilotLog { path: file, speed }
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
        Command::Simulate(a) => simulate(a),
        Command::Eval(a) => dronewatt::offline::eval::run(a),
        Command::Calibrate(a) => dronewatt::offline::calibrate::run(a),
        Command::Learn(a) => dronewatt::offline::learn::run(a),
        Command::Train(a) => dronewatt::offline::train::run(a),
        Command::Sensitivity(a) => dronewatt::offline::sensitivity::run(a),
        Command::Plan(a) => dronewatt::offline::mission::run_plan(a),
        Command::PlanEval(a) => dronewatt::offline::mission::run_plan_eval(a),
        Command::Vehicles { data_dir, json } => {
            let dir = dronewatt::vehicle::store::data_dir_from_env(data_dir.as_deref())
                .context("the vehicle store is off (DRONEWATT_HOME=off or no home directory): give --data-dir DIR")?;
            print!("{}", dronewatt::vehicle::store::list(&dir, json)?);
            Ok(())
        }
        Command::CheckConfig { file } => {
            let cfg = Config::load(&file)?;
            // The secrets' files too: missing, unreadable or readable by others fails here.
            let err = |e: String| anyhow::anyhow!("{}: {e}", file.display());
            cfg.link.load().map_err(err)?;
            if cfg.sinks.web.enabled {
                cfg.sinks.web.token().map_err(err)?;
            }
            print!("{}", describe_config(&file, &cfg));
            Ok(())
        }
    }
}

/// Arguments of `dronewatt simulate`: a triangle mission (the default route) for a vehicle.
#[derive(Debug, Clone, clap::Args)]
struct SimulateArgs {
    /// Write the flight to this file: a `.tlog`, or with `.bin` the ArduPilot vehicle's own
    /// DataFlash log (one vehicle, `--autopilot ardupilot`), with `.ulg` the PX4 vehicle's
    /// own ULog (one vehicle, `--autopilot px4`).
    #[arg(long, value_name = "FILE.tlog|FILE.bin|FILE.ulg", conflicts_with = "udp", required_unless_present = "udp")]
    out: Option<PathBuf>,
    /// Stream the flight's MAVLink frames to this UDP address (`dronewatt monitor udpin:…`).
    #[arg(long, value_name = "HOST:PORT")]
    udp: Option<String>,
    /// Commanded cruise ground speed, m/s.
    #[arg(long, default_value_t = 10.0)]
    speed_mps: f64,
    /// Cruise altitude above home, m.
    #[arg(long, default_value_t = 25.0)]
    altitude_m: f64,
    /// Payload, g.
    #[arg(long, default_value_t = 500.0)]
    payload_g: f64,
    /// Mean wind speed, m/s.
    #[arg(long, default_value_t = 3.0)]
    wind_mps: f64,
    /// Direction the wind comes FROM, degrees clockwise from north (meteorological).
    #[arg(long, default_value_t = 270.0)]
    wind_dir_deg: f64,
    /// Side of the triangle, m.
    #[arg(long, default_value_t = 300.0)]
    leg_m: f64,
    /// Hover time over home after the triangle (the delivery), s.
    #[arg(long, default_value_t = 20.0)]
    hover_s: f64,
    /// Seed of the noise and gusts.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Fly this mission plan (QGroundControl `.plan` or `QGC WPL 110` `.waypoints`)
    /// instead of the triangle, moved to the simulator's home (its offsets kept), at
    /// `--speed-mps` until the plan sets a speed; the tlog logs the mission (MISSION_COUNT,
    /// MISSION_ITEM_INT) and MISSION_CURRENT, as a ground station's log of ArduPilot does.
    #[arg(long, value_name = "FILE")]
    plan: Option<PathBuf>,
    /// Pace of `--udp`: `real` (wall clock, the default), `max` (flat out) or a factor such
    /// as `5` (five times real time). A `--out` tlog is always written at once.
    #[arg(long)]
    rate: Option<Speed>,
    /// Whose telemetry style to imitate.
    #[arg(long, value_enum, default_value_t = Autopilot::Ardupilot)]
    autopilot: Autopilot,
    /// The airframe and battery: a built-in profile (m100, x500, quad-3s) or a vehicle
    /// profile file with the simulator's sections ([rotor], [body], [powertrain], [battery]).
    #[arg(long, value_name = "PROFILE", default_value = "m100")]
    vehicle: String,
    /// Fly this many vehicles at once on the one link or tlog: system ids 1..=N, each its own
    /// heading (the route turned about home), seed (seed + i) and start (within the first second).
    #[arg(long, value_name = "N", default_value_t = 1)]
    vehicles: u8,
}

impl SimulateArgs {
    /// The library's options; an out-of-range value is named by its flag.
    fn options(&self) -> Result<SimOptions> {
        let flag = |e: InvalidOption| anyhow::anyhow!("--{} {}", e.key.replace('_', "-"), e.reason);
        let (route, mission) = match &self.plan {
            Some(path) => {
                let plan = dronewatt::mission::plan::Plan::load(path)?;
                let (route, mission) = sim::SimMission::from_plan(&plan, self.speed_mps, self.autopilot).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
                (route, Some(mission))
            }
            None => {
                let triangle = Triangle { leg_m: self.leg_m, altitude_m: self.altitude_m, speed_mps: self.speed_mps, hover_s: self.hover_s };
                triangle.validate().map_err(flag)?;
                (triangle.route(), None)
            }
        };
        let opts = SimOptions {
            vehicle: dronewatt::model::profile::VehicleProfile::named_or_file(&self.vehicle)?,
            route,
            mission,
            payload_g: self.payload_g,
            wind_mps: self.wind_mps,
            wind_dir_deg: self.wind_dir_deg,
            seed: self.seed,
            autopilot: self.autopilot,
        };
        opts.validate().map_err(|e| match e.downcast::<InvalidOption>() {
            Ok(e) => flag(e),
            Err(e) => e,
        })?;
        Ok(opts)
    }
}

/// `dronewatt simulate`: fly, then write the `.tlog` or stream to UDP.
fn simulate(args: SimulateArgs) -> Result<()> {
    let opts = args.options()?;
    let (flight, energy_wh) = if args.vehicles == 1 {
        let f = sim::simulate(&opts)?;
        let e = f.energy_wh();
        (f, e)
    } else {
        // One stream; the longest flight's truth gives the duration, the energy is everyone's.
        let flights = sim::simulate_fleet(&opts, args.vehicles)?;
        let energy_wh: f64 = flights.iter().map(|f| f.energy_wh()).sum();
        let truth = flights.iter().max_by(|a, b| a.duration_s().total_cmp(&b.duration_s())).map(|f| f.truth.clone()).unwrap_or_default();
        (sim::SimFlight { records: sim::merge(&flights), truth }, energy_wh)
    };
    let duration_s = flight.duration_s();
    tracing::info!(messages = flight.records.len(), duration_s, energy_wh, "simulated mission");
    if let Some(path) = &args.out {
        let bytes = if dronewatt::source::dataflash::is_dataflash(path) {
            // The autopilot's own log: one ArduPilot vehicle (PX4 writes ULog, not DataFlash).
            if args.vehicles > 1 || args.autopilot != Autopilot::Ardupilot {
                bail!("{}: a DataFlash .bin is one ArduPilot vehicle's own log: use --autopilot ardupilot and one vehicle, or write a .tlog", path.display());
            }
            sim::output::write_dataflash(path, &flight)?
        } else if dronewatt::source::ulog::is_ulog(path) {
            if args.vehicles > 1 || args.autopilot != Autopilot::Px4 {
                bail!("{}: a ULog .ulg is one PX4 vehicle's own log: use --autopilot px4 and one vehicle, or write a .tlog", path.display());
            }
            sim::output::write_ulog(path, &flight)?
        } else {
            sim::output::write_tlog(path, &flight)?
        };
        let n = flight.records.len();
        let who = if args.vehicles > 1 { format!(" by {} vehicles (system ids 1-{})", args.vehicles, args.vehicles) } else { String::new() };
        eprintln!("{}: {n} messages, {duration_s:.1} s of flight, {energy_wh:.1} Wh drawn{who}, {bytes} bytes", path.display());
        return Ok(());
    }
    let addr = args.udp.as_deref().context("give --out FILE.tlog or --udp HOST:PORT")?;
    let speed = args.rate.unwrap_or(Speed::Factor(1.0));
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().context("cannot start the tokio runtime")?;
    let sent = rt.block_on(async {
        tokio::select! {
            r = sim::output::stream_udp(&flight.records, addr, speed) => r,
            _ = tokio::signal::ctrl_c() => Ok(0),
        }
    })?;
    eprintln!("sent {sent} frames to udp {addr}");
    Ok(())
}

/// What `check-config` prints: what the file sets up, in words.
fn describe_config(file: &std::path::Path, cfg: &Config) -> String {
    let e = &cfg.energy;
    let mut out = format!("{}: ok\n", file.display());
    out += &format!(
        "energy: capacity {}, cells {}, reserve {}%, forecast model {}, smoothing {} s\n",
        e.capacity_wh.map_or("from the vehicle (else 129.96 Wh)".to_string(), |c| format!("{c:.2} Wh")),
        e.cell_count.map_or("from the vehicle (else 6)".to_string(), |n| n.to_string()),
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
        m.system_id.map_or("of each vehicle".to_string(), |id| id.to_string()),
        m.component_id,
        m.rate_hz
    );
    let w = &cfg.sinks.web;
    let guarded = if w.token_file.is_some() || std::env::var_os(dronewatt::sink::web::TOKEN_ENV).is_some() { ", token required" } else { "" };
    out += &format!("sinks.web: {}\n", if w.enabled { format!("on, http://{}/{guarded}", w.bind) } else { "off".into() });
    let l = &cfg.link;
    out += &match &l.signing_key_file {
        Some(k) => format!(
            "link: MAVLink 2 signing with the key in {}, link id {}, unsigned frames {}\n",
            k.display(),
            l.signing_link_id,
            if l.require_signing { "refused" } else { "accepted" }
        ),
        None => "link: no signing\n".into(),
    };
    let f = &cfg.fleet;
    out += &format!(
        "fleet: vehicles {}, lost after {} s, dropped after {} s, batches wait up to {} ms, LSTM {}\n",
        f.vehicles.as_deref().unwrap_or("all"),
        f.lost_after_s,
        f.drop_after_s,
        f.batch_wait_ms,
        f.lstm_rate_hz.map_or("on every window".to_string(), |r| format!("at {r} Hz per vehicle"))
    );
    let q = &cfg.sinks.mqtt;
    out += &format!(
        "sinks.mqtt: {}\n",
        if q.enabled {
            format!(
                "on, {}://{}:{}/ under {}/ as instance {}{}",
                if q.tls { "mqtts" } else { "mqtt" },
                q.host,
                q.port(),
                q.prefix,
                q.instance(),
                q.username.as_ref().map(|u| format!(", user {u}")).unwrap_or_default()
            )
        } else {
            "off".into()
        }
    );
    out
}

fn run_pipeline(source: SourceSpec, run: RunArgs) -> Result<()> {
    let mut config = Config::load_or_default(run.config.as_deref())?;
    if let Some(m) = &run.model {
        config.models.lstm.path = Some(m.clone());
    }
    if let Some(v) = &run.vehicles {
        dronewatt::fleet::VehicleFilter::parse(v).map_err(|e| anyhow::anyhow!("--vehicles {v}: {e}"))?;
        config.fleet.vehicles = Some(v.clone());
    }
    if let Some(v) = &run.vehicle {
        config.vehicle = Some(v.clone());
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
    if config.sinks.mqtt.enabled {
        sinks.push(SinkSpec::Mqtt(config.sinks.mqtt.clone()));
    }
    let data_dir = dronewatt::vehicle::store::data_dir_from_env(run.data_dir.as_deref());
    let rt = tokio::runtime::Builder::new_multi_thread().enable_all().build()?;
    rt.block_on(async move {
        let shutdown = pipeline::shutdown_on_signal();
        pipeline::run(Pipeline { config, source, sinks, data_dir }, shutdown).await.map(|_| ())
    })
}
