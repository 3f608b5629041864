//! The `dronewatt` command line: the operator's commands (parse, load config, run one
//! command). `dronewatt`'s `main` is [`main`]; the lab's binaries (`dronewatt-lab`, and
//! `dronewatt-torch`, which registers the libtorch parts first) run their own commands and
//! these ([`Command`], [`run_command`]) through the same [`run_main`].
//!
//! `dronewatt` does not load libtorch (it starts in milliseconds; the LSTM runs on the
//! hand-written kernel). A command that needs libtorch (training, a TorchScript model) fails
//! with [`NeedsLibtorch`] and is handed, whole, to `dronewatt-torch` beside this executable
//! (`handoff`), which runs this same command line with the libtorch parts registered.

mod dashboard;
mod describe;
mod gateway;
pub mod simulate;

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::{CommandFactory, Parser, Subcommand};

use crate::cli::describe::describe_config;
use crate::cli::simulate::SimulateArgs;
use crate::config::Config;
use crate::model::NeedsLibtorch;
use crate::offline::args::ConfigArg;
use crate::pipeline::{self, Pipeline};
use crate::sink::{JsonTarget, SinkSpec};
use crate::source::{SourceSpec, Speed};

/// Live drone power, energy and flight-time estimates from MAVLink telemetry.
#[derive(Debug, Parser)]
#[command(name = "dronewatt", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// What every command that runs the pipeline shares.
#[derive(Debug, Clone, clap::Args)]
pub struct RunArgs {
    #[command(flatten)]
    config: ConfigArg,
    /// Write JSON lines to PATH, or to standard output with '-'.
    #[arg(long, value_name = "PATH|-")]
    json: Option<String>,
    /// No live terminal view.
    #[arg(long, short = 'q')]
    quiet: bool,
    /// The pilot's status line (at most 120 characters, one a second on stderr) instead of
    /// the full screen (which is drawn only when standard output is a terminal).
    #[arg(long)]
    plain: bool,
    /// Every model's figures: the engineer's status line (each model's raw~adapted
    /// estimate, the energy's bookkeeping, the pack model, the link's counters) instead of
    /// the pilot's, and every model's estimate beside the screen's power chart.
    #[arg(long)]
    detail: bool,
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
    /// ~/.local/share/dronewatt (Linux; elsewhere the platform's data directory).
    #[arg(long, value_name = "DIR")]
    data_dir: Option<PathBuf>,
    /// The vehicle's pack, when nothing else says: `<cells>S[<n>P]:<capacity>[:<chemistry>]`,
    /// e.g. `4S2P:5000mAh:li-ion` (capacity of the whole pack in mAh, Ah or Wh; chemistry
    /// lipo, lihv, li-ion, nmc or lifepo4). Overrides the config's `[energy]` pack keys.
    #[arg(long, value_name = "SPEC")]
    pack: Option<String>,
    /// Ask the vehicle nothing (no parameter reads, no stream-rate requests): only listen.
    /// By default a live link asks for the battery parameters and, with
    /// MAV_CMD_SET_MESSAGE_INTERVAL (ArduPilot: REQUEST_DATA_STREAM when refused), for the
    /// messages the estimate needs at the rates it needs. Sets `[link] listen_only`.
    #[arg(long)]
    listen_only: bool,
}

/// The operator's commands.
#[derive(Debug, Subcommand)]
pub enum Command {
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
    #[command(after_help = crate::alert::defaults::HELP)]
    Monitor {
        /// The link address, as MAVProxy and rust-mavlink spell it; several for several
        /// links (one vehicle over redundant radios, or fleets on several links), else the
        /// config's `[[links]]`.
        address: Vec<String>,
        #[command(flatten)]
        nats: crate::source::nats::NatsArgs,
        #[command(flatten)]
        run: RunArgs,
    },
    /// Read MAVLink links (the addresses `monitor` takes) into a NATS JetStream stream for
    /// fleet workers (`monitor --nats`), and send what they address to a vehicle back on its
    /// links.
    Gateway {
        /// The link addresses, as `monitor` takes them (else the config's `[[links]]`).
        address: Vec<String>,
        #[command(flatten)]
        nats: crate::source::nats::NatsArgs,
        #[command(flatten)]
        config: ConfigArg,
    },
    /// Fly the built-in simulator to a UDP address or a .tlog.
    Simulate(SimulateArgs),
    /// Learn a vehicle from its .tlog logs: the physics models fitted, scored on held-out logs; writes a profile and a model card.
    Learn(crate::offline::learn::LearnArgs),
    /// Forecast a mission plan's energy before flight: per leg and in all, P50/P90, margin over reserve.
    Plan(crate::offline::plan::PlanArgs),
    /// List the vehicles in the vehicle store: flights, energy per minute, the pack's capacity trend.
    Vehicles {
        /// The store's folder (as `monitor --data-dir`).
        #[arg(long, value_name = "DIR")]
        data_dir: Option<PathBuf>,
        /// Print JSON instead of the table.
        #[arg(long)]
        json: bool,
        /// With --nats: the fleet as NATS shows it (each vehicle's latest estimate, from
        /// whichever worker holds it), read as a viewer instead of the store.
        #[command(flatten)]
        nats: crate::source::nats::NatsArgs,
        /// With --nats: how long to listen for the workers' estimates.
        #[arg(long, value_name = "SECONDS", default_value_t = 3.0, requires = "nats")]
        listen: f64,
    },
    /// Serve the web dashboard of the whole fleet on NATS, read as a viewer: every
    /// vehicle's estimates and alerts, whichever worker (`monitor --nats`) holds it.
    Dashboard {
        #[command(flatten)]
        nats: crate::source::nats::NatsArgs,
        /// Address to serve the dashboard on (overrides the config's `[sinks.web] bind`;
        /// default 127.0.0.1:8787). Beyond loopback it needs an access token, as
        /// `[sinks.web]` does.
        #[arg(long, value_name = "IP:PORT")]
        bind: Option<String>,
        /// The dashboard's settings: the config's `[sinks.web]` table (its `enabled` is not
        /// needed here).
        #[command(flatten)]
        config: ConfigArg,
    },
    /// Validate a configuration file and say what it sets up; with no file, what the
    /// defaults set up (the default alert rules, as TOML to copy).
    CheckConfig {
        /// The TOML file.
        file: Option<PathBuf>,
    },
}

pub fn main() -> ExitCode {
    run_main(|cli: Cli| run_command(cli.command))
}

/// The operator's command line as clap defines it: what `dronewatt --help` prints and the
/// book's CLI reference is generated from (`dronewatt-lab cli-reference`).
pub fn command() -> clap::Command {
    Cli::command()
}

/// Set up logging, parse the command line as `C`, run it, and print an error the way every
/// dronewatt binary does; a command that needs libtorch is handed to `dronewatt-torch`.
pub fn run_main<C: Parser>(run: impl FnOnce(C) -> Result<()>) -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| "dronewatt=info,warn".into()),
        )
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    match run(C::parse()) {
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
    let Some(torch) = std::env::current_exe()
        .ok()
        .map(|exe| exe.with_file_name("dronewatt-torch"))
        .filter(|p| p.is_file())
    else {
        return;
    };
    tracing::info!(
        "handing the command to {} (it loads libtorch)",
        torch.display()
    );
    let err = std::process::Command::new(&torch)
        .args(std::env::args_os().skip(1))
        .env(MARK, "1")
        .exec();
    tracing::warn!("{}: cannot run: {err}", torch.display());
}

/// Run one of the operator's commands: the match only dispatches, one function per family.
pub fn run_command(command: Command) -> Result<()> {
    match command {
        Command::Replay {
            file,
            speed,
            flight,
            raw,
            run,
        } => replay(file, speed, flight, raw, run),
        Command::Monitor { address, nats, run } => monitor(address, nats, run),
        Command::Gateway {
            address,
            nats,
            config,
        } => run_gateway(address, nats, config),
        Command::Simulate(a) => simulate::simulate(a),
        Command::Learn(a) => crate::offline::learn::run(a),
        Command::Plan(a) => crate::offline::plan::run_plan(a),
        Command::Vehicles {
            data_dir,
            json,
            nats,
            listen,
        } => vehicles(data_dir, json, nats, listen),
        Command::Dashboard { nats, bind, config } => run_dashboard(nats, bind, config),
        Command::CheckConfig { file } => check_config(file),
    }
}

/// `replay`: the source the file's name (and `--raw`, `--flight`) says, through the pipeline.
fn replay(file: PathBuf, speed: Speed, flight: Option<u32>, raw: bool, run: RunArgs) -> Result<()> {
    if !file.exists() {
        anyhow::bail!("{}: no such file", file.display());
    }
    let name = file.to_string_lossy().to_ascii_lowercase();
    let source = if name.ends_with(".csv") || name.ends_with(".csv.gz") {
        let flight =
            flight.context("a data-set CSV holds many flights: pick one with --flight N")?;
        SourceSpec::Dataset {
            path: file,
            flight,
            speed,
        }
    } else if !raw
        && (name.ends_with(".ulg")
            || name.ends_with(".bin") && crate::source::logs::dataflash::starts_as_dataflash(&file))
    {
        SourceSpec::AutopilotLog { path: file, speed }
    } else if raw || !name.ends_with(".tlog") {
        SourceSpec::Raw { path: file, speed }
    } else {
        SourceSpec::Tlog { path: file, speed }
    };
    run_pipeline(source, run)
}

/// `monitor`: with `--nats` a fleet worker on the NATS stream, else the links given (or the
/// config's `[[links]]`).
fn monitor(address: Vec<String>, nats: crate::source::nats::NatsArgs, run: RunArgs) -> Result<()> {
    if nats.nats.is_some() {
        if !address.is_empty() {
            anyhow::bail!("monitor --nats is a fleet worker: it reads the NATS stream, no link address (the gateway reads the links)");
        }
        return run_pipeline(SourceSpec::Nats(nats), run);
    }
    let mut address = address;
    // Addresses on the command line are one network; the config's may name several.
    let mut networks = vec![String::new(); address.len()];
    if address.is_empty() {
        let config = run.config.load()?;
        address = config.links.iter().map(|l| l.address.clone()).collect();
        networks = config.links.iter().map(|l| l.network.clone()).collect();
    }
    // A malformed address fails here, before anything starts, with one line.
    for a in &address {
        a.parse::<crate::source::links::address::LinkAddress>()?;
    }
    let source = match <[String; 1]>::try_from(address) {
        Ok([one]) => SourceSpec::Link(one),
        Err(many) if many.is_empty() => {
            anyhow::bail!("monitor: give a link address (or [[links]] in the config)")
        }
        Err(many) => SourceSpec::Links {
            addresses: many,
            networks,
            every_link: false,
        },
    };
    run_pipeline(source, run)
}

/// `gateway`: the links (given, or the config's) into the NATS stream.
fn run_gateway(
    address: Vec<String>,
    nats: crate::source::nats::NatsArgs,
    config: ConfigArg,
) -> Result<()> {
    let config_file = config.load()?;
    let source = link_source(address, &config_file)?;
    if nats.nats.is_none() {
        anyhow::bail!("gateway: give --nats URL");
    }
    gateway::run(source, config_file, nats)
}

/// `vehicles`: with `--nats` the fleet as NATS shows it, else the vehicle store's list.
fn vehicles(
    data_dir: Option<PathBuf>,
    json: bool,
    nats: crate::source::nats::NatsArgs,
    listen: f64,
) -> Result<()> {
    if nats.nats.is_some() {
        if !(listen.is_finite() && listen > 0.0 && listen <= 3600.0) {
            anyhow::bail!("--listen {listen}: give seconds, more than 0 and at most 3600");
        }
        let listen = std::time::Duration::from_secs_f64(listen);
        print!("{}", crate::source::nats::view::run(&nats, listen, json)?);
        return Ok(());
    }
    let dir = crate::vehicle::store::data_dir_from_env(data_dir.as_deref()).context(
        "the vehicle store is off (DRONEWATT_HOME=off or no home directory): give --data-dir DIR",
    )?;
    print!("{}", crate::vehicle::store::list(&dir, json)?);
    Ok(())
}

/// `dashboard`: the fleet's web dashboard, read from NATS.
fn run_dashboard(
    nats: crate::source::nats::NatsArgs,
    bind: Option<String>,
    config: ConfigArg,
) -> Result<()> {
    if nats.nats.is_none() {
        anyhow::bail!("dashboard: give --nats URL (the fleet's NATS server)");
    }
    let mut web = config.load()?.sinks.web;
    if let Some(b) = bind {
        web.bind = b;
    }
    dashboard::run(&nats, web)
}

/// `check-config`: a file's settings (and its secrets' files), or the defaults' with the
/// default alert rules.
fn check_config(file: Option<PathBuf>) -> Result<()> {
    let Some(file) = file else {
        let cfg = Config::load_or_default(None)?;
        print!("{}", describe_config(None, &cfg));
        println!("\n# The default alert rules (put edited copies in a config to override):");
        print!("{}", crate::alert::defaults::toml(cfg.energy.reserve_pct));
        return Ok(());
    };
    let cfg = Config::load(&file)?;
    // The secrets' files too: missing, unreadable or readable by others fails here.
    let err = |e: String| anyhow::anyhow!("{}: {e}", file.display());
    cfg.link.load().map_err(err)?;
    if cfg.sinks.web.enabled {
        cfg.sinks.web.token().map_err(err)?;
    }
    print!("{}", describe_config(Some(&file), &cfg));
    Ok(())
}

/// The source of `gateway`'s addresses (else the config's `[[links]]`), as `monitor` makes it.
fn link_source(address: Vec<String>, config: &Config) -> Result<SourceSpec> {
    let (address, networks): (Vec<String>, Vec<String>) = if address.is_empty() {
        config
            .links
            .iter()
            .map(|l| (l.address.clone(), l.network.clone()))
            .unzip()
    } else {
        let n = address.len();
        (address, vec![String::new(); n])
    };
    for a in &address {
        a.parse::<crate::source::links::address::LinkAddress>()?;
    }
    Ok(match <[String; 1]>::try_from(address) {
        Ok([one]) => SourceSpec::Link(one),
        Err(many) if many.is_empty() => {
            anyhow::bail!("gateway: give a link address (or [[links]] in the config)")
        }
        Err(many) => SourceSpec::Links {
            addresses: many,
            networks,
            every_link: config.link.every_link,
        },
    })
}

fn run_pipeline(mut source: SourceSpec, run: RunArgs) -> Result<()> {
    let mut config = run.config.load()?;
    if let SourceSpec::Links { every_link, .. } = &mut source {
        *every_link = config.link.every_link;
    }
    if let Some(m) = &run.model {
        config.models.lstm.path = Some(m.clone());
    }
    if let Some(v) = &run.vehicles {
        crate::source::messages::fleet::VehicleFilter::parse(v)
            .map_err(|e| anyhow::anyhow!("--vehicles {v}: {e}"))?;
        config.fleet.vehicles = Some(v.clone());
    }
    if let Some(v) = &run.vehicle {
        config.vehicle = Some(v.clone());
    }
    if let Some(spec) = &run.pack {
        let pack = crate::vehicle::pack_spec::parse_pack(spec).map_err(anyhow::Error::msg)?;
        config.energy.capacity_wh = None;
        config.energy.cell_count = None;
        config.energy.chemistry = None;
        config.energy.fill_pack(&pack);
    }
    config.link.listen_only |= run.listen_only;
    let mut sinks = Vec::new();
    if !run.quiet && run.json.as_deref() != Some("-") {
        // The full screen on a terminal; lines on stderr with --plain or a piped stdout.
        let tty = std::io::IsTerminal::is_terminal(&std::io::stdout());
        let detail = run.detail;
        sinks.push(if tty && !run.plain {
            SinkSpec::Screen { detail }
        } else {
            SinkSpec::Terminal { detail }
        });
    }
    if let Some(j) = &run.json {
        sinks.push(SinkSpec::Json(if j == "-" {
            JsonTarget::Stdout
        } else {
            JsonTarget::File(j.into())
        }));
    }
    // MAVLink back to the ground station: on by default when watching a live link (so
    // `monitor udpin:…` answers the ground station with no config at all), or wherever
    // the config gives an address.
    let mav = &config.sinks.mavlink;
    let live = source.is_live();
    if mav.enabled.unwrap_or(live || mav.address.is_some()) {
        sinks.push(SinkSpec::Mavlink(mav.clone()));
    }
    if config.sinks.web.enabled {
        sinks.push(SinkSpec::Web(config.sinks.web.clone()));
    }
    if config.sinks.mqtt.enabled {
        sinks.push(SinkSpec::Mqtt(config.sinks.mqtt.clone()));
    }
    let data_dir = crate::vehicle::store::data_dir_from_env(run.data_dir.as_deref());
    // A telemetry log or raw capture with not one MAVLink frame in it is an error (after
    // the summary, which the sinks still write): nothing was replayed.
    let log = match &source {
        SourceSpec::Tlog { path, .. } | SourceSpec::Raw { path, .. } => Some(path.clone()),
        _ => None,
    };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    rt.block_on(async move {
        let shutdown = pipeline::shutdown_on_signal();
        pipeline::run(
            Pipeline {
                config,
                source,
                sinks,
                data_dir,
            },
            shutdown,
        )
        .await
    })
    .and_then(|stats| match log {
        Some(path) if stats.frames_ok == 0 => Err(anyhow::anyhow!(
            "{}: no MAVLink in this file: nothing was replayed",
            path.display()
        )),
        _ => Ok(()),
    })
}
