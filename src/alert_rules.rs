//! Alert rules as the `[[alerts]]` tables write them: what each kind watches, its levels,
//! severity and debounce, and the checks that name the broken key.

use serde::Deserialize;

use crate::report::Severity;

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
pub(super) struct Common {
    name: String,
    #[serde(default = "default_severity")]
    severity: Severity,
    #[serde(default)]
    for_s: f64,
    #[serde(default)]
    repeat_s: f64,
    message: Option<String>,
}

pub(super) fn default_severity() -> Severity {
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
pub(super) enum Dir {
    Below,
    Above,
}

/// A rule reduced to a number, a direction, a raise level and a clear level.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Levels {
    pub(super) dir: Dir,
    pub(super) raise: f64,
    pub(super) clear: f64,
    /// Unit shown in messages.
    pub(super) unit: &'static str,
    /// Key of the raise level, for errors.
    pub(super) key: &'static str,
}

impl AlertRule {
    pub(super) fn levels(&self) -> Result<Levels, String> {
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
