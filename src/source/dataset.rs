//! The M100 data set as a MAVLink source: each CSV row encoded as the messages an autopilot would send.

/// Arguments of `dronewatt convert`.
#[derive(Debug, Clone, clap::Args)]
pub struct ConvertArgs {}

/// Run `dronewatt convert`.
pub fn run(args: ConvertArgs) -> anyhow::Result<()> {
    let _ = args;
    anyhow::bail!("`dronewatt convert` is not implemented yet")
}

/// One flight of the official `flights.csv[.gz]` encoded as an in-memory `.tlog`: every row
/// becomes the MAVLink messages an autopilot would send, stamped with the row's time.
/// (Owner: features. Used by the `Dataset` source, `convert` and `offline::data`.)
pub fn flight_tlog(path: &std::path::Path, flight: u32) -> anyhow::Result<Vec<u8>> {
    let _ = (path, flight);
    anyhow::bail!("the data-set encoder is not implemented yet")
}
