//! Alert rules from TOML: typed kinds, debounce, hysteresis, repeat. Owner: energy (issue 6).

/// An alert raised or cleared.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct AlertEvent {
    pub t: f64,
    pub rule: String,
    pub severity: String,
    pub state: AlertState,
    pub message: String,
}

/// Whether an alert began or ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum AlertState {
    Raised,
    Cleared,
}

/// One `[[alerts]]` rule.
#[derive(Debug, Clone, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AlertRule {
    /// Rule name, unique; shown in every alert it raises.
    pub name: String,
}

/// Evaluates every rule on every report.
pub struct AlertEngine {}

impl AlertEngine {
    /// Check and compile the rules.
    pub fn new(rules: &[AlertRule]) -> anyhow::Result<Self> {
        let _ = rules;
        Ok(Self {})
    }
    /// Events raised or cleared by this estimate.
    pub fn evaluate(&mut self, est: &crate::model::Estimate, energy: &crate::energy::EnergyState) -> Vec<AlertEvent> {
        let _ = (est, energy);
        Vec::new()
    }
}
