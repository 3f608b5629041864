//! The pilot's alert rules, run when the config names none.
//!
//! | rule | kind | raises when | severity |
//! |---|---|---|---|
//! | `low_voltage_before_home` | `low_voltage_before_home` | the pack is forecast to sag under the low voltage before the vehicle is home | critical |
//! | `below_reserve` | `remaining_below` | remaining energy under the reserve (`[energy] reserve_pct`) | critical |
//! | `voltage_forecast` | `voltage_forecast_below` | the lowest voltage forecast for the rest of the flight under the low threshold (`BATT_LOW_VOLT`, else 3.5 V a cell) | warning |
//! | `mission_margin` | `mission_margin_below` | the rest of the mission, the return and the landing do not fit above the reserve | critical |
//! | `telemetry_lost` | `telemetry_lost` | the vehicle's state stopped arriving for 5 s (a vehicle gone wholly silent is reported by the link: `vehicle_lost`) | critical |
//!
//! They are TOML, the same text `check-config` prints: a config's `[[alerts]]` replace them
//! all, so copying this text and editing a level overrides one.

use super::AlertRule;

/// The rules in words, for `--help`.
pub const HELP: &str = "Alerts with no [[alerts]] in the config (the pilot's defaults; `check-config` prints them as TOML to copy and edit):
  low_voltage_before_home  critical  the pack is forecast to sag under the low voltage before the vehicle is home
  below_reserve            critical  remaining energy under the reserve ([energy] reserve_pct)
  voltage_forecast         warning   the lowest voltage forecast under the low threshold (BATT_LOW_VOLT, else 3.5 V a cell)
  mission_margin           critical  the rest of the mission and the return do not fit above the reserve
  telemetry_lost           critical  the vehicle's state stopped arriving for 5 s
A config's [[alerts]] replace them all.";

/// The default rules as TOML `[[alerts]]` tables, for a reserve of `reserve_pct` %.
pub fn toml(reserve_pct: f64) -> String {
    format!(
        r#"[[alerts]]
name = "low_voltage_before_home"
kind = "low_voltage_before_home"
severity = "critical"
for_s = 2
repeat_s = 30
message = "Return now: low voltage before home"

[[alerts]]
name = "below_reserve"
kind = "remaining_below"
below_pct = {reserve_pct}
clear_pct = {clear}
severity = "critical"
for_s = 2
repeat_s = 30
message = "Land now: under the reserve"

[[alerts]]
name = "voltage_forecast"
kind = "voltage_forecast_below"
clear_margin_v = 0.2
severity = "warning"
for_s = 2
message = "Voltage forecast under the low threshold"

[[alerts]]
name = "mission_margin"
kind = "mission_margin_below"
below_wh = 0
clear_wh = 1
severity = "critical"
for_s = 2
repeat_s = 30
message = "Mission does not fit: return now"

[[alerts]]
name = "telemetry_lost"
kind = "telemetry_lost"
severity = "critical"
for_s = 5
message = "Vehicle state lost"
"#,
        clear = reserve_pct + 2.0,
    )
}

/// The default rules, for a reserve of `reserve_pct` %.
pub fn rules(reserve_pct: f64) -> Vec<AlertRule> {
    #[derive(serde::Deserialize)]
    struct Rules {
        alerts: Vec<AlertRule>,
    }
    // The text is ours: a failure here is a bug the tests catch, never the user's input.
    toml::from_str::<Rules>(&toml(reserve_pct))
        .map(|r| r.alerts)
        .expect("the default alert rules parse")
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_default_rules_parse_and_validate_for_any_reserve() {
        for reserve in [0.0, 20.0, 35.5] {
            let rules = super::rules(reserve);
            assert_eq!(rules.len(), 5);
            super::super::validate_rules(&rules).unwrap();
        }
    }
}
