//! The TOML configuration. These serde types *are* its reference: every field's doc
//! comment says what it means, its unit and its default. Unknown keys are errors.
//!
//! Errors name the file, the key and why (`Config::load`).

use std::path::{Path, PathBuf};

use serde::Deserialize;

/// The whole configuration file (`config/dronewatt.toml` is a commented example).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Config {
    /// Vehicle profile: a path to a `config/vehicles/*.toml` file (relative paths are
    /// resolved against the config file's folder). Default: the built-in M100 profile.
    pub vehicle: Option<PathBuf>,
    /// Mission facts the telemetry cannot tell: commanded speed, payload, altitude.
    pub mission: crate::telemetry::MissionConfig,
    /// Resampling rate, window length, staleness.
    pub telemetry: crate::telemetry::TelemetryConfig,
    /// Which models run.
    pub models: crate::model::ModelsConfig,
    /// Battery capacity, reserve, home-return assumptions.
    pub energy: crate::energy::EnergyConfig,
    /// Mission energy forecast: kinematics of flying a plan, the forecast's correction.
    pub forecast: crate::mission::ForecastConfig,
    /// Alert rules, `[[alerts]]` tables.
    pub alerts: Vec<crate::alert::AlertRule>,
    /// Publishers: terminal, jsonl, mavlink, web, mqtt.
    pub sinks: crate::sink::SinksConfig,
    /// The live link: MAVLink 2 signing key file, whether unsigned frames are refused.
    pub link: crate::source::links::LinkConfig,
    /// Many vehicles on one link: when a silent vehicle is lost and dropped, which system
    /// ids this instance watches.
    pub fleet: crate::source::messages::fleet::FleetConfig,
    /// The links `monitor` reads when no address is given on its command line, `[[links]]`
    /// tables: several are merged, deduplicated, and watched per link (`source::links`).
    pub links: Vec<LinkEntry>,
}

/// One `[[links]]` table.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinkEntry {
    /// A link address, as on `monitor`'s command line (`udpin:0.0.0.0:14550`,
    /// `serial:/dev/ttyUSB0:57600`, …).
    pub address: String,
    /// The network the link belongs to. Links with the same name (by default all of them:
    /// one vehicle over redundant radios, a fleet over several) are one network, merged and
    /// deduplicated, a vehicle being its system id. Links with different names are separate
    /// networks (two fleets that may both use system id 1): a vehicle is then its network
    /// and system id, shown `N:SYSID` (networks numbered from 1 in the order first named
    /// here), and what dronewatt sends it goes on its own network's links only. Default `""`.
    #[serde(default)]
    pub network: String,
}

/// A configuration error that names the file, the key and why.
#[derive(Debug, thiserror::Error)]
#[error("{file}: {message}")]
pub struct ConfigError {
    pub file: PathBuf,
    pub message: String,
}

impl Config {
    /// Read and validate a configuration file.
    pub fn load(path: &Path) -> Result<Config, ConfigError> {
        let err = |message: String| ConfigError {
            file: path.to_path_buf(),
            message,
        };
        let text = std::fs::read_to_string(path).map_err(|e| err(format!("cannot read: {e}")))?;
        let mut cfg: Config =
            toml::from_str(&text).map_err(|e| err(e.to_string().trim_end().to_string()))?;
        // Every path the file names, against the file's folder (one resolver: a key added
        // here and nowhere else resolves like the rest).
        for field in [
            cfg.vehicle.as_mut(),
            cfg.models.lstm.path.as_mut(),
            cfg.forecast.live.calibrated_profile.as_mut(),
            cfg.sinks.web.token_file.as_mut(),
            cfg.sinks.mqtt.password_file.as_mut(),
            cfg.sinks.mqtt.ca_file.as_mut(),
            cfg.link.signing_key_file.as_mut(),
        ] {
            crate::files::resolve(path, field);
        }
        cfg.validate().map_err(err)?;
        Ok(cfg.with_default_alerts())
    }

    /// With no `[[alerts]]`, the pilot's default rules ([`crate::alert::defaults`]).
    pub fn with_default_alerts(mut self) -> Self {
        if self.alerts.is_empty() {
            self.alerts = crate::alert::defaults::rules(self.energy.reserve_pct);
        }
        self
    }

    /// Whether the alert rules are the defaults (the config names none).
    pub fn default_alerts(&self) -> bool {
        self.alerts == crate::alert::defaults::rules(self.energy.reserve_pct)
    }

    /// [`Config::load`] when a file is given (`--config FILE`), else the built-in defaults.
    pub fn load_or_default(path: Option<&Path>) -> Result<Config, ConfigError> {
        path.map_or_else(|| Ok(Config::default().with_default_alerts()), Config::load)
    }

    /// Checks serde cannot express (ranges, cross-field rules): every error in the file,
    /// not just the first, so one edit can fix them all. One error is its own message;
    /// several read `N errors:` and one per line. Each names its key.
    pub fn validate(&self) -> Result<(), String> {
        match self.errors().as_slice() {
            [] => Ok(()),
            [one] => Err(one.clone()),
            many => Err(format!("{} errors:\n  {}", many.len(), many.join("\n  "))),
        }
    }

    fn links_valid(&self) -> Result<(), String> {
        let errs: Vec<String> = self
            .links
            .iter()
            .enumerate()
            .filter_map(|(i, l)| {
                l.address
                    .parse::<crate::source::links::address::LinkAddress>()
                    .err()
                    .map(|e| format!("links[{i}].address: {e}"))
            })
            .collect();
        if errs.is_empty() {
            Ok(())
        } else {
            Err(errs.join("\n"))
        }
    }

    /// Every validation error, one message per broken key, in file order of the sections.
    pub fn errors(&self) -> Vec<String> {
        let mut out = Vec::new();
        let checks = [
            self.telemetry.validate(),
            self.models.validate(),
            self.energy.validate(),
            self.forecast.validate(),
            crate::alert::validate_rules(&self.alerts),
            self.sinks.mavlink.validate(),
            self.sinks.web.validate(),
            self.sinks.mqtt.validate(),
            self.link.validate(),
            self.fleet.validate(),
            self.links_valid(),
        ];
        for e in checks.into_iter().filter_map(Result::err) {
            out.extend(e.lines().map(str::to_string));
        }
        out
    }
}
