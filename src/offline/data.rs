//! Data-set flights as the models see them: each flight of `flights.csv[.gz]` walked
//! through the same encoder → MAVLink → ingest → resample → window path as live telemetry,
//! so training, evaluation and live monitoring see identical features.
//! Owner: features (issue 3).

use std::path::Path;

use crate::telemetry::TelemetryConfig;
use crate::window::Window;

/// One flight's windows, oldest first.
#[derive(Debug, Clone)]
pub struct FlightWindows {
    /// The data set's flight number.
    pub flight: u32,
    /// Route label from the data set (`R1`…`R7`, `A1`…`A3`, `H`).
    pub route: String,
    /// Every window the ingest path built for this flight. Each window's last sample
    /// carries the measured power (the target).
    pub windows: Vec<Window>,
}

/// Load these flights (all when `flights` is `None`) from the official file, plain or gzip.
pub fn load_flights(path: &Path, flights: Option<&[u32]>, cfg: &TelemetryConfig) -> anyhow::Result<Vec<FlightWindows>> {
    let _ = (path, flights, cfg);
    anyhow::bail!("data-set loading is not implemented yet")
}

/// Hex sha256 of a file's bytes (the model card records the data file's hash).
pub fn sha256_file(path: &Path) -> anyhow::Result<String> {
    use sha2::Digest;
    use std::io::Read;
    let mut f = std::fs::File::open(path).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    let mut h = sha2::Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    loop {
        let n = f.read(&mut buf)?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
    }
    Ok(h.finalize().iter().map(|b| format!("{b:02x}")).collect())
}

/// The test flights of Choudhry et al. (ICRA 2021): never trained or validated on.
pub const TEST_FLIGHTS: [u32; 10] = [268, 269, 270, 271, 272, 273, 276, 277, 278, 279];
