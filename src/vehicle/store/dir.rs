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
/// `dronewatt` in `platform`, the platform's data directory (on Linux, the XDG rule:
/// `$XDG_DATA_HOME` when it is absolute, else `~/.local/share`). `None`: the store is off
/// (`off` given, or no data directory at all). The environment is passed in, so the rule
/// is testable.
pub fn data_dir(
    flag: Option<&Path>,
    home_env: Option<&str>,
    platform: Option<PathBuf>,
) -> Option<PathBuf> {
    let chosen = flag
        .map(|p| p.to_string_lossy().into_owned())
        .filter(|s| !s.is_empty())
        .or_else(|| home_env.filter(|s| !s.is_empty()).map(str::to_string));
    if let Some(dir) = chosen {
        return (dir != "off").then(|| PathBuf::from(dir));
    }
    platform.map(|d| d.join("dronewatt"))
}

/// [`data_dir`] from this process's environment; the platform's data directory from the
/// `dirs` crate (XDG on Linux, `~/Library/Application Support` on macOS, `%APPDATA%` on
/// Windows).
pub fn data_dir_from_env(flag: Option<&Path>) -> Option<PathBuf> {
    data_dir(
        flag,
        std::env::var(HOME_ENV).ok().as_deref(),
        dirs::data_dir(),
    )
}
