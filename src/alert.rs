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

use crate::report::{AlertEvent, AlertState, Severity};
use serde::Deserialize;

use crate::report::{EnergyState, Estimate};

/// What a rule watches, with its levels. Units are in the key names.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum AlertKind {
    /// Remaining energy under `below_wh` Wh or `below_pct` % of capacity (one of them).
    RemainingBelow {
        below_wh: Option<f64>,
        below_pct: Option<f64>,
        clear_wh: Option<f64>,
        clear_pct: Option<f64>,
    },
    /// Time to empty at the forecast power under `below_s`.
    TimeToEmptyBelow { below_s: f64, clear_s: Option<f64> },
    /// Remaining − energy to get home − reserve under `below_wh`.
    HomeMarginBelow {
        below_wh: f64,
        clear_wh: Option<f64>,
    },
    /// Remaining − energy of the rest of the mission, the return and the landing − reserve
    /// under `below_wh`: "mission cannot finish with reserve — return now".
    MissionMarginBelow {
        below_wh: f64,
        clear_wh: Option<f64>,
    },
    /// Measured electrical power over `above_w`.
    PowerAbove { above_w: f64, clear_w: Option<f64> },
    /// |measured − predicted| over `above_w`, predicted by `model` (default `lstm`, else the
    /// first model that ran).
    DeviationAbove {
        above_w: f64,
        clear_w: Option<f64>,
        model: Option<String>,
    },
    /// The models' predictions spread (max − min) wider than `above_w`.
    ModelsDisagree { above_w: f64, clear_w: Option<f64> },
    /// Battery voltage per cell under `below_v`.
    CellVoltageBelow { below_v: f64, clear_v: Option<f64> },
    /// Battery voltage (whole pack) under the autopilot's own `threshold` plus `margin_v`
    /// (V, default 0: at the threshold). Quiet while the vehicle has not said its threshold.
    VehicleVoltageBelow {
        threshold: VehicleThreshold,
        margin_v: Option<f64>,
        clear_margin_v: Option<f64>,
    },
    /// The lowest loaded voltage forecast for the rest of the flight under `below_v` (V,
    /// whole pack; default the low threshold: the vehicle's `BATT_LOW_VOLT`, else 3.5 V a
    /// cell) plus `margin_v` (default 0).
    VoltageForecastBelow {
        below_v: Option<f64>,
        margin_v: Option<f64>,
        clear_margin_v: Option<f64>,
    },
    /// Time to the low voltage (the pack's loaded-voltage forecast) − time home (energy home
    /// at the forecast power) under `below_s` (default 0): the pack will sag under the
    /// low threshold before the vehicle is home.
    LowVoltageBeforeHome {
        below_s: Option<f64>,
        clear_s: Option<f64>,
    },
    /// Every kinematic feature (position, attitude, velocity, rates, acceleration) stale for
    /// `for_s`: the vehicle's state stopped arriving while the link still carries something
    /// (battery, heartbeats). A link gone wholly silent yields no estimates at all, so no
    /// rule runs; the source reports that silence itself.
    TelemetryLost {},
}

/// Which of the autopilot's battery thresholds a `vehicle_voltage_below` rule watches.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum VehicleThreshold {
    /// `BATT_LOW_VOLT` (ArduPilot).
    Low,
    /// `BATT_CRT_VOLT` (ArduPilot), else PX4's `BAT1_V_EMPTY` × cells.
    Critical,
}

/// One `[[alerts]]` rule: the keys every kind shares, and its [`AlertKind`].
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(try_from = "toml::Table")]
pub struct AlertRule {
    /// Rule name, unique; shown in every alert it raises.
    pub name: String,
    /// How loud: a MAV_SEVERITY name. Default `warning`.
    pub severity: Severity,
    /// Debounce: the condition must hold this long before the alert raises, s. Default 0.
    pub for_s: f64,
    /// While raised, say it again this often, s; 0 says it once. Default 0.
    pub repeat_s: f64,
    /// Text of the alert, default the rule name; the value is appended.
    pub message: Option<String>,
    /// What it watches.
    pub kind: AlertKind,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Common {
    name: String,
    #[serde(default = "default_severity")]
    severity: Severity,
    #[serde(default)]
    for_s: f64,
    #[serde(default)]
    repeat_s: f64,
    message: Option<String>,
}

fn default_severity() -> Severity {
    Severity::Warning
}

impl TryFrom<toml::Table> for AlertRule {
    type Error = String;
    /// The shared keys come off first, the rest must be exactly one kind's keys: serde's
    /// `flatten` cannot do this and still reject unknown keys.
    fn try_from(mut t: toml::Table) -> Result<Self, String> {
        let mut common = toml::Table::new();
        for k in ["name", "severity", "for_s", "repeat_s", "message"] {
            if let Some(v) = t.remove(k) {
                common.insert(k.to_string(), v);
            }
        }
        let c = Common::deserialize(common).map_err(|e| format!("alert rule: {}", e.message()))?;
        let kind = AlertKind::deserialize(t)
            .map_err(|e| format!("alert rule '{}': {}", c.name, e.message()))?;
        Ok(AlertRule {
            name: c.name,
            severity: c.severity,
            for_s: c.for_s,
            repeat_s: c.repeat_s,
            message: c.message,
            kind,
        })
    }
}

/// Which way a level points.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Dir {
    Below,
    Above,
}

/// A rule reduced to a number, a direction, a raise level and a clear level.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Levels {
    dir: Dir,
    raise: f64,
    clear: f64,
    /// Unit shown in messages.
    unit: &'static str,
    /// Key of the raise level, for errors.
    key: &'static str,
}

impl AlertRule {
    fn levels(&self) -> Result<Levels, String> {
        use AlertKind as K;
        let lv = |dir, raise: f64, clear: Option<f64>, unit, key| Levels {
            dir,
            raise,
            clear: clear.unwrap_or(raise),
            unit,
            key,
        };
        Ok(match &self.kind {
            K::RemainingBelow {
                below_wh,
                below_pct,
                clear_wh,
                clear_pct,
            } => match (below_wh, below_pct) {
                (Some(wh), None) => {
                    if clear_pct.is_some() {
                        return Err(
                            "clear_pct: with below_wh, give the clear level as clear_wh".into()
                        );
                    }
                    lv(Dir::Below, *wh, *clear_wh, "Wh", "below_wh")
                }
                (None, Some(pct)) => {
                    if clear_wh.is_some() {
                        return Err(
                            "clear_wh: with below_pct, give the clear level as clear_pct".into(),
                        );
                    }
                    lv(Dir::Below, *pct, *clear_pct, "%", "below_pct")
                }
                _ => {
                    return Err(
                        "kind 'remaining_below' needs exactly one of below_wh, below_pct".into(),
                    )
                }
            },
            K::TimeToEmptyBelow { below_s, clear_s } => {
                lv(Dir::Below, *below_s, *clear_s, "s", "below_s")
            }
            K::HomeMarginBelow { below_wh, clear_wh } => {
                lv(Dir::Below, *below_wh, *clear_wh, "Wh", "below_wh")
            }
            K::MissionMarginBelow { below_wh, clear_wh } => {
                lv(Dir::Below, *below_wh, *clear_wh, "Wh", "below_wh")
            }
            K::PowerAbove { above_w, clear_w } => {
                lv(Dir::Above, *above_w, *clear_w, "W", "above_w")
            }
            K::DeviationAbove {
                above_w, clear_w, ..
            } => lv(Dir::Above, *above_w, *clear_w, "W", "above_w"),
            K::ModelsDisagree { above_w, clear_w } => {
                lv(Dir::Above, *above_w, *clear_w, "W", "above_w")
            }
            K::CellVoltageBelow { below_v, clear_v } => {
                lv(Dir::Below, *below_v, *clear_v, "V", "below_v")
            }
            K::VehicleVoltageBelow {
                margin_v,
                clear_margin_v,
                ..
            } => lv(
                Dir::Below,
                margin_v.unwrap_or(0.0),
                clear_margin_v.or(*margin_v),
                "V",
                "margin_v",
            ),
            K::VoltageForecastBelow {
                below_v,
                margin_v,
                clear_margin_v,
            } => {
                if let Some(v) = below_v {
                    crate::validate::in_range(
                        "below_v",
                        *v,
                        crate::validate::above(0.0),
                        "V (whole pack)",
                    )?;
                }
                lv(
                    Dir::Below,
                    margin_v.unwrap_or(0.0),
                    clear_margin_v.or(*margin_v),
                    "V",
                    "margin_v",
                )
            }
            K::LowVoltageBeforeHome { below_s, clear_s } => {
                lv(Dir::Below, below_s.unwrap_or(0.0), *clear_s, "s", "below_s")
            }
            K::TelemetryLost {} => lv(Dir::Above, 0.5, None, "", "for_s"),
        })
    }

    /// Check one rule; the message names the key and why (the caller adds the file and
    /// the rule's position).
    pub fn validate(&self) -> Result<(), String> {
        if self.name.trim().is_empty() {
            return Err("name: must not be empty".into());
        }
        crate::validate::in_range("for_s", self.for_s, 0.0.., "s")?;
        crate::validate::in_range("repeat_s", self.repeat_s, 0.0.., "s (0: say it once)")?;
        if matches!(self.kind, AlertKind::TelemetryLost {}) && self.for_s <= 0.0 {
            return Err(
                "for_s: telemetry_lost needs for_s > 0 (how long before the link counts as lost)"
                    .into(),
            );
        }
        let l = self.levels()?;
        if !l.raise.is_finite() || !l.clear.is_finite() {
            return Err(format!("{}: levels must be finite numbers", l.key));
        }
        let clear_key = if l.key == "margin_v" {
            "clear_margin_v".to_string()
        } else {
            l.key.replace("below", "clear").replace("above", "clear")
        };
        match l.dir {
            Dir::Below if l.clear < l.raise => {
                return Err(format!(
                "{clear_key} = {}: must be ≥ {} = {} (it clears above the level it raises under)",
                l.clear, l.key, l.raise
            ))
            }
            Dir::Above if l.clear > l.raise => {
                return Err(format!(
                "{clear_key} = {}: must be ≤ {} = {} (it clears below the level it raises over)",
                l.clear, l.key, l.raise
            ))
            }
            _ => {}
        }
        Ok(())
    }

    /// One line saying what the rule does, for `check-config`.
    pub fn describe(&self) -> String {
        let Ok(l) = self.levels() else {
            return format!("{}: invalid", self.name);
        };
        let what = match &self.kind {
            AlertKind::RemainingBelow { .. } => "remaining energy",
            AlertKind::TimeToEmptyBelow { .. } => "time to empty",
            AlertKind::HomeMarginBelow { .. } => "home-reserve margin",
            AlertKind::MissionMarginBelow { .. } => "mission-reserve margin",
            AlertKind::PowerAbove { .. } => "measured power",
            AlertKind::DeviationAbove { .. } => "|measured − predicted|",
            AlertKind::ModelsDisagree { .. } => "model spread",
            AlertKind::CellVoltageBelow { .. } => "cell voltage",
            AlertKind::VehicleVoltageBelow {
                threshold: VehicleThreshold::Low,
                ..
            } => "battery voltage − the vehicle's low threshold",
            AlertKind::VehicleVoltageBelow {
                threshold: VehicleThreshold::Critical,
                ..
            } => "battery voltage − the vehicle's critical threshold",
            AlertKind::VoltageForecastBelow {
                below_v: Some(_), ..
            } => "lowest forecast loaded voltage − below_v",
            AlertKind::VoltageForecastBelow { .. } => {
                "lowest forecast loaded voltage − the low threshold"
            }
            AlertKind::LowVoltageBeforeHome { .. } => "time to the low voltage − time home",
            AlertKind::TelemetryLost {} => "telemetry",
        };
        let cond = if matches!(self.kind, AlertKind::TelemetryLost {}) {
            "lost".to_string()
        } else {
            let (op, cop) = if l.dir == Dir::Below {
                ("<", "≥")
            } else {
                (">", "≤")
            };
            format!(
                "{op} {} {}, clears {cop} {} {}",
                l.raise, l.unit, l.clear, l.unit
            )
        };
        let repeat = if self.repeat_s > 0.0 {
            format!(", repeats every {} s", self.repeat_s)
        } else {
            String::new()
        };
        format!(
            "{} [{}]: {what} {cond}, for {} s{repeat}",
            self.name, self.severity, self.for_s
        )
    }
}

/// Check a rule list: each rule, and names unique. Errors say `alerts[i] (name).key: why`,
/// one line per broken rule (a rule's first error; fixing it shows the next).
pub fn validate_rules(rules: &[AlertRule]) -> Result<(), String> {
    let mut errs = Vec::new();
    for (i, r) in rules.iter().enumerate() {
        if let Err(e) = r.validate() {
            errs.push(format!("alerts[{i}] ({}).{e}", r.name.escape_debug()));
        }
        if rules[..i].iter().any(|o| o.name == r.name) {
            errs.push(format!(
                "alerts[{i}].name = '{}': another rule already has this name",
                r.name.escape_debug()
            ));
        }
    }
    if errs.is_empty() {
        Ok(())
    } else {
        Err(errs.join("\n"))
    }
}

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
#[derive(Debug, Clone, Copy, Default)]
struct RuleState {
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
