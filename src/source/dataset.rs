//! The M100 data set as a MAVLink source: each CSV row encoded as the messages an autopilot would send.

/// Arguments of `dronewatt convert`.
#[derive(Debug, Clone, clap::Args)]
pub struct ConvertArgs {}

/// Run `dronewatt convert`.
pub fn run(args: ConvertArgs) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("`dronewatt convert` is not implemented yet")
}
