//! A model stuck at one value: flagged once, by name.
//!
//! A model whose estimate holds one value (within [`TOLERANCE_W`]) for [`STUCK_S`] seconds
//! while the measured power moved by [`MOVED_SHARE`] of its level or more does not follow the
//! flight. Some do so by their form: Dorling et al.'s equation is hover power from the mass
//! alone, `(m·g)^1.5 / (η·√(2·n·ρ·ζ))`, so it gives one figure (the demo's 168.3 W) for a
//! whole flight at one mass — not a bug in the code, but a figure a reader must not take for
//! a tracking estimate. Others would by a fault (an input stuck, a NaN path). Either way the
//! operator is told once, by a warning naming the model, its value and for how long; the
//! model keeps running (its figure is still the published model's).

use crate::report::Estimate;

/// Seconds at one value, while the measured power moved, before a model is flagged.
pub const STUCK_S: f64 = 60.0;
/// Within this of the value it started at, W, a model has not moved.
pub const TOLERANCE_W: f32 = 0.05;
/// The measured power's range over its peak that counts as moving.
pub const MOVED_SHARE: f64 = 0.2;

/// One model's run at one value.
#[derive(Debug, Clone)]
struct Track {
    name: String,
    value: f32,
    since_s: f64,
    measured: Option<(f64, f64)>,
    told: bool,
}

/// Watches every model's estimate for a run at one value.
#[derive(Debug, Default, Clone)]
pub struct StuckWatch {
    tracks: Vec<Track>,
}

impl StuckWatch {
    /// Take in one estimate; the messages for the models flagged now (each model once).
    pub fn observe(&mut self, est: &Estimate) -> Vec<String> {
        let measured = est
            .sample
            .measured_w
            .filter(|p| p.is_finite())
            .map(f64::from);
        let mut out = Vec::new();
        for m in &est.models {
            if !m.power_w.is_finite() {
                continue;
            }
            let i = match self.tracks.iter().position(|t| t.name == m.name) {
                Some(i) => i,
                None => {
                    self.tracks.push(Track {
                        name: m.name.clone(),
                        value: m.power_w,
                        since_s: est.t_s,
                        measured: None,
                        told: false,
                    });
                    self.tracks.len() - 1
                }
            };
            let t = &mut self.tracks[i];
            if (m.power_w - t.value).abs() > TOLERANCE_W {
                t.value = m.power_w;
                t.since_s = est.t_s;
                t.measured = None;
                continue;
            }
            if let Some(p) = measured {
                t.measured = Some(t.measured.map_or((p, p), |(lo, hi)| (lo.min(p), hi.max(p))));
            }
            let held = est.t_s - t.since_s;
            let moved = t
                .measured
                .is_some_and(|(lo, hi)| hi > 0.0 && (hi - lo) >= MOVED_SHARE * hi);
            if !t.told && held >= STUCK_S && moved {
                t.told = true;
                let (lo, hi) = t.measured.unwrap_or_default();
                out.push(format!(
                    "model {} stuck at {:.1} W for {held:.0} s while the measured power moved {lo:.0}–{hi:.0} W: it does not follow the flight{}",
                    t.name,
                    t.value,
                    if t.name.starts_with("dorling") {
                        " (Dorling's equation is hover power from the mass alone)"
                    } else {
                        ""
                    }
                ));
            }
        }
        out
    }

    /// The models flagged so far.
    pub fn flagged(&self) -> Vec<&str> {
        self.tracks
            .iter()
            .filter(|t| t.told)
            .map(|t| t.name.as_str())
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::ModelEstimate;

    fn est(t_s: f64, measured: f64, models: &[(&str, f32)]) -> Estimate {
        let mut sample =
            crate::features::Sample::new(t_s, [0.0; crate::features::N_FEATURES], None);
        sample.measured_w = Some(measured as f32);
        let models = models
            .iter()
            .map(|(n, p)| ModelEstimate {
                name: (*n).into(),
                power_w: *p,
                band_w: None,
                adapted_w: None,
                reference_w: None,
                adapted_err: None,
            })
            .collect();
        Estimate {
            t_s,
            sample,
            models,
            arrived: None,
        }
    }

    #[test]
    fn a_model_at_one_value_while_power_moves_is_flagged_once() {
        let mut w = StuckWatch::default();
        let mut said = Vec::new();
        for i in 0..200 {
            let t = f64::from(i);
            let measured = 300.0 + 100.0 * (t / 10.0).sin();
            let follows = measured as f32 * 0.9;
            said.extend(w.observe(&est(t, measured, &[("dorling", 168.3), ("lstm", follows)])));
        }
        assert_eq!(said.len(), 1, "{said:?}");
        assert!(said[0].contains("dorling stuck at 168.3 W"), "{}", said[0]);
        assert_eq!(w.flagged(), vec!["dorling"]);
    }

    #[test]
    fn a_steady_hover_flags_nothing() {
        let mut w = StuckWatch::default();
        for i in 0..300 {
            // the measured power within a few percent: the model's flat line is right
            let measured = 300.0 + f64::from(i % 7);
            assert!(w
                .observe(&est(f64::from(i), measured, &[("dorling", 290.0)]))
                .is_empty());
        }
        assert!(w.flagged().is_empty());
    }
}
