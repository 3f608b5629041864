//! Offline work the operator runs: `plan` (a mission's energy before flight) and `learn` (a vehicle
//! from its logs), through the live stages: windows from the ingest path ([`data`]), estimates,
//! energy and alerts from the live chain ([`chain`]), each with the user's configuration
//! (`--config`). The lab's research commands (eval, calibrate, train, sensitivity, plan-eval,
//! battery-eval) live in the `dronewatt-lab` crate (`lab/`) and use these.

pub mod args;
pub mod chain;
pub mod data;
pub mod fit;
pub mod learn;
pub mod metrics;
pub mod plan;
pub mod plot;
