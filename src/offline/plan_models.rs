//! The models a plan is forecast with (the M100's calibrated ones, a vehicle's own learned
//! forecast model, else its published physics models), the forecast's header, and the forecast
//! along the flown trajectory.

use std::path::Path;

use super::{models_for, PlanArgs, OWN_MODEL_P90, PUBLISHED, UNCALIBRATED_P90};
use crate::config::Config;
use crate::features::VehicleClass;
use crate::mission::forecast::{forecast, MissionForecast};
use crate::mission::trajectory::Trajectory;
use crate::model::profile::VehicleProfile;
use crate::model::PowerModel;

/// The models that fly the plan, their calibration, and the forecast's header.
pub(super) type PlanModels = (
    Vec<Box<dyn PowerModel>>,
    crate::mission::forecast::Calibration,
    String,
);

/// The models, the calibration and the forecast's header: the M100 with its calibrated
/// models and fitted correction; another vehicle with its learned forecast model, else the
/// mean of its own physics models uncorrected, the P90 widened (the M100's correction is
/// not its).
pub(super) fn forecast_models(
    a: &PlanArgs,
    cfg: &Config,
    profile: &VehicleProfile,
    profile_path: Option<&Path>,
    class: VehicleClass,
    is_m100: bool,
) -> anyhow::Result<PlanModels> {
    if is_m100 {
        return Ok((
            models_for(cfg, &a.forecast.calibrated)?,
            cfg.forecast.calibration.clone(),
            "the M100's calibrated models and fitted correction".to_string(),
        ));
    }
    // a measured hover changed the profile in memory: its physics models, not the file's
    let mut models = match profile_path.filter(|_| a.hover_w.is_none()) {
        Some(p) => crate::model::build_models(&cfg.models, Some(p), &cfg.telemetry)?,
        None => crate::model::physics::models(profile),
    };
    let wing = !matches!(class, VehicleClass::Multirotor | VehicleClass::Other);
    if wing {
        let params = profile.fixed_wing.unwrap_or_default();
        params.validate().map_err(anyhow::Error::msg)?;
        models.push(Box::new(crate::model::physics::fixed_wing::FixedWing::new(
            params,
        )));
    }
    Ok(
        match profile
            .forecast
            .as_ref()
            .filter(|f| models.iter().any(|m| m.name() == f.model))
        {
            Some(fd) => {
                let (c, header) = own_forecast(fd, &models, wing, &profile.name)?;
                (models, c, header)
            }
            None => {
                // a plane: the fixed-wing model alone; a VTOL: the rotor models on its
                // rotor-borne samples, the fixed-wing model on the rest
                let applies = |n: &String| {
                    (class != VehicleClass::FixedWing && PUBLISHED.contains(&n.as_str()))
                        || (wing && n == "fixed_wing")
                };
                let (names, left): (Vec<String>, Vec<String>) = models
                    .iter()
                    .map(|m| m.name().to_string())
                    .filter(applies)
                    .partition(|n| !profile.does_not_transfer.contains(n));
                if names.is_empty() {
                    anyhow::bail!("{}: every model that applies to it is in its profile's does_not_transfer: nothing left to forecast with", profile.name);
                }
                let left = if left.is_empty() {
                    String::new()
                } else {
                    tracing::warn!(
                    "{}: {} left out of the forecast: the vehicle's profile says they do not transfer to it",
                    profile.name,
                    left.join(", ")
                );
                    format!(
                        "; left out, as its profile says they do not transfer: {}",
                        left.join(", ")
                    )
                };
                tracing::warn!(
                "only the M100's forecast calibration exists; {} ({class}) flies on its own published models, uncorrected, with the P90 widened to {UNCALIBRATED_P90} × P50",
                profile.name
            );
                let c = crate::mission::forecast::Calibration {
                    members: names
                        .iter()
                        .map(|n| crate::mission::forecast::Member::of(n))
                        .collect(),
                    p90_ratio: UNCALIBRATED_P90,
                    live_weight: 0.0,
                    vehicle_kg: profile.vehicle.airframe_kg + profile.vehicle.battery_kg,
                };
                (models, c, format!("the mean of {}'s published models that apply ({class}: {}) (uncorrected: only the M100 is calibrated; P90 = {UNCALIBRATED_P90} × P50){left}", profile.name, names.join(", ")))
            }
        },
    )
}

/// A vehicle's own learned forecast model: it, the others its profile scales (a VTOL's
/// rotor model) and the fixed-wing model on the wing, each with its fitted scale; the
/// calibration and the forecast's header.
fn own_forecast(
    fd: &crate::model::profile::ForecastDefault,
    models: &[Box<dyn PowerModel>],
    wing: bool,
    vehicle: &str,
) -> anyhow::Result<(crate::mission::forecast::Calibration, String)> {
    // its own forecast model, the others its profile scales (a VTOL's rotor
    // model) and the fixed-wing model on the wing, each with its fitted scale
    let mut names = vec![fd.model.clone()];
    let wing_model = wing.then(|| "fixed_wing".to_string());
    for n in fd.scale.keys().chain(wing_model.iter()) {
        if !names.contains(n) && models.iter().any(|m| m.name() == n) {
            names.push(n.clone());
        }
    }
    let p90 = fd.p90_ratio.unwrap_or(OWN_MODEL_P90);
    let members: Vec<_> = names
        .iter()
        .map(|n| crate::mission::forecast::Member {
            scale: fd.scale.get(n).copied().unwrap_or(1.0),
            ..crate::mission::forecast::Member::of(n)
        })
        .collect();
    let how = members
        .iter()
        .map(|m| format!("{} × {}", m.model, m.scale))
        .collect::<Vec<_>>()
        .join(", ");
    let c = crate::mission::forecast::Calibration {
        members,
        p90_ratio: p90,
        ..crate::mission::forecast::Calibration::uncorrected(&fd.model)
    };
    c.validate().map_err(anyhow::Error::msg)?;
    Ok((
        c,
        format!(
            "{}'s forecast model{} {how} (P90 = {p90} × P50){}",
            vehicle,
            if names.len() > 1 { "s" } else { "" },
            if fd.why.is_empty() {
                String::new()
            } else {
                format!(": {}", fd.why)
            }
        ),
    ))
}

/// The vehicle that flies the plan, as [`plan_forecast`] needs it.
pub(super) struct PlanVehicle<'a> {
    pub profile: &'a VehicleProfile,
    pub profile_path: Option<&'a Path>,
    pub class: VehicleClass,
    pub is_m100: bool,
}

/// The plan's forecast along the flown trajectory, and what it was forecast from (said
/// as what ran when the calibration's models did not all run).
pub(super) fn plan_forecast(
    a: &PlanArgs,
    cfg: &Config,
    v: &PlanVehicle,
    tr: &Trajectory,
) -> anyhow::Result<(MissionForecast, String)> {
    let (mut models, calibration, mut forecast_from) =
        forecast_models(a, cfg, v.profile, v.profile_path, v.class, v.is_m100)?;
    let f = forecast(
        tr,
        &mut models,
        &calibration,
        cfg.telemetry.window,
        crate::mission::MODEL_STRIDE,
    );
    let wanted = calibration.name();
    if f.model != wanted {
        tracing::warn!(
            "forecast models {wanted:?} did not all run; the P50 follows {:?}",
            f.model
        );
        // the header says what ran, never the calibration that did not
        forecast_from = format!(
            "{:?} (the forecast's models {wanted:?} did not all run)",
            f.model
        );
    }
    Ok((f, forecast_from))
}
