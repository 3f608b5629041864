//! Offline work: train, cross-validate, evaluate, calibrate, learn a vehicle from its logs, sensitivity, plots — through
//! the live stages: windows from the ingest path ([`data`]), estimates, energy and alerts
//! from the live chain ([`chain`]), each with the user's configuration (`--config`).

pub mod args;
pub mod battery_eval;
pub mod calibrate;
pub mod chain;
pub mod data;
pub mod eval;
pub mod forecast_fit;
pub mod learn;
pub mod live_dump;
pub mod metrics;
pub mod plan;
pub mod plan_eval;
pub mod plot;
pub mod route;
pub mod sensitivity;
pub mod train;
