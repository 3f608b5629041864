//! # dronewatt-lab
//!
//! The lab beside the product: the commands that score, fit and train dronewatt's models on
//! the M100 data set, and the tables the book prints from their `--json`. It uses the
//! product library ([`dronewatt`]) and the product never uses it.
//!
//! | module | command |
//! |---|---|
//! | [`eval`] | `eval`: every model on data-set flights (the paper's tables, in watts) |
//! | [`calibrate`] | `calibrate`: the physics models' free parameters fitted to training flights |
//! | [`train`] | `train`: the LSTM (the trainer itself is `dronewatt-torch`'s) |
//! | [`sensitivity`] | `sensitivity`: the LSTM against altitude, payload and speed |
//! | [`plan_eval`] | `plan-eval`: the mission forecast on the route flights (with [`route`], [`forecast_fit`], [`live_dump`]) |
//! | [`battery_eval`] | `battery-eval`: the pack model beside the autopilots' rules |
//! | [`cli`] | the command line of `dronewatt-lab` and `dronewatt-torch` |
//! | [`cli_reference`] | `cli-reference`: the book's CLI reference, generated from clap |

pub mod battery_eval;
pub mod calibrate;
pub mod cli;
pub mod cli_reference;
pub mod eval;
pub mod forecast_fit;
pub mod live_dump;
pub mod plan_eval;
pub mod route;
pub mod sensitivity;
pub mod train;
