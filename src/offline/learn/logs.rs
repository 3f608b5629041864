//! The logs `learn` reads: the files and folders named, each decoded through the ingest
//! path into the windows the models see, split by what lifted the vehicle (rotors or wing).

use super::*;

/// The logs named: files as given, folders' `.tlog`, `.bin` and `.ulg` files in name order.
pub(super) fn collect_logs(args: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for p in args {
        if p.is_dir() {
            let mut v: Vec<PathBuf> = std::fs::read_dir(p)
                .with_context(|| format!("{}: cannot list", p.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|f| is_log(f))
                .collect();
            v.sort();
            if v.is_empty() {
                tracing::warn!(
                    "{}: no .tlog, .bin or .ulg file in this folder",
                    p.display()
                );
            }
            out.extend(v);
        } else if !p.exists() {
            bail!("{}: no such file", p.display());
        } else if is_log(p) {
            out.push(p.clone());
        } else {
            bail!(
                "{}: learn reads .tlog, ArduPilot DataFlash .bin and PX4 ULog .ulg logs",
                p.display()
            );
        }
    }
    dedup::refuse_duplicates(&out)?;
    Ok(out)
}

fn is_log(p: &Path) -> bool {
    p.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("tlog"))
        || crate::source::logs::dataflash::is_dataflash(p)
        || crate::source::logs::ulog::is_ulog(p)
}

/// One log through the live ingest path: its windows, numbered `flight`; only those flown
/// on rotors (a multirotor's, a VTOL's hover and transitions: what the multirotor fit
/// takes), the others left out with a warning. [`log_windows_by_lift`] keeps both.
pub fn log_windows(path: &Path, flight: u32, cfg: &Config) -> Result<FlightWindows> {
    Ok(log_windows_by_lift(path, flight, cfg)?.0)
}

/// One log through the live ingest path, its windows split by what carries the vehicle:
/// (on rotors: the multirotor models' and the LSTM's; on a wing: a plane's and a VTOL's
/// forward flight, the fixed-wing model's). A rover's or a boat's windows are in neither,
/// said once.
pub fn log_windows_by_lift(
    path: &Path,
    flight: u32,
    cfg: &Config,
) -> Result<(FlightWindows, FlightWindows)> {
    use crate::features::Lift;
    let stats = crate::report::status::IngestStats::default();
    let messages = if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("tlog"))
    {
        let bytes =
            std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
        crate::source::logs::tlog::decode_tlog(&bytes, &stats)
    } else {
        crate::source::logs::decode_autopilot_log(path, &stats)?
    };
    let class = crate::model::load_profile(cfg.vehicle.as_deref())?
        .vehicle
        .class;
    let mut tel = Telemetry::new(&cfg.telemetry, &cfg.mission).with_class(class);
    let mut windows = Vec::new();
    for m in messages {
        tel.push(&m, &mut windows);
    }
    tel.finish(&mut windows);
    let all = windows.len();
    let (rotor, rest): (Vec<_>, Vec<_>) = windows
        .into_iter()
        .partition(|w| w.last().vehicle.lift() == Lift::Rotor);
    let wing: Vec<_> = rest
        .into_iter()
        .filter(|w| w.last().vehicle.lift() == Lift::Wing)
        .collect();
    if rotor.len() < all {
        tracing::info!(
            "{}: {} of {all} windows flown on rotors (the multirotor fit), {} on a wing (the fixed-wing fit); the vehicle: {}",
            path.display(),
            rotor.len(),
            wing.len(),
            tel.vehicle_kind().describe()
        );
    }
    if rotor.len() + wing.len() < all {
        tracing::warn!(
            "{}: {} of {all} windows left out: no power model for this vehicle",
            path.display(),
            all - rotor.len() - wing.len()
        );
    }
    let fw = |windows| FlightWindows {
        flight,
        route: "log".into(),
        windows,
    };
    Ok((fw(rotor), fw(wing)))
}
