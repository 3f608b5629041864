//! A simulator: an M100-like delivery mission with a physically plausible power draw.

/// Arguments of `dronewatt simulate`.
#[derive(Debug, Clone, clap::Args)]
pub struct SimulateArgs {}

/// Run `dronewatt simulate`.
pub fn run(args: SimulateArgs) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("`dronewatt simulate` is not implemented yet")
}
