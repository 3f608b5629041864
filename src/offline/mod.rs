//! Offline work: train, cross-validate, evaluate, calibrate, sensitivity, plots.

pub mod calibrate;
pub mod data;
pub mod eval;
pub mod metrics;
pub mod mission;
pub mod plot;
pub mod sensitivity;
pub mod train;
