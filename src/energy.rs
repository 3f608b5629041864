//! Energy used, remaining energy and time, energy to get home. Owner: energy (issue 6).

use crate::model::Estimate;

/// Energy bookkeeping at one estimate.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct EnergyState {
    /// Energy drawn so far, Wh.
    pub energy_used_wh: f64,
    /// Remaining usable energy, Wh, when known.
    pub remaining_wh: Option<f64>,
    /// Time to empty at the forecast power, s.
    pub time_to_empty_s: Option<f64>,
    /// Remaining minus energy to get home minus reserve, Wh.
    pub home_margin_wh: Option<f64>,
}

/// What the energy + alerts stage sends to every sink.
#[derive(Debug, Clone)]
pub struct Report {
    pub estimate: Estimate,
    pub energy: EnergyState,
    pub alerts: Vec<crate::alert::AlertEvent>,
}

/// Battery and home-return assumptions (the `[energy]` table).
#[derive(Debug, Clone, Default, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EnergyConfig {}

/// Integrates power into energy and forecasts what is left.
pub struct EnergyTracker {}

impl EnergyTracker {
    /// A tracker for this configuration's battery and reserve.
    pub fn new(cfg: &crate::config::Config) -> anyhow::Result<Self> {
        let _ = cfg;
        Ok(Self {})
    }
    /// Account for one estimate.
    pub fn update(&mut self, est: &Estimate) -> EnergyState {
        let _ = est;
        EnergyState::default()
    }
}
