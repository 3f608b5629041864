//! Sensitivity analysis of the trained LSTM (the paper's Table 3).

/// Arguments of `dronewatt sensitivity`.
#[derive(Debug, Clone, clap::Args)]
pub struct SensitivityArgs {}

/// Run `dronewatt sensitivity`.
pub fn run(args: SensitivityArgs) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("`dronewatt sensitivity` is not implemented yet")
}
