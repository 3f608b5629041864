//! `dronewatt simulate`: fly a triangle mission (or a plan) for a vehicle, then write the
//! log or stream it over UDP.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};

use crate::sim::guidance::{InvalidOption, Triangle};
use crate::sim::{self, Autopilot, SimOptions};
use crate::source::Speed;

/// Arguments of `dronewatt simulate`: a triangle mission (the default route) for a vehicle.
#[derive(Debug, Clone, clap::Args)]
pub struct SimulateArgs {
    /// Write the flight to this file: a `.tlog`, or with `.bin` the ArduPilot vehicle's own
    /// DataFlash log (one vehicle, `--autopilot ardupilot`), with `.ulg` the PX4 vehicle's
    /// own ULog (one vehicle, `--autopilot px4`); a plane or a quadplane: `.tlog` only.
    #[arg(
        long,
        value_name = "FILE.tlog|FILE.bin|FILE.ulg",
        conflicts_with = "udp",
        required_unless_present = "udp"
    )]
    out: Option<PathBuf>,
    /// Also write the simulator's ground truth at 10 Hz to this CSV (`t_s,phase,power_w,
    /// voltage_v,ground_speed_mps,north_m,east_m,height_m,vtol`): what a replay is scored against.
    #[arg(long, value_name = "FILE.csv")]
    truth: Option<PathBuf>,
    /// Stream the flight's MAVLink frames to this UDP address (`dronewatt monitor udpin:…`).
    #[arg(long, value_name = "HOST:PORT")]
    udp: Option<String>,
    /// Commanded cruise speed, m/s: a multirotor's ground speed (default 10), a plane's
    /// airspeed (default its `[plane] cruise_mps`; never under 1.25 × its stall speed).
    #[arg(long)]
    speed_mps: Option<f64>,
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
    /// The airframe and battery: a built-in profile (m100, x500, quad-3s, plane, quadplane)
    /// or a vehicle profile file with the simulator's sections ([rotor], [body],
    /// [powertrain], [battery]; [plane] for a plane, and all of them for a quadplane).
    #[arg(long, value_name = "PROFILE", default_value = "m100")]
    vehicle: String,
    /// Fly this many vehicles at once on the one link or tlog: system ids 1..=N, each its own
    /// heading (the route turned about home), seed (seed + i) and start (within the first second).
    #[arg(long, value_name = "N", default_value_t = 1)]
    vehicles: u8,
    /// Start the pack at this resting (open-circuit) voltage, V, through the pack's OCV
    /// curve: a part-used pack (the M100's TB48D: 26.1 V full, about 23.5 V at 60 %).
    /// Default: a full pack.
    #[arg(long, value_name = "V", conflicts_with = "soc_pct")]
    battery_v: Option<f64>,
    /// Start the pack at this state of charge, % of its energy. Default: 100 (full).
    #[arg(long, value_name = "PCT")]
    soc_pct: Option<f64>,
}

impl SimulateArgs {
    /// The library's options; an out-of-range value is named by its flag.
    fn options(&self) -> Result<SimOptions> {
        let flag = |e: InvalidOption| anyhow::anyhow!("--{} {}", e.key.replace('_', "-"), e.reason);
        let vehicle = crate::model::profile::VehicleProfile::named_or_file(&self.vehicle)?;
        let speed_mps = self
            .speed_mps
            .unwrap_or_else(|| vehicle.plane.as_ref().map_or(10.0, |p| p.cruise_mps));
        let (route, mission) = match &self.plan {
            Some(path) => {
                let plan = crate::mission::plan::Plan::load(path)?;
                let (route, mission) = sim::SimMission::from_plan(&plan, speed_mps, self.autopilot)
                    .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
                (route, Some(mission))
            }
            None => {
                let triangle = Triangle {
                    leg_m: self.leg_m,
                    altitude_m: self.altitude_m,
                    speed_mps,
                    hover_s: self.hover_s,
                };
                triangle.validate().map_err(flag)?;
                (triangle.route(), None)
            }
        };
        let opts = SimOptions {
            vehicle,
            route,
            mission,
            payload_g: self.payload_g,
            wind_mps: self.wind_mps,
            wind_dir_deg: self.wind_dir_deg,
            seed: self.seed,
            autopilot: self.autopilot,
            battery: match (self.battery_v, self.soc_pct) {
                (Some(v), _) => sim::physics::BatteryStart::RestV(v),
                (None, Some(pct)) => sim::physics::BatteryStart::Soc(pct / 100.0),
                (None, None) => sim::physics::BatteryStart::Full,
            },
        };
        if let Err(e) = sim::physics::Battery::from_profile(&opts.vehicle, opts.battery) {
            let flag = if self.battery_v.is_some() {
                "--battery-v"
            } else {
                "--soc-pct"
            };
            if self.battery_v.is_some() || self.soc_pct.is_some() {
                bail!("{flag}: {e:#}");
            }
        }
        opts.validate()
            .map_err(|e| match e.downcast::<InvalidOption>() {
                Ok(e) => flag(e),
                Err(e) => e,
            })?;
        Ok(opts)
    }
}

/// `dronewatt simulate`: fly, then write the `.tlog` or stream to UDP.
pub(crate) fn simulate(args: SimulateArgs) -> Result<()> {
    let opts = args.options()?;
    let (flight, energy_wh) = if args.vehicles == 1 {
        let f = sim::simulate(&opts)?;
        let e = f.energy_wh();
        (f, e)
    } else {
        // One stream; the longest flight's truth gives the duration, the energy is everyone's.
        let flights = sim::simulate_fleet(&opts, args.vehicles)?;
        let energy_wh: f64 = flights.iter().map(|f| f.energy_wh()).sum();
        let truth = flights
            .iter()
            .max_by(|a, b| a.duration_s().total_cmp(&b.duration_s()))
            .map(|f| f.truth.clone())
            .unwrap_or_default();
        (
            sim::SimFlight {
                records: sim::merge(&flights),
                truth,
            },
            energy_wh,
        )
    };
    let duration_s = flight.duration_s();
    if let Some(path) = &args.truth {
        sim::output::write_truth(path, &flight)?;
    }
    tracing::info!(
        messages = flight.records.len(),
        duration_s,
        energy_wh,
        "simulated mission"
    );
    if let Some(path) = &args.out {
        let own_log = crate::source::logs::dataflash::is_dataflash(path)
            || crate::source::logs::ulog::is_ulog(path);
        if own_log && sim::Frame::of(&opts.vehicle) != sim::Frame::Multirotor {
            // The readers give a .bin or .ulg the HEARTBEAT of a multirotor: a plane's would
            // be read as one.
            bail!("{}: a plane's or quadplane's flight is written as a .tlog only (dronewatt reads a .bin or .ulg as a multirotor's)", path.display());
        }
        let bytes = if crate::source::logs::dataflash::is_dataflash(path) {
            // The autopilot's own log: one ArduPilot vehicle (PX4 writes ULog, not DataFlash).
            if args.vehicles > 1 || args.autopilot != Autopilot::Ardupilot {
                bail!("{}: a DataFlash .bin is one ArduPilot vehicle's own log: use --autopilot ardupilot and one vehicle, or write a .tlog", path.display());
            }
            sim::output::write_dataflash(path, &flight)?
        } else if crate::source::logs::ulog::is_ulog(path) {
            if args.vehicles > 1 || args.autopilot != Autopilot::Px4 {
                bail!("{}: a ULog .ulg is one PX4 vehicle's own log: use --autopilot px4 and one vehicle, or write a .tlog", path.display());
            }
            sim::output::write_ulog(path, &flight)?
        } else {
            sim::output::write_tlog(path, &flight)?
        };
        let n = flight.records.len();
        let who = if args.vehicles > 1 {
            format!(
                " by {} vehicles (system ids 1-{})",
                args.vehicles, args.vehicles
            )
        } else {
            String::new()
        };
        eprintln!("{}: {n} messages, {duration_s:.1} s of flight, {energy_wh:.3} Wh drawn{who}, {bytes} bytes", path.display());
        return Ok(());
    }
    let addr = args
        .udp
        .as_deref()
        .context("give --out FILE.tlog or --udp HOST:PORT")?;
    let speed = args.rate.unwrap_or(Speed::Factor(1.0));
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("cannot start the tokio runtime")?;
    let sent = rt.block_on(async {
        tokio::select! {
            r = sim::output::stream_udp(&flight.records, addr, speed) => r,
            _ = tokio::signal::ctrl_c() => Ok(0),
        }
    })?;
    eprintln!("sent {sent} frames to udp {addr}");
    Ok(())
}
