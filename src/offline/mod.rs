//! Offline work: train, cross-validate, evaluate, calibrate, sensitivity, plots.

pub mod calibrate;
pub mod data;
pub mod eval;
pub mod sensitivity;
pub mod train;
