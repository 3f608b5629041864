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
use crate::source::fleet::VehicleFilter;
use crate::source::SourceSpec;

/// The files the configuration names, read once at start (a file that does not read or
/// parse fails the start, naming it): every chain is built from these values, and no stage
/// reads a file again.
#[derive(Debug, Clone)]
pub struct Resolved {
    /// The vehicle profile (`vehicle`), else the built-in M100.
    pub vehicle: LoadedProfile,
    /// `[forecast.live] calibrated_profile`, when set and the live forecast is enabled.
    pub calibrated: Option<Arc<VehicleProfile>>,
}

impl Resolved {
    /// Read what `cfg` names.
    pub fn load(cfg: &Config) -> Result<Self> {
        let vehicle = LoadedProfile::load(cfg.vehicle.as_deref())?;
        let calibrated = match &cfg.forecast.live.calibrated_profile {
            Some(p) if cfg.forecast.live.enabled => Some(Arc::new(VehicleProfile::load(p)?)),
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
            forecast: cfg.forecast.clone(),
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
