//! Which model the forecast follows: online model selection on this vehicle's evidence.
//!
//! The forecast (time to empty, energy home, mission margin) follows one model's adapted
//! prediction. Which one:
//!
//! 1. `[energy] model`, when the config names one: always that model (no selection).
//! 2. Else it starts from the *default*: the vehicle profile's `[forecast] model` (what
//!    `dronewatt learn` picked on held-out logs), else `lstm` (the M100's best), and moves
//!    to another model only when this vehicle's measured power says so:
//!    - every model's adapted estimate carries its recent mean absolute error against the
//!      measured power ([`crate::report::AdaptedError`], scored out of sample by
//!      [`crate::model::adapt`], only while the motors lift);
//!    - a challenger needs `evidence_s` seconds of scored flight, and so does the model
//!      followed (no switch on the first seconds of a flight);
//!    - it must beat the followed model's recent error by the fraction `margin`, without a
//!      break, for `hold_s` seconds (hysteresis: two models of near-equal error never flap,
//!      and a transient of a few seconds does not move the forecast);
//!    - the profile's model was picked on whole held-out logs of this vehicle, evidence
//!      the M100's LSTM has not on a vehicle it was not made for: away from it a
//!      challenger must win by `profile_margin` (larger).
//!
//! The choice and why are published ([`Choice`]): the JSON lines (`forecast_model`,
//! `forecast_why`), the terminal and the dashboard say which model the forecast uses.
//! Pure: estimates in, a name out; no I/O, no clock but the estimates' time.

use crate::report::ModelEstimate;

/// The `[energy.select]` table: online selection of the forecast model.
#[derive(Debug, Clone, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SelectConfig {
    /// Let the forecast move to the model with the lowest recent error on this vehicle.
    /// Default true. Off: it follows the default model (profile's, else `lstm`) always.
    /// `[energy] model` set turns selection off too.
    pub enabled: bool,
    /// Seconds of scored flight (measured power, motors lifting) a model needs, and the
    /// model followed needs, before the forecast may switch to it. Default 30.
    pub evidence_s: f64,
    /// A challenger's recent error must be below (1 − `margin`) × the followed model's.
    /// Default 0.2.
    pub margin: f64,
    /// The margin against the vehicle profile's own forecast model (picked by `learn` on
    /// held-out logs of this vehicle), while the forecast still follows it. Default 0.3.
    pub profile_margin: f64,
    /// ... without a break for this long, s. Default 10.
    pub hold_s: f64,
}

impl Default for SelectConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            evidence_s: 30.0,
            margin: 0.2,
            profile_margin: 0.3,
            hold_s: 10.0,
        }
    }
}

impl SelectConfig {
    /// Range checks; each message names the key.
    pub fn validate(&self) -> Vec<String> {
        let mut errs = crate::validate::Errors::new();
        errs.range("energy.select.evidence_s", self.evidence_s, 0.0.., "s");
        errs.range("energy.select.hold_s", self.hold_s, 0.0.., "s");
        errs.range("energy.select.margin", self.margin, 0.0..1.0, "");
        errs.range(
            "energy.select.profile_margin",
            self.profile_margin,
            0.0..1.0,
            "",
        );
        errs.into_vec()
    }
}

/// Why the forecast follows the model it follows.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Why {
    /// `[energy] model` names it.
    Config,
    /// The default: the vehicle profile's choice (`learn`; `profile`), else `lstm`; `from`
    /// says which.
    Default { from: String, profile: bool },
    /// Its adapted estimate's recent error on this vehicle beat the model followed before.
    LowestError {
        err_w: f32,
        was: String,
        was_err_w: f32,
        evidence_s: f32,
    },
}

impl std::fmt::Display for Why {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Why::Config => write!(f, "config [energy] model"),
            Why::Default { from, .. } => write!(f, "default ({from})"),
            Why::LowestError { err_w, was, was_err_w, evidence_s } => write!(
                f,
                "lowest recent error on this vehicle: {err_w:.0} W vs {was} {was_err_w:.0} W ({evidence_s:.0} s of evidence)"
            ),
        }
    }
}

/// The model the forecast follows, and why.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Choice {
    pub model: String,
    pub why: Why,
}

/// Online selection of the forecast model (module docs).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Selector {
    cfg: SelectConfig,
    /// Whether the config fixed the model (no selection).
    fixed: bool,
    current: Choice,
    /// The challenger ahead of the model followed, and since when, s.
    ahead: Option<(String, f64)>,
}

impl Selector {
    /// `configured`: `[energy] model`; `default`: the profile's choice and where it came
    /// from (None: `lstm`).
    pub fn new(
        cfg: &SelectConfig,
        configured: Option<&str>,
        default: Option<(&str, &str)>,
    ) -> Self {
        let (current, fixed) = match (configured, default) {
            (Some(m), _) => (
                Choice {
                    model: m.to_string(),
                    why: Why::Config,
                },
                true,
            ),
            (None, Some((m, from))) => (
                Choice {
                    model: m.to_string(),
                    why: Why::Default {
                        from: from.to_string(),
                        profile: true,
                    },
                },
                false,
            ),
            (None, None) => (
                Choice {
                    model: "lstm".into(),
                    why: Why::Default {
                        from: "the M100's forecast model".into(),
                        profile: false,
                    },
                },
                false,
            ),
        };
        Self {
            fixed: fixed || !cfg.enabled,
            cfg: cfg.clone(),
            current,
            ahead: None,
        }
    }

    /// The model followed now.
    pub fn current(&self) -> &Choice {
        &self.current
    }

    /// Take one estimate (time `t_s`): the choice after it. Selection runs only while the
    /// model followed is among `models` (else the forecast follows measured power, as
    /// without a forecast model).
    pub fn update(&mut self, t_s: f64, models: &[ModelEstimate]) -> &Choice {
        if self.fixed || !t_s.is_finite() {
            return &self.current;
        }
        let scored = |m: &ModelEstimate| {
            let e = m.adapted_err.filter(|e| {
                e.err_w.is_finite() && f64::from(e.evidence_s) >= self.cfg.evidence_s
            })?;
            m.adapted_w.is_some().then_some(e)
        };
        let Some(now) = models
            .iter()
            .find(|m| m.name == self.current.model)
            .and_then(scored)
        else {
            self.ahead = None;
            return &self.current;
        };
        let margin = match self.current.why {
            Why::Default { profile: true, .. } => self.cfg.profile_margin,
            _ => self.cfg.margin,
        };
        let best = models
            .iter()
            .filter(|m| m.name != self.current.model)
            .filter_map(|m| Some((m, scored(m)?)))
            .min_by(|a, b| a.1.err_w.total_cmp(&b.1.err_w))
            .filter(|(_, e)| f64::from(e.err_w) < (1.0 - margin) * f64::from(now.err_w));
        let Some((m, e)) = best else {
            self.ahead = None;
            return &self.current;
        };
        let since = match &self.ahead {
            Some((name, since)) if *name == m.name => *since,
            _ => t_s,
        };
        self.ahead = Some((m.name.clone(), since));
        if t_s - since >= self.cfg.hold_s {
            tracing::info!(
                "forecast model: {} → {} (recent error {:.0} W vs {:.0} W over {:.0} s of flight)",
                self.current.model,
                m.name,
                e.err_w,
                now.err_w,
                e.evidence_s
            );
            self.current = Choice {
                model: m.name.clone(),
                why: Why::LowestError {
                    err_w: e.err_w,
                    was: self.current.model.clone(),
                    was_err_w: now.err_w,
                    evidence_s: e.evidence_s,
                },
            };
            self.ahead = None;
        }
        &self.current
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::AdaptedError;

    fn m(name: &str, err_w: f32, evidence_s: f32) -> ModelEstimate {
        ModelEstimate {
            adapted_w: Some(100.0),
            adapted_err: Some(AdaptedError { err_w, evidence_s }),
            ..ModelEstimate::new(name, 100.0, None)
        }
    }

    /// Steps `ks` at 10 Hz, each model with its error and as much evidence as time passed.
    fn feed(s: &mut Selector, ks: std::ops::Range<u32>, errs: &[(&str, f32)]) {
        for k in ks {
            let t = f64::from(k) * 0.1;
            let models: Vec<ModelEstimate> = errs.iter().map(|&(n, e)| m(n, e, t as f32)).collect();
            s.update(t, &models);
        }
    }

    #[test]
    fn stays_on_the_default_until_the_evidence_says_otherwise() {
        let mut s = Selector::new(&SelectConfig::default(), None, None);
        assert_eq!(s.current().model, "lstm");
        // 20 s in: stolaroff much better, but too little evidence.
        for k in 0..200 {
            let t = f64::from(k) * 0.1;
            assert_eq!(
                s.update(
                    t,
                    &[m("lstm", 40.0, t as f32), m("stolaroff", 10.0, t as f32)]
                )
                .model,
                "lstm"
            );
        }
        // With evidence: it must stay ahead for hold_s (10 s) before the switch.
        let mut switched_at = None;
        for k in 300..500 {
            let t = f64::from(k) * 0.1;
            if s.update(
                t,
                &[m("lstm", 40.0, t as f32), m("stolaroff", 10.0, t as f32)],
            )
            .model
                == "stolaroff"
            {
                switched_at.get_or_insert(t);
            }
        }
        let at = switched_at.expect("switched");
        assert!((at - 40.0).abs() < 0.15, "{at}");
        assert!(
            s.current().why.to_string().contains("lowest recent error"),
            "{}",
            s.current().why
        );
    }

    #[test]
    fn does_not_flap_between_near_equals_or_on_a_transient() {
        let mut s = Selector::new(&SelectConfig::default(), None, None);
        for k in 0..3000 {
            let t = f64::from(k) * 0.1;
            // Near-equal errors crossing back and forth, and a 5 s dip of the other model.
            let other = if (1000..1050).contains(&k) {
                5.0
            } else if k % 20 < 10 {
                18.0
            } else {
                22.0
            };
            assert_eq!(
                s.update(
                    t,
                    &[m("lstm", 20.0, t as f32), m("dorling", other, t as f32)]
                )
                .model,
                "lstm",
                "at {t}"
            );
        }
    }

    #[test]
    fn the_config_wins_and_the_profile_sets_the_default() {
        let mut s = Selector::new(
            &SelectConfig::default(),
            Some("dandrea"),
            Some(("stolaroff_cal", "profile")),
        );
        feed(
            &mut s,
            0..1000,
            &[("dandrea", 90.0), ("stolaroff_cal", 1.0)],
        );
        assert_eq!(
            (s.current().model.as_str(), &s.current().why),
            ("dandrea", &Why::Config)
        );
        let s = Selector::new(
            &SelectConfig::default(),
            None,
            Some(("stolaroff_cal", "vehicle profile learned")),
        );
        assert_eq!(s.current().model, "stolaroff_cal");
        assert_eq!(
            s.current().why.to_string(),
            "default (vehicle profile learned)"
        );
        // The profile's pick (held-out evidence) needs the larger margin: 25 % better is not
        // enough, 40 % is.
        let mut s = Selector::new(
            &SelectConfig::default(),
            None,
            Some(("stolaroff_cal", "profile")),
        );
        feed(&mut s, 0..1000, &[("lstm", 15.0), ("stolaroff_cal", 20.0)]);
        assert_eq!(s.current().model, "stolaroff_cal");
        feed(
            &mut s,
            1000..1200,
            &[("lstm", 12.0), ("stolaroff_cal", 20.0)],
        );
        assert_eq!(s.current().model, "lstm");
        // Off: never moves.
        let mut s = Selector::new(
            &SelectConfig {
                enabled: false,
                ..Default::default()
            },
            None,
            None,
        );
        for k in 0..1000 {
            let t = f64::from(k) * 0.1;
            s.update(t, &[m("lstm", 90.0, 100.0), m("dorling", 1.0, 100.0)]);
        }
        assert_eq!(s.current().model, "lstm");
    }

    #[test]
    fn config_checks_name_the_key() {
        let bad = SelectConfig {
            margin: 1.5,
            hold_s: -1.0,
            ..Default::default()
        };
        let errs = bad.validate().join("\n");
        assert!(
            errs.contains("energy.select.margin") && errs.contains("energy.select.hold_s"),
            "{errs}"
        );
    }
}
