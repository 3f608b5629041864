//! # dronewatt
//!
//! Watches a drone's live MAVLink telemetry and tells the operator, before the battery
//! does, how much power the drone draws and how much energy and flight time remain.
//!
//! ## One path, one direction
//!
//! ```text
//!  source ──TimedMessage──▶ telemetry ──Window──▶ inference ──Estimate──▶ energy + alerts ──Report──▶ sinks
//!  (link, tlog, raw,         (state, frames,        (physics ×6,            (used, remaining,          (terminal, jsonl,
//!   dataset csv, sim)         resample → Sample,      lstm, byo model)        home margin, rules)        mavlink, web)
//!                             ring of T → Window)
//! ```
//!
//! Live monitoring, replay, evaluation and training all walk this same path: `eval` is a
//! replay of a data-set flight at full speed whose estimates are scored, and `train` reads
//! the windows the same code builds, so live and offline features cannot drift apart.
//! Each arrow is one typed value on a bounded tokio channel ([`pipeline`]), or a plain
//! iterator when offline work runs flat out. Nothing flows backwards; the only fan-out is
//! to the sinks. Model code ([`model`]) is pure: a window and a vehicle profile in, watts
//! out, no I/O and no clocks.
//!
//! ## Modules
//!
//! | module | what it owns |
//! |---|---|
//! | [`source`] | where MAVLink comes from: live links, `.tlog`, raw streams, the M100 CSV, the simulator; frame decoding and its counters |
//! | [`telemetry`] | vehicle state, frame/unit conversion to the data set's conventions, fixed-rate resampling, feature vectors |
//! | [`window`] | rolling windows of T samples |
//! | [`model`] | the [`model::PowerModel`] trait, the physics models, the LSTM and its model card, online adaptation to measured power |
//! | [`vehicle`] | who the vehicle is: its identity and battery parameters over MAVLink, battery facts with their provenance |
//! | [`energy`] | energy used, remaining energy and time, energy to get home |
//! | [`alert`] | alert rules from TOML: debounce, hysteresis, repeat |
//! | [`sink`] | terminal, JSON lines, MAVLink back to the ground station, web dashboard |
//! | [`pipeline`] | wires the tasks together and owns shutdown |
//! | [`offline`] | train, cross-validate, evaluate, calibrate, sensitivity, plots |
//! | [`config`] | the TOML configuration; its serde types are the reference |

pub mod alert;
pub mod config;
pub mod energy;
pub mod model;
pub mod offline;
pub mod pipeline;
pub mod sink;
pub mod source;
pub mod telemetry;
pub mod vehicle;
pub mod window;

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
