//! # dronewatt
//!
//! Watches a drone's live MAVLink telemetry and tells the operator, before the battery
//! does, how much power the drone draws and how much energy and flight time remain.
//!
//! ## One path, one direction
//!
//! ```text
//!  source ──TimedMessage──▶ telemetry ──Window──▶ model ──Estimate──▶ energy + alert ──Report──▶ sink
//!  (link, tlog, raw,         (state, frames,        (physics ×7,         (used, remaining,          (terminal, jsonl,
//!   DataFlash, ULog,          resample → Sample,      lstm, byo model,     home and mission           mavlink, web, mqtt)
//!   dataset csv)              ring of T → Window)     adaptation)          margin, rules)
//! ```
//!
//! Live monitoring, replay and evaluation walk this same path: [`pipeline::VehicleChain`]
//! is one vehicle's stages, run as tasks live ([`pipeline::run`]) or in one loop offline
//! ([`offline::chain`]), so live and offline cannot drift apart. Each vehicle's chain also
//! forecasts that vehicle's mission ([`mission::live::MissionStep`], a step of its telemetry
//! stage after the demultiplexer). What the configuration names (the vehicle profile, the
//! calibrated profile) is read once at start ([`pipeline::Resolved`]) and handed to every
//! chain as values. Each arrow is one typed
//! value on a bounded tokio channel. Nothing flows backwards; the only fan-out is to the
//! sinks. Model code ([`model`]) is pure: a window and a vehicle profile in, watts out, no
//! I/O and no clocks.
//!
//! ## Modules
//!
//! The folders are the diagram. The floor (imports nothing of ours but the floor):
//! [`features`], [`files`], [`report`] (with [`report::status`]), [`validate`]. Each stage imports the floor and the
//! stages before it, never one after it; [`config`] gathers each part's own config and no
//! part imports it (`python3 ../shared/tools/module-cycles.py src` checks there is no cycle).
//!
//! | module | what it owns |
//! |---|---|
//! | [`features`] | the floor: [`features::Sample`], the 21 feature names and indices, the home vector, frame conversions, the vehicle class ([`features::class`]) |
//! | [`report`] | the floor: the messages from the models on ([`report::Estimate`], [`report::EnergyState`], [`report::AlertEvent`], [`report::Report`]), and [`report::status`]: what a chain says beside them (ingest counters, signal health, the uplink, the stop signal) |
//! | [`source`] | where MAVLink comes from: the link address grammar, live links, `.tlog`, raw streams, DataFlash `.bin`, ULog `.ulg`, the M100 CSV; frame decoding and its counters; which senders are vehicles ([`source::messages::fleet`]) |
//! | [`telemetry`] | vehicle state and class ([`telemetry::kind`]), frame/unit conversion to the data set's conventions, fixed-rate resampling, feature vectors, rolling windows ([`telemetry::window`]) |
//! | [`model`] | the [`model::PowerModel`] trait, the physics models (multirotor, and the fixed-wing model), the LSTM and its model card, online adaptation to measured power |
//! | [`battery`] | the pack, pure like [`model`]: chemistry and cell count, OCV curves (the TB48D's fitted on the data set), the equivalent circuit and its online estimator, the loaded-voltage forecast |
//! | [`vehicle`] | who the vehicle is: identity and battery parameters over MAVLink, battery facts with their provenance, the vehicle store |
//! | [`mission`] | plans (.plan, .waypoints, the mission protocol), the plan flown on paper, its energy forecast (P50/P90, per leg, live re-forecast) |
//! | [`energy`] | energy used, remaining energy and time, energy to get home, the forecast model's selection |
//! | [`alert`] | alert rules from TOML: debounce, hysteresis, repeat |
//! | [`sink`] | terminal, JSON lines, MAVLink back to the ground station, web dashboard, MQTT |
//! | [`pipeline`] | running it: one vehicle's chain as named stages, the shared inference stage, the fleet's demultiplexer, the sinks, shutdown |
//! | [`sim`] | the simulator: route guidance, a vehicle profile flying it, sent as ArduPilot or PX4 telemetry (`.tlog`, `.bin`, `.ulg` or UDP); outside the flow, it makes what sources read |
//! | [`offline`] | the operator's offline commands, `plan` and `learn`, and what they share with the lab: the offline chain, the data set's windows, metrics, plots, the physics models' least-squares fit |
//! | [`cli`] | the operator's command line (`dronewatt`); the lab's binaries (`lab/`, `dronewatt-lab`, `dronewatt-torch`) run it beside their own |
//! | [`config`] | the TOML configuration; its serde types are the reference |
//! | [`files`] | the floor for files a config names: one path resolver (relative to the file that names it), one reader of private secrets |
//! | [`validate`] | the floor: range checks with one message shape (`KEY = VALUE: must be in (0, 100] Hz`) for the config's sections, the vehicle profile and the simulator's options |
//! | [`fuzz_props`] | properties every reader keeps on any input: the fuzz targets' checks, replayed by `tests/it/fuzz_props.rs` |

pub mod alert;
pub mod assets;
pub mod battery;
pub mod cli;
pub mod config;
pub mod energy;
pub mod features;
pub mod files;
pub mod fuzz_props;
pub mod mission;
pub mod model;
pub mod offline;
pub mod pipeline;
pub mod report;
pub mod sim;
pub mod sink;
pub mod source;
pub mod telemetry;
pub mod validate;
pub mod vehicle;

/// The MAVLink dialect dronewatt speaks: ArduPilot's, which includes `common`.
pub use mavlink::dialects::ardupilotmega as dialect;
/// One decoded MAVLink message of [`dialect`].
pub type MavMessage = mavlink::dialects::ardupilotmega::MavMessage;

/// Where the M100 data set lives unless `DRONEWATT_DATA` says otherwise (relative to the
/// project root): `../shared/data/m100/flights.csv.gz`.
pub fn default_data_path() -> std::path::PathBuf {
    if let Some(p) = std::env::var_os("DRONEWATT_DATA") {
        return p.into();
    }
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/m100/flights.csv.gz")
}
