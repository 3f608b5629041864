//! LSTM training: by-flight splits, cross-validation, grid search, early stopping.

/// Arguments of `dronewatt train`.
#[derive(Debug, Clone, clap::Args)]
pub struct TrainArgs {}

/// Run `dronewatt train`.
pub fn run(args: TrainArgs) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("`dronewatt train` is not implemented yet")
}
