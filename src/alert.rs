//! Alert rules from TOML: typed kinds, debounce, hysteresis, repeat.
//!
//! ```toml
//! [[alerts]]
//! name = "low_energy"          # unique, shown in every alert it raises
//! kind = "remaining_below"     # what it watches (table below)
//! below_pct = 25               # raise under 25 % …
//! clear_pct = 27               # … clear only back above 27 % (hysteresis)
//! severity = "warning"         # a MAV_SEVERITY name: emergency … debug
//! for_s = 2                    # the condition must hold this long before it raises
//! repeat_s = 60                # say it again every 60 s while raised (0: once)
//! message = "Battery low"      # optional; default names the rule and the value
//! ```
//!
//! | `kind` | level key (unit) | clear key | watches |
//! |---|---|---|---|
//! | `remaining_below` | `below_wh` or `below_pct` | `clear_wh` / `clear_pct` | remaining energy |
//! | `time_to_empty_below` | `below_s` | `clear_s` | time to empty at the forecast power |
//! | `home_margin_below` | `below_wh` | `clear_wh` | remaining − energy home − reserve |
//! | `mission_margin_below` | `below_wh` | `clear_wh` | remaining − energy of the rest of the mission, its return and landing − reserve (needs a mission: downloaded on the live link or logged in a replayed `.tlog`) |
//! | `power_above` | `above_w` | `clear_w` | measured power |
//! | `deviation_above` | `above_w`, optional `model` | `clear_w` | \|measured − predicted\| (a damaged propeller, a heavy payload); predicted by the model's slowly adapting reference when adaptation runs |
//! | `models_disagree` | `above_w` | `clear_w` | spread (max − min) of the models' predictions |
//! | `cell_voltage_below` | `below_v` | `clear_v` | battery voltage / cells (`[energy] cell_count`, else the vehicle's) |
//! | `vehicle_voltage_below` | `threshold` (`low`, `critical`), optional `margin_v` (default 0) | `clear_margin_v` | battery voltage − the autopilot's own threshold (`BATT_LOW_VOLT`/`BATT_CRT_VOLT`, PX4 `BAT1_V_EMPTY` × cells); quiet while the vehicle has not said |
//! | `voltage_forecast_below` | optional `below_v` (default: the low threshold, the vehicle's `BATT_LOW_VOLT` else 3.5 V a cell), optional `margin_v` (default 0) | `clear_margin_v` | the lowest loaded voltage forecast for the rest of the flight (the mission's, else until the reserve) − that threshold: "the final climb sags under BATT_LOW_VOLT" before it does |
//! | `low_voltage_before_home` | optional `below_s` (default 0) | `clear_s` | time to the low voltage (the pack's forecast) − time home (energy home / forecast power): "the pack sags under BATT_LOW_VOLT before it is home" |
//! | `telemetry_lost` | — (`for_s` is the time) | — | every kinematic feature stale |
//!
//! With no `[[alerts]]` in the config (or no config), the pilot's rules ([`defaults`])
//! run: `check-config` and `monitor --help` show them; a config's `[[alerts]]` replace them
//! all (copy the ones to keep).
//!
//! A clear level defaults to the raise level (no hysteresis) and must lie on the safe side
//! of it. A value that is unknown (no measured power, no home yet) neither raises nor
//! clears: the rule keeps its state. Time is the estimates' own clock, so a replay at ×10
//! debounces exactly like the live flight did.

// A file beside this one, not under `alert/` (the lint wants no self-named module folders).
#[path = "alert_defaults.rs"]
pub mod defaults;
#[path = "alert_rules.rs"]
mod rules;

use rules::*;
pub use rules::{validate_rules, AlertKind, AlertRule, VehicleThreshold};

use crate::report::{AlertEvent, AlertState};

use crate::report::{EnergyState, Estimate};

/// Bitmask of the kinematic features (position, attitude, velocity, rates, acceleration):
/// all of them stale means the vehicle's telemetry is gone, whatever wind does.
const KINEMATIC_MASK: u32 = {
    let mut m = 0u32;
    let mut i = crate::features::idx::POS_X;
    while i <= crate::features::idx::AZ {
        m |= 1 << i;
        i += 1;
    }
    m
};

/// The rule's value at one estimate, in its level's unit; None when unknown.
fn value(rule: &AlertRule, est: &Estimate, en: &EnergyState) -> Option<f64> {
    use AlertKind as K;
    let measured = est
        .sample
        .measured_w
        .map(f64::from)
        .filter(|v| v.is_finite());
    match &rule.kind {
        K::RemainingBelow {
            below_wh: Some(_), ..
        } => en.remaining_wh,
        K::RemainingBelow { .. } => en.remaining_pct,
        K::TimeToEmptyBelow { .. } => en.time_to_empty_s,
        K::HomeMarginBelow { .. } => en.home_margin_wh,
        K::MissionMarginBelow { .. } => en.mission_margin_wh,
        K::PowerAbove { .. } => measured,
        K::DeviationAbove { model, .. } => {
            let m = match model {
                Some(n) => est.models.iter().find(|m| &m.name == n),
                None => est
                    .models
                    .iter()
                    .find(|m| m.name == "lstm")
                    .or(est.models.first()),
            }?;
            // Against the slowly adapting reference when adaptation runs (a fault is not
            // learned away in seconds: see model::adapt), else the raw prediction.
            let predicted = m.reference_w.unwrap_or(m.power_w);
            Some((measured? - f64::from(predicted)).abs()).filter(|v| v.is_finite())
        }
        K::ModelsDisagree { .. } => {
            let ps = est
                .models
                .iter()
                .map(|m| f64::from(m.power_w))
                .filter(|p| p.is_finite());
            let (lo, hi) = ps.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p), hi.max(p))
            });
            (est.models.len() >= 2 && hi >= lo).then_some(hi - lo)
        }
        K::CellVoltageBelow { .. } => en.cell_voltage_v,
        K::VehicleVoltageBelow { threshold, .. } => {
            let level = match threshold {
                VehicleThreshold::Low => en.battery.low_voltage_v.as_ref(),
                VehicleThreshold::Critical => en.battery.critical_voltage_v.as_ref(),
            }?;
            let v = f64::from(est.sample.voltage_v?);
            Some(v - level.value).filter(|d| d.is_finite())
        }
        K::VoltageForecastBelow { below_v, .. } => {
            let threshold = below_v.or(en.pack.low_threshold_v)?;
            Some(en.pack.v_min_forecast_v? - threshold).filter(|d| d.is_finite())
        }
        K::LowVoltageBeforeHome { .. } => {
            let home_s = en.home_energy_wh? / en.forecast_w.filter(|w| *w > 1.0)? * 3600.0;
            // A forecast that never reaches the low voltage: as far away as can be.
            let to_low = match (en.pack.time_to_low_v_s, en.pack.v_min_forecast_v) {
                (Some(t), _) => t,
                (None, Some(_)) => 1e9,
                (None, None) => return None,
            };
            Some(to_low - home_s).filter(|d| d.is_finite())
        }
        K::TelemetryLost {} => Some(
            if est.sample.stale_mask & KINEMATIC_MASK == KINEMATIC_MASK {
                1.0
            } else {
                0.0
            },
        ),
    }
}

/// Where one rule stands.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RuleState {
    /// Since when the raise condition has held (debounce), while not raised.
    pending_since: Option<f64>,
    /// Raised, and when it last said so.
    raised_at: Option<f64>,
    /// Last estimate time seen, to notice clocks going backwards.
    last_t: Option<f64>,
}

/// Evaluates every rule on every report.
pub struct AlertEngine {
    rules: Vec<(AlertRule, Levels, RuleState)>,
}

impl AlertEngine {
    /// Check and compile the rules.
    pub fn new(rules: &[AlertRule]) -> anyhow::Result<Self> {
        validate_rules(rules).map_err(anyhow::Error::msg)?;
        let mut compiled = Vec::with_capacity(rules.len());
        for r in rules {
            let l = r.levels().map_err(anyhow::Error::msg)?;
            compiled.push((r.clone(), l, RuleState::default()));
        }
        Ok(Self { rules: compiled })
    }

    /// Where each rule stands (raised, pending), by rule name: what a fleet worker's
    /// checkpoint keeps of the alerts.
    pub fn standing(&self) -> Vec<(String, RuleState)> {
        self.rules
            .iter()
            .map(|(r, _, st)| (r.name.clone(), *st))
            .collect()
    }

    /// Take back where the rules stood ([`AlertEngine::standing`]): each rule of the same
    /// name; a rule the standing does not name starts afresh.
    pub fn restore(&mut self, standing: &[(String, RuleState)]) {
        for (rule, _, st) in &mut self.rules {
            if let Some((_, s)) = standing.iter().find(|(n, _)| *n == rule.name) {
                *st = *s;
            }
        }
    }

    /// Events raised or cleared by this estimate.
    pub fn evaluate(&mut self, est: &Estimate, energy: &EnergyState) -> Vec<AlertEvent> {
        let t = est.t_s;
        let mut events = Vec::new();
        if !t.is_finite() {
            return events;
        }
        for (rule, l, st) in &mut self.rules {
            if st.last_t.is_some_and(|t0| t < t0) {
                // The clock went backwards (a new replay, a rebooted autopilot): restart the
                // debounce and repeat timers; a raised alert stays raised until it clears.
                st.pending_since = None;
                st.raised_at = st.raised_at.map(|_| t);
            }
            st.last_t = Some(t);
            let Some(v) = value(rule, est, energy) else {
                continue;
            };
            let (raising, clearing) = match l.dir {
                Dir::Below => (v < l.raise, v >= l.clear),
                Dir::Above => (v > l.raise, v <= l.clear),
            };
            let mut emit = |state, text: String| {
                events.push(AlertEvent {
                    t,
                    rule: rule.name.clone(),
                    severity: rule.severity,
                    state,
                    message: text,
                })
            };
            let text = |prefix: &str| {
                let head = rule.message.as_deref().unwrap_or(&rule.name);
                if matches!(rule.kind, AlertKind::TelemetryLost {}) {
                    format!("{prefix}{head}")
                } else if let (AlertKind::VoltageForecastBelow { .. }, Some(low), Some(at)) = (
                    &rule.kind,
                    energy.pack.v_min_forecast_v,
                    energy.pack.v_min_forecast_at_s,
                ) {
                    // "sags to 20.6 V (0.4 V under) in 3:05": what, by how much, and when.
                    format!(
                        "{prefix}{head} {low:.1}V ({}V) in {}:{:02}",
                        fmt_value(v),
                        (at / 60.0).floor(),
                        (at % 60.0).floor()
                    )
                } else {
                    format!("{prefix}{head} {}{}", fmt_value(v), l.unit)
                }
            };
            match st.raised_at {
                None if raising => {
                    let since = *st.pending_since.get_or_insert(t);
                    if t - since >= rule.for_s {
                        st.raised_at = Some(t);
                        st.pending_since = None;
                        emit(AlertState::Raised, text(""));
                    }
                }
                None => st.pending_since = None,
                Some(_) if clearing => {
                    st.raised_at = None;
                    emit(AlertState::Cleared, text("cleared: "));
                }
                Some(last) => {
                    if rule.repeat_s > 0.0 && t - last >= rule.repeat_s {
                        st.raised_at = Some(t);
                        emit(AlertState::Raised, text(""));
                    }
                }
            }
        }
        events
    }
}

/// A value short enough for a 50-byte STATUSTEXT: integers above 100, one decimal below.
fn fmt_value(v: f64) -> String {
    if v.abs() >= 100.0 {
        format!("{v:.0}")
    } else {
        format!("{v:.1}")
    }
}
