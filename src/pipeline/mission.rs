//! What a run reads once at start and hands every chain (the loaded profiles), and each
//! vehicle's live mission forecast: built from those values, run as a step of the vehicle's
//! chain ([`crate::mission::live::MissionStep`]), its statuses taken by the energy stage.

use std::sync::Arc;

use anyhow::Result;
use tokio::sync::mpsc;

use crate::config::Config;
use crate::energy::EnergyTracker;
use crate::mission::live::LiveSetup;
use crate::model::profile::VehicleProfile;
use crate::model::LoadedProfile;
use crate::report::MissionUpdate;
use crate::source::messages::fleet::VehicleFilter;
use crate::source::SourceSpec;

/// The files the configuration names, read once at start (a file that does not read or
/// parse fails the start, naming it): every chain is built from these values, and no stage
/// reads a file again.
#[derive(Debug, Clone)]
pub struct Resolved {
    /// The vehicle profile (`vehicle`), else the built-in M100.
    pub vehicle: LoadedProfile,
    /// `[forecast.live] calibrated_profile` when the live forecast is enabled; unset, the
    /// M100's compiled-in calibrated profile when the vehicle is the M100 (its forecast's
    /// members are that profile's `<model>_cal` models), else none.
    pub calibrated: Option<Arc<VehicleProfile>>,
}

impl Resolved {
    /// Read what `cfg` names.
    pub fn load(cfg: &Config) -> Result<Self> {
        let vehicle = LoadedProfile::load(cfg.vehicle.as_deref())?;
        let live = &cfg.forecast.live;
        let calibrated = match &live.calibrated_profile {
            Some(p) if live.enabled => Some(Arc::new(VehicleProfile::load(p)?)),
            None if live.enabled && vehicle.profile.name == VehicleProfile::m100().name => {
                Some(Arc::new(crate::model::profile::m100_calibrated()?))
            }
            _ => None,
        };
        Ok(Self {
            vehicle,
            calibrated,
        })
    }
}

/// How each vehicle's chain forecasts its mission, when the source can carry a mission (a
/// live link, a `.tlog` or raw log; not the data set) and `[forecast.live] enabled`.
#[derive(Debug, Clone)]
pub(super) struct MissionOn {
    /// Download over the link (a live link); else only overhear (a replay).
    active: bool,
    /// The vehicles followed (`[fleet] vehicles` / `--vehicles`).
    follows: VehicleFilter,
}

impl MissionOn {
    /// None when there is no mission to follow.
    pub(super) fn of(cfg: &Config, source: &SourceSpec, follows: &VehicleFilter) -> Option<Self> {
        if !cfg.forecast.live.enabled || matches!(source, SourceSpec::Dataset { .. }) {
            return None;
        }
        Some(Self {
            active: source.is_live(),
            follows: follows.clone(),
        })
    }

    /// One vehicle's forecast: its own power models, built from the loaded profiles.
    pub(super) fn setup(&self, cfg: &Config, resolved: &Resolved) -> Result<LiveSetup> {
        let vehicle = &resolved.vehicle.profile;
        let mut models = crate::model::physics::models(vehicle);
        // a plane's and a VTOL's wing-borne samples (only run where the class asks for it)
        let wing = vehicle.fixed_wing.unwrap_or_default();
        wing.validate().map_err(anyhow::Error::msg)?;
        models.push(Box::new(crate::model::physics::fixed_wing::FixedWing::new(
            wing,
        )));
        if let Some(p) = &resolved.calibrated {
            models.extend(crate::model::physics::models(p));
        }
        Ok(LiveSetup {
            forecast: own_forecast(cfg, vehicle, &models),
            models,
            rate_hz: cfg.telemetry.rate_hz,
            window: cfg.telemetry.window,
            payload_g: cfg.mission.payload_g.map_or(0.0, f64::from),
            speed_m_s: cfg.mission.speed_m_s.map(f64::from),
            active: self.active,
            // Requests go out as the configured id, else as the vehicle's companion computer.
            system_id: cfg.sinks.mavlink.system_id,
            component_id: cfg.sinks.mavlink.component_id,
            follows: self.follows.clone(),
            class: vehicle.vehicle.class,
            flight: vehicle.fixed_wing_flight.unwrap_or_default(),
        })
    }
}

/// The mission statuses due by source time `t_s` into the energy tracker (the latest one
/// wins): the mission step runs ahead of the estimates, so each status waits for its time.
pub(super) fn take_mission(
    energy: &mut EnergyTracker,
    rx: &mut Option<mpsc::Receiver<MissionUpdate>>,
    next: &mut Option<MissionUpdate>,
    t_s: f64,
) {
    let Some(rx) = rx else { return };
    loop {
        if next.is_none() {
            *next = rx.try_recv().ok();
        }
        match next.take() {
            Some(m) if m.t_s <= t_s => energy.set_mission(m.status),
            other => {
                *next = other;
                return;
            }
        }
    }
}

/// The mission forecast's configuration: the configured one, except for a vehicle whose
/// forecast is the momentum-theory member (a spec sheet) when none of the configured
/// calibration's members runs for it (the M100's `_cal` members without a calibrated
/// profile): then that member, uncorrected, with the profile's P90 (what `plan` forecasts
/// it with), so that its first hover's calibration ([`crate::energy::hover`]) rescales the
/// forecast it made. Otherwise the first model would be followed uncorrected.
fn own_forecast(
    cfg: &Config,
    vehicle: &VehicleProfile,
    models: &[Box<dyn crate::model::PowerModel>],
) -> crate::mission::ForecastConfig {
    let mut forecast = cfg.forecast.clone();
    let runs = |n: &str| models.iter().any(|m| m.name() == n);
    let fd = vehicle
        .forecast
        .as_ref()
        .filter(|f| crate::energy::hover::follows_momentum_theory(vehicle) && runs(&f.model));
    if let Some(fd) = fd {
        // its plans flown at its own tilt, as `plan` flies them
        forecast.kinematics = forecast
            .kinematics
            .tilted_as(vehicle, cfg.mission.payload_g.map_or(0.0, f64::from));
        if !forecast.calibration.members.iter().any(|m| runs(&m.model)) {
            forecast.calibration = crate::mission::forecast::Calibration {
                p90_ratio: fd.p90_ratio.unwrap_or(forecast.calibration.p90_ratio),
                ..crate::mission::forecast::Calibration::uncorrected(&fd.model)
            };
        }
    }
    forecast
}
