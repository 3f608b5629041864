//! The first hover's calibration kept in the vehicle store: the run's vehicle profile with
//! the hover efficiency its first hover measured ([`crate::model::spec::calibrate_hover`])
//! is written beside the database (`profiles/<key>-hover.toml`) and kept as the vehicle's
//! profile, so `plan --vehicle <key>` forecasts with it and the next run of the vehicle
//! (with no profile configured) starts from it. A profile `dronewatt learn` wrote for the
//! vehicle is never replaced by it (learning from whole flights beats one hover).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use super::{Store, VehicleKey};
use crate::model::profile::VehicleProfile;
use crate::report::hover::HoverCalibration;
use crate::vehicle::params::Identity;

/// Suffix of the profiles this module writes.
pub const HOVER_SUFFIX: &str = "-hover.toml";

/// Where the hover profile of vehicle `key` goes under the store's folder `dir`.
pub fn hover_profile_path(dir: &Path, key: &str) -> PathBuf {
    let safe: String = key
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    dir.join("profiles").join(format!("{safe}{HOVER_SUFFIX}"))
}

/// Keep the calibration as the vehicle's profile; what was done, or why not. An error: the
/// store or the file could not be written.
pub fn keep_hover(
    dir: &Path,
    id: &Identity,
    profile: &VehicleProfile,
    cal: &HoverCalibration,
) -> Result<String> {
    if !cal.applied {
        return Ok("the forecast does not follow the momentum-theory member: the hover is not kept as a profile".into());
    }
    let key = VehicleKey::of(id);
    let mut store = Store::open(dir)?;
    if let Some(p) = store.learned_profile(&key.key)? {
        let ours = p.path.to_string_lossy().ends_with(HOVER_SUFFIX);
        if !ours {
            return Ok(format!(
                "the profile `learn` kept ({}) stays the vehicle's; the hover is not kept over it",
                p.path.display()
            ));
        }
    }
    let calibrated =
        crate::model::spec::calibrate_hover(profile.clone(), cal.hover_w, cal.payload_kg)
            .map_err(anyhow::Error::msg)?;
    let path = hover_profile_path(store.path().parent().unwrap_or(dir), &key.key);
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("vehicle store: creating {}", parent.display()))?;
    }
    let text = toml::to_string(&calibrated).context("vehicle store: the calibrated profile")?;
    std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    let model = calibrated.forecast.as_ref().map(|f| f.model.clone());
    store.record_profile(id, &path, model.as_deref())?;
    Ok(format!(
        "the first hover's η_h {:.3} ({:.0} W) kept as its profile {}: `plan --vehicle {}` uses it",
        cal.eta_h,
        cal.hover_w,
        path.display(),
        key.key
    ))
}

/// At the end of a run: keep a first hover's calibration ([`keep_hover`]); any problem is a
/// warning (the run's results stand without it).
pub fn remember_hover(
    dir: &Path,
    id: Option<&Identity>,
    profile: &VehicleProfile,
    cal: Option<&HoverCalibration>,
) {
    let (Some(id), Some(cal)) = (id, cal) else {
        return;
    };
    match keep_hover(dir, id, profile, cal) {
        Ok(what) => tracing::info!("vehicle {}: {what}", VehicleKey::of(id).key),
        Err(e) => tracing::warn!("vehicle store: {e:#}; the first hover's calibration is not kept"),
    }
}
