//! The flags several offline commands share, said once: each command's arguments take them
//! in with `#[command(flatten)]` where the flag stands in its `--help`. A command whose flag
//! means a little more says so by overriding the help text
//! (`#[command(mut_arg("config", help("…")))]`), not by declaring the flag again.

use std::path::PathBuf;

use anyhow::Context;

use crate::config::{Config, ConfigError};

/// For `#[command(mut_arg(ID, help(TEXT)))]`: a command's own help text for a shared flag.
pub fn help(text: &'static str) -> impl FnOnce(clap::Arg) -> clap::Arg {
    move |a| a.help(text)
}

// The structs carry no doc comment: clap would take it for the command's `about`.

// `--config FILE`, `-c FILE`: the configuration (every command that reads one; each says
// which of its tables it reads).
#[derive(Debug, Clone, clap::Args)]
pub struct ConfigArg {
    /// Configuration file (TOML). Without one, the built-in defaults.
    #[arg(id = "config", long = "config", short = 'c', value_name = "FILE")]
    pub path: Option<PathBuf>,
}

impl ConfigArg {
    /// The configuration: the file's, else the built-in defaults.
    pub fn load(&self) -> Result<Config, ConfigError> {
        Config::load_or_default(self.path.as_deref())
    }
}

// `--data FILE`: the M100 data set (`eval`, `calibrate`, `train`, `sensitivity`, `plan-eval`,
// `battery-eval`).
#[derive(Debug, Clone, clap::Args)]
pub struct DataArg {
    /// The data set (`flights.csv` or `.csv.gz`). Default: `DRONEWATT_DATA` or `../shared/data/m100/flights.csv.gz`.
    #[arg(id = "data", long = "data", value_name = "FILE")]
    pub file: Option<PathBuf>,
}

impl DataArg {
    /// The data set's path: `--data`, else [`crate::default_data_path`].
    pub fn path(&self) -> PathBuf {
        self.file.clone().unwrap_or_else(crate::default_data_path)
    }
}

// `--json PATH|-`: the command's report as one JSON object (`eval`, `plan`, `plan-eval`,
// `battery-eval`).
#[derive(Debug, Clone, clap::Args)]
pub struct JsonArg {
    /// Print one JSON object to PATH, or to standard output with '-' (then no table).
    #[arg(id = "json", long = "json", value_name = "PATH|-")]
    pub to: Option<String>,
}

impl JsonArg {
    /// `--json -`: the JSON on standard output instead of the table; `--json PATH`: the table,
    /// and the JSON written to PATH; no `--json`: the table alone.
    pub fn publish(
        &self,
        report: &impl serde::Serialize,
        table: impl FnOnce() -> String,
    ) -> anyhow::Result<()> {
        match self.to.as_deref() {
            Some("-") => println!("{}", serde_json::to_string_pretty(report)?),
            other => {
                print!("{}", table());
                if let Some(p) = other {
                    std::fs::write(p, serde_json::to_string_pretty(report)?)
                        .with_context(|| format!("{p}: cannot write"))?;
                }
            }
        }
        Ok(())
    }
}

// `--calibrated FILE`: the profile `dronewatt-lab calibrate` writes, whose physics models run as
// `<model>_cal` (`eval`, `plan`, `plan-eval`, `battery-eval`). Without it, the M100's,
// compiled in ([`crate::assets`]): the same figures from any directory.
#[derive(Debug, Clone, clap::Args)]
pub struct CalibratedArg {
    /// Calibrated vehicle profile for the `<model>_cal` physics models. Default: the M100's,
    /// compiled in (`config/vehicles/m100-calibrated.toml` as built).
    #[arg(id = "calibrated", long = "calibrated", value_name = "FILE")]
    pub path: Option<PathBuf>,
}

impl CalibratedArg {
    /// The profile: the file given (an error when it does not read), else the M100's.
    pub fn profile(&self) -> anyhow::Result<crate::model::profile::VehicleProfile> {
        crate::model::profile::calibrated_profile(self.path.as_deref())
    }

    /// Where the profile came from, for messages.
    pub fn describe(&self) -> String {
        match &self.path {
            Some(p) => p.display().to_string(),
            None => "the built-in m100-calibrated".to_string(),
        }
    }
}

// What `plan` and `plan-eval` share, in this order: the configuration and the calibrated
// profile the forecast's models come from, and the JSON report.
#[derive(Debug, Clone, clap::Args)]
pub struct ForecastArgs {
    #[command(flatten)]
    pub config: ConfigArg,
    #[command(flatten)]
    pub calibrated: CalibratedArg,
    #[command(flatten)]
    pub json: JsonArg,
}
