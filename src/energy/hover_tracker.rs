//! The energy tracker's side of the first-hover calibration ([`super::hover`]): it feeds
//! the search, says what it finds, and rescales the mission forecast it holds.

use super::{hover, idx, EnergyTracker};

impl EnergyTracker {
    /// Calibrate on the vehicle's first hover ([`hover`]): its reference (an error: why it
    /// has none, said when it would have flown); `applies`: the forecast follows the
    /// momentum-theory member, so the live forecast and the mission's are rescaled.
    pub fn set_hover_reference(
        &mut self,
        reference: Result<hover::HoverReference, String>,
        applies: bool,
    ) {
        let throttle = self.first_hover.hover_throttle();
        self.first_hover = hover::HoverCalibrator::new(reference, applies);
        // kept across a new reference: the parameter came with the vehicle
        let _ = self.first_hover.set_hover_throttle(throttle);
    }

    /// ArduPilot's `MOT_THST_HOVER` from the vehicle's parameters (said when it is unusable).
    pub(super) fn set_hover_throttle(&mut self, value: Option<f64>) {
        if value == self.first_hover.hover_throttle() {
            return;
        }
        if let Err(why) = self.first_hover.set_hover_throttle(value) {
            if !self.quiet {
                tracing::info!("first hover: {why}");
            }
        }
    }

    /// The first hover's calibration, once made.
    pub fn hover_calibration(&self) -> Option<&hover::HoverCalibration> {
        self.first_hover.calibration()
    }

    /// The estimate with the momentum-theory member's power (and band) at the first hover's
    /// calibration, once made and applied: what the forecast selection, the forecast and the
    /// reports see. Its adapted power, already matched to measured power, is left as it is.
    pub fn calibrated(&self, mut est: crate::report::Estimate) -> crate::report::Estimate {
        if let Some(c) = self.first_hover.calibration().filter(|c| c.applied) {
            let at = |w: f32| c.power_w(f64::from(w)) as f32;
            for m in est
                .models
                .iter_mut()
                .filter(|m| m.name.starts_with("stolaroff"))
            {
                m.power_w = at(m.power_w);
                m.band_w = m.band_w.map(|(lo, hi)| (at(lo), at(hi)));
            }
        }
        est
    }

    /// Feed the first-hover search one sample; say what it finds (INFO), and rescale the
    /// mission held when it calibrates.
    pub(super) fn observe_hover(&mut self, s: &crate::features::Sample, measured: Option<f64>) {
        let f = |i: usize| f64::from(s.features[i]);
        self.first_hover.set_payload_kg(f(idx::PAYLOAD) / 1000.0);
        let news = self.first_hover.observe(
            s.t_s,
            s.home.map(|h| f64::from(h.height_m)),
            f(idx::VX).hypot(f(idx::VY)),
            f(idx::VZ),
            s.air.throttle_pct.map(f64::from),
            measured,
        );
        match news {
            Some(hover::HoverNews::Calibrated(c)) => {
                if !self.quiet {
                    let then = if c.applied {
                        "the live estimate and the remaining mission's forecast follow it (P90 the drag prior's spread alone)".to_string()
                    } else {
                        "kept for the vehicle store; the forecast does not follow the momentum-theory member, so it is not rescaled".to_string()
                    };
                    let at = if c.source == crate::report::hover::HoverSource::Hover {
                        String::new()
                    } else {
                        format!(
                            " at the hover throttle (MOT_THST_HOVER {:.0} %)",
                            100.0 * self.first_hover.hover_throttle().unwrap_or(f64::NAN)
                        )
                    };
                    let at = if c.payload_kg > 0.0 {
                        format!("{at} with {:.2} kg of payload", c.payload_kg)
                    } else {
                        at
                    };
                    tracing::info!(
                        "first hover: {:.0} W over {:.0} s{at} sets the hover efficiency η_h {:.3} (was {:.3}); {then}",
                        c.hover_w,
                        c.hover_s,
                        c.eta_h,
                        c.prior_eta_h
                    );
                }
                if let Some(m) = self.mission.take() {
                    self.mission = Some(self.hover_scaled(m));
                }
            }
            Some(hover::HoverNews::NoHover(why)) if !self.quiet => {
                tracing::info!("first hover: {why}");
            }
            _ => {}
        }
    }

    /// A mission status of the momentum-theory member rescaled to the calibrated η_h (its
    /// P90 tightened to the drag's spread); as it is without an applied calibration.
    pub(super) fn hover_scaled(
        &self,
        mut m: crate::report::MissionStatus,
    ) -> crate::report::MissionStatus {
        if let Some(c) = self.first_hover.calibration().filter(|c| c.applied) {
            let ratio = if m.energy_p50_wh > 0.0 {
                m.energy_p90_wh / m.energy_p50_wh
            } else {
                1.0
            };
            m.energy_p50_wh = c.energy_wh(m.energy_p50_wh, m.time_left_s);
            m.energy_p90_wh = m.energy_p50_wh * ratio.min(crate::model::spec::calibrated_p90());
        }
        m
    }
}
