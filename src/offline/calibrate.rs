//! Calibration: fit the physics models' free parameters to training flights by least squares.

/// Arguments of `dronewatt calibrate`.
#[derive(Debug, Clone, clap::Args)]
pub struct CalibrateArgs {}

/// Run `dronewatt calibrate`.
pub fn run(args: CalibrateArgs) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("`dronewatt calibrate` is not implemented yet")
}
