//! Evaluation: every model over data-set flights through the live ingest path, scored by flight.

/// Arguments of `dronewatt eval`.
#[derive(Debug, Clone, clap::Args)]
pub struct EvalArgs {}

/// Run `dronewatt eval`.
pub fn run(args: EvalArgs) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("`dronewatt eval` is not implemented yet")
}
