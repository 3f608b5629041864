//! The lab's integration tests, as one test binary (as the product's `tests/it/`): each file
//! a command of `dronewatt-lab`, run on the real data set where it is beside the checkout.

#[path = "../../../tests/it/harness.rs"]
mod harness;

mod battery_eval;
mod cli_reference;
mod config;
mod eval;
mod plan_eval;
