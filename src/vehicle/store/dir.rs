//! Where the store lives: the data-directory rule (`--data-dir`, `$DRONEWATT_HOME`, XDG).

use std::path::{Path, PathBuf};
use std::time::Duration;

/// The environment variable that overrides the data directory (`off`: no store).
pub const HOME_ENV: &str = "DRONEWATT_HOME";
/// The database's file name in the data directory.
pub const DB_FILE: &str = "dronewatt.sqlite";
/// Smallest fall of the autopilot's battery % that yields an effective capacity.
pub const MIN_PCT_DROP: f64 = 10.0;
/// How long a write waits for another run holding the database.
pub(crate) const BUSY_WAIT: Duration = Duration::from_secs(2);

/// The data directory: `flag` (`--data-dir`), else `home_env` (`$DRONEWATT_HOME`), else
/// `$XDG_DATA_HOME/dronewatt`, else `$HOME/.local/share/dronewatt`. `None`: the store is
/// off (`off` given, or no home directory at all). The environment is passed in, so the
/// rule is testable.
pub fn data_dir(
    flag: Option<&Path>,
    home_env: Option<&str>,
    xdg_data_home: Option<&str>,
    home: Option<&str>,
) -> Option<PathBuf> {
    let nonempty = |s: Option<&str>| s.filter(|s| !s.is_empty()).map(str::to_string);
    let chosen = flag
        .map(|p| p.to_string_lossy().into_owned())
        .filter(|s| !s.is_empty())
        .or_else(|| nonempty(home_env));
    if let Some(dir) = chosen {
        return (dir != "off").then(|| PathBuf::from(dir));
    }
    if let Some(x) = nonempty(xdg_data_home).filter(|x| Path::new(x).is_absolute()) {
        return Some(Path::new(&x).join("dronewatt"));
    }
    nonempty(home).map(|h| Path::new(&h).join(".local/share/dronewatt"))
}

/// [`data_dir`] from this process's environment.
pub fn data_dir_from_env(flag: Option<&Path>) -> Option<PathBuf> {
    let var = |k: &str| std::env::var(k).ok();
    data_dir(
        flag,
        var(HOME_ENV).as_deref(),
        var("XDG_DATA_HOME").as_deref(),
        var("HOME").as_deref(),
    )
}
