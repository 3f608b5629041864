//! The lab's command line: `dronewatt-lab` runs the research commands ([`LabCommand`]);
//! `dronewatt-torch` runs those and the operator's ([`dronewatt::cli::Command`]) with libtorch
//! registered. Both through [`dronewatt::cli::run_main`], so logging, errors and the hand-off
//! to `dronewatt-torch` are the operator binary's.

use std::process::ExitCode;

use clap::{CommandFactory, Parser, Subcommand};

/// The research commands (parsed once: the variants' sizes do not matter).
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Subcommand)]
pub enum LabCommand {
    /// Write one data-set flight as a .tlog.
    Convert(dronewatt::source::logs::dataset::ConvertArgs),
    /// Score every model on data-set flights (the paper's tables, in watts).
    Eval(crate::eval::EvalArgs),
    /// Fit the physics models' free parameters to training flights.
    Calibrate(crate::calibrate::CalibrateArgs),
    /// Train the LSTM (by-flight cross-validation, grid search, early stopping).
    Train(crate::train::TrainArgs),
    /// Sensitivity of the LSTM to altitude, payload and speed (the paper's Table 3).
    Sensitivity(crate::sensitivity::SensitivityArgs),
    /// Judge the mission forecast on the data set's route flights (pre-flight and live at 50 %, vs the autopilots' rule).
    PlanEval(crate::plan_eval::PlanEvalArgs),
    /// Score the battery pack model (rest-voltage energy, loaded-voltage model, forecasts) on the data set, beside the autopilots' rules.
    BatteryEval(crate::battery_eval::BatteryEvalArgs),
    /// Print the book's CLI reference (Markdown) from both binaries' definitions.
    CliReference,
}

/// Run one research command.
pub fn run_lab(command: LabCommand) -> anyhow::Result<()> {
    match command {
        LabCommand::Convert(a) => dronewatt::source::logs::dataset::run(a),
        LabCommand::Eval(a) => crate::eval::run(a),
        LabCommand::Calibrate(a) => crate::calibrate::run(a),
        LabCommand::Train(a) => crate::train::run(a),
        LabCommand::Sensitivity(a) => crate::sensitivity::run(a),
        LabCommand::PlanEval(a) => crate::plan_eval::run_plan_eval(a),
        LabCommand::BatteryEval(a) => crate::battery_eval::run(a),
        LabCommand::CliReference => {
            print!(
                "{}",
                crate::cli_reference::render(&dronewatt::cli::command(), &LabCli::command())
            );
            Ok(())
        }
    }
}

/// dronewatt's lab: score, fit and train the models on the M100 data set.
#[derive(Debug, Parser)]
#[command(name = "dronewatt-lab", version, about, long_about = None)]
struct LabCli {
    #[command(subcommand)]
    command: LabCommand,
}

/// `dronewatt-lab`'s `main`.
pub fn main() -> ExitCode {
    dronewatt::cli::run_main(|cli: LabCli| run_lab(cli.command))
}

/// A command of either binary: the lab's or the operator's.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Subcommand)]
pub enum AnyCommand {
    #[command(flatten)]
    Lab(LabCommand),
    #[command(flatten)]
    Operator(dronewatt::cli::Command),
}

/// `dronewatt-torch`: the lab's and the operator's commands with libtorch loaded.
#[derive(Debug, Parser)]
#[command(name = "dronewatt-torch", version, about, long_about = None)]
struct TorchCli {
    #[command(subcommand)]
    command: AnyCommand,
}

/// `dronewatt-torch`'s `main` (call after registering the libtorch parts).
pub fn torch_main() -> ExitCode {
    dronewatt::cli::run_main(|cli: TorchCli| match cli.command {
        AnyCommand::Lab(c) => run_lab(c),
        AnyCommand::Operator(c) => dronewatt::cli::run_command(c),
    })
}
