//! Data-set flights as the models see them: each flight of `flights.csv[.gz]` walked
//! through the same encoder → MAVLink → ingest → resample → window path as live telemetry,
//! so training, evaluation and live monitoring see identical features. The telemetry
//! stage is built from the configuration's `[telemetry]` and `[mission]`, as live.

use std::path::Path;

use crate::source::logs::dataset;
use crate::telemetry::window::Window;
use crate::telemetry::{MissionConfig, Telemetry, TelemetryConfig};

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

/// Every flight of `want` is among `read` (else the error names the file and the missing).
pub fn require_flights(read: &[dataset::Flight], want: &[u32], path: &Path) -> anyhow::Result<()> {
    let missing: Vec<u32> = want
        .iter()
        .copied()
        .filter(|w| !read.iter().any(|f| f.flight == *w))
        .collect();
    if missing.is_empty() {
        Ok(())
    } else {
        anyhow::bail!(
            "{}: flights {missing:?} are not in this file",
            path.display()
        )
    }
}

/// Load these flights (all when `flights` is `None`) from the official file, plain or gzip.
///
/// Each flight walks the live path: [`dataset::encode_flight`] (rows → MAVLink tlog bytes) →
/// decode → [`Telemetry`] (state, frames, resampling) → windows. Flights are spread over
/// two threads; a progress bar shows on stderr when more than a few are loaded. Asking
/// for a flight the file does not hold is an error naming it; rows the reader skipped
/// are reported by a warning (see [`dataset::read_flights`]).
///
/// Memory: every window owns its T samples (~130 bytes each), so the whole data set at
/// 10 Hz and T = 10 is about 0.5 GB.
pub fn load_flights(
    path: &Path,
    flights: Option<&[u32]>,
    cfg: &TelemetryConfig,
    mission: &MissionConfig,
) -> anyhow::Result<Vec<FlightWindows>> {
    cfg.validate().map_err(anyhow::Error::msg)?;
    let ds = dataset::read_flights(path, flights)?;
    if let Some(want) = flights {
        require_flights(&ds.flights, want, path)?;
    }
    let bar = if ds.flights.len() > 4 {
        indicatif::ProgressBar::new(ds.flights.len() as u64)
    } else {
        indicatif::ProgressBar::hidden()
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "loading flights {bar:30} {pos}/{len} [{elapsed}<{eta}]",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut results: Vec<(usize, FlightWindows)> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..2)
            .map(|_| {
                s.spawn(|| {
                    let mut done = Vec::new();
                    loop {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(f) = ds.flights.get(i) else { break };
                        done.push((i, flight_windows(f, cfg, mission)));
                        bar.inc(1);
                    }
                    done
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().unwrap_or_default())
            .collect()
    });
    bar.finish_and_clear();
    results.sort_by_key(|(i, _)| *i);
    Ok(results.into_iter().map(|(_, w)| w).collect())
}

/// One data-set flight through encoder → tlog bytes → decode → [`Telemetry`] → windows.
/// The flight's own mission facts (NAMED_VALUE_FLOAT) override `mission` once they arrive.
pub fn flight_windows(
    f: &dataset::Flight,
    cfg: &TelemetryConfig,
    mission: &MissionConfig,
) -> FlightWindows {
    let bytes = dataset::encode_flight(f);
    let stats = crate::report::status::IngestStats::default();
    let mut tel = Telemetry::new(cfg, mission);
    let mut windows = Vec::new();
    for m in crate::source::logs::tlog::decode_tlog(&bytes, &stats) {
        tel.push(&m, &mut windows);
    }
    tel.finish(&mut windows);
    FlightWindows {
        flight: f.flight,
        route: f.route.clone(),
        windows,
    }
}

/// A data-set flight's mission facts, as [`list_flights`] reports them.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct FlightInfo {
    /// Flight number.
    pub flight: u32,
    /// Route label (`R1`…`R7`, `A1`…`A3`, `H`).
    pub route: String,
    /// Commanded cruise ground speed, m/s.
    pub speed_m_s: f64,
    /// Payload, g.
    pub payload_g: f64,
    /// Commanded cruise altitude, m (highest stage of a multi-stage text like `25-50-100-25`).
    pub altitude_m: f64,
    /// Number of rows.
    pub rows: usize,
    /// Recording length, s (time of the last row).
    pub duration_s: f64,
}

/// Every flight in the file with its route, speed, payload and altitude, in flight order:
/// what `eval` and `train` use to pick flights. Reads (and for .gz, decompresses) the file
/// once, encoding nothing: about a second for the whole data set.
pub fn list_flights(path: &Path) -> anyhow::Result<Vec<FlightInfo>> {
    let ds = dataset::read_flights(path, None)?;
    Ok(ds
        .flights
        .iter()
        .map(|f| FlightInfo {
            flight: f.flight,
            route: f.route.clone(),
            speed_m_s: f.speed_m_s,
            payload_g: f.payload_g,
            altitude_m: f.altitude_m,
            rows: f.rows.len(),
            duration_s: f.rows.last().map_or(0.0, |r| r.time_s),
        })
        .collect())
}

/// Hex sha256 of a file's bytes (the model card records the data file's hash).
pub fn sha256_file(path: &Path) -> anyhow::Result<String> {
    use sha2::Digest;
    use std::io::Read;
    let mut f =
        std::fs::File::open(path).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    let mut h = sha2::Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    loop {
        let n = f.read(&mut buf)?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
    }
    Ok(hex::encode(h.finalize()))
}

/// The test flights of Choudhry et al. (ICRA 2021): never trained or validated on.
pub const TEST_FLIGHTS: [u32; 10] = [268, 269, 270, 271, 272, 273, 276, 277, 278, 279];

/// The flights that train and validate: every flight that is not a test flight
/// ([`TEST_FLIGHTS`]), not a ground test (routes `A*`: no GPS, motors in odd states), and
/// has at least one window whose target sample (`target_lag` before the newest) carries a
/// measured power. In the order of `flights`.
pub fn training_pool(flights: &[FlightWindows], target_lag: usize) -> Vec<u32> {
    flights
        .iter()
        .filter(|f| {
            !TEST_FLIGHTS.contains(&f.flight)
                && !f.route.starts_with('A')
                && f.windows
                    .iter()
                    .any(|w| w.back(target_lag).measured_w.is_some_and(f32::is_finite))
        })
        .map(|f| f.flight)
        .collect()
}

/// The number of folds `--cv K` gives over a pool of `n` flights: at least 2, at most `n`.
pub fn cv_k(k: usize, n: usize) -> usize {
    k.max(2).min(n)
}

/// K-fold by-flight cross-validation folds: `(flight, fold)` for every flight of `pool`,
/// sorted by flight, folds `0..k`.
///
/// The pool (in the order given, as [`training_pool`] returns it) is shuffled by a
/// [`rand::rngs::StdRng`] seeded `seed ^ 0x5eed`, and the flight at shuffled position `i`
/// goes to fold `i % k`, so fold sizes differ by at most one. `k` is taken through
/// [`cv_k`]. These are the folds `dronewatt-lab train --cv K --seed S` validates the LSTM on,
/// and the `fold` column `dronewatt-lab train --export-csv` writes for the LightGBM scripts:
/// both sides of the comparison hold out the same flights.
pub fn cv_folds(pool: &[u32], k: usize, seed: u64) -> Vec<(u32, usize)> {
    use rand::seq::SliceRandom;
    use rand::SeedableRng;
    let k = cv_k(k, pool.len());
    let mut shuffled = pool.to_vec();
    shuffled.shuffle(&mut rand::rngs::StdRng::seed_from_u64(seed ^ 0x5eed));
    let mut folds: Vec<(u32, usize)> = shuffled
        .into_iter()
        .enumerate()
        .map(|(i, f)| (f, i % k.max(1)))
        .collect();
    folds.sort_unstable();
    folds
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fold assignment `cross_validate` did inline before [`cv_folds`] (kept verbatim
    /// as the reference: the LSTM's CV figures were computed on these folds).
    fn legacy_folds(pool: &[u32], cv: usize, seed: u64) -> Vec<Vec<u32>> {
        use rand::seq::SliceRandom;
        use rand::SeedableRng;
        let k = cv.max(2).min(pool.len());
        let mut shuffled = pool.to_vec();
        shuffled.shuffle(&mut rand::rngs::StdRng::seed_from_u64(seed ^ 0x5eed));
        (0..k)
            .map(|fold| {
                let mut val: Vec<u32> = shuffled
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| i % k == fold)
                    .map(|(_, f)| *f)
                    .collect();
                val.sort_unstable();
                val
            })
            .collect()
    }

    fn grouped(folds: &[(u32, usize)]) -> Vec<Vec<u32>> {
        let k = folds.iter().map(|(_, k)| k + 1).max().unwrap_or(0);
        (0..k)
            .map(|fold| {
                folds
                    .iter()
                    .filter(|(_, g)| *g == fold)
                    .map(|(f, _)| *f)
                    .collect()
            })
            .collect()
    }

    #[test]
    fn cv_folds_match_the_legacy_assignment_and_cover_the_pool_once() {
        let pool: Vec<u32> = (1..=150).chain(160..=267).chain(280..=300).collect();
        for seed in [0, 7, 42] {
            for k in [0, 2, 3, 5, 10] {
                let folds = cv_folds(&pool, k, seed);
                assert_eq!(
                    grouped(&folds),
                    legacy_folds(&pool, k, seed),
                    "k {k} seed {seed}"
                );
                let mut flights: Vec<u32> = folds.iter().map(|(f, _)| *f).collect();
                flights.dedup();
                assert_eq!(flights, pool, "every flight exactly once, sorted");
                let sizes: Vec<usize> = grouped(&folds).iter().map(Vec::len).collect();
                assert_eq!(sizes.len(), cv_k(k, pool.len()));
                let (lo, hi) = (sizes.iter().min().unwrap(), sizes.iter().max().unwrap());
                assert!(hi - lo <= 1, "balanced: {sizes:?}");
            }
        }
        assert_ne!(
            cv_folds(&pool, 5, 7),
            cv_folds(&pool, 5, 8),
            "the seed matters"
        );
        assert_eq!(cv_folds(&[3, 1], 5, 7).len(), 2, "k clamped to the pool");
    }

    /// Pinned: the documented CV figures (LightGBM's `lgbm-cv.json`) were computed on these
    /// folds; a change here (a new `rand`, a new rule) changes which flights are held out.
    #[test]
    fn cv_folds_are_pinned() {
        let pool: Vec<u32> = (1..=12).collect();
        let got: Vec<usize> = cv_folds(&pool, 5, 7).iter().map(|(_, k)| *k).collect();
        assert_eq!(got, [1, 2, 0, 0, 0, 2, 3, 4, 1, 4, 3, 1]);
    }
}
