//! The first hover's calibration as the reports carry it (`hover_calibration`): what the
//! energy tracker's first-hover search (`energy::hover`) measured and set, and how it
//! rescales the momentum-theory member's power and energy.

use serde::Serialize;

/// A first hover measured and what it set (in `--json`: `hover_calibration`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct HoverCalibration {
    /// Source time it was made at, s.
    pub t_s: f64,
    /// Mean measured power V·I over the hover, W.
    pub hover_w: f64,
    /// Seconds of hover averaged.
    pub hover_s: f64,
    /// The hover efficiency it gives, and the one before.
    pub eta_h: f64,
    pub prior_eta_h: f64,
    /// Avionics power, W (not scaled).
    pub avionics_w: f64,
    /// The mission's payload on board during the hover, kg: the ideal power η_h is taken
    /// against is the take-off mass's with it (0 in reports written before it was kept).
    #[serde(default)]
    pub payload_kg: f64,
    /// Whether the forecast follows the momentum-theory member, so that the live forecast
    /// and the mission's were rescaled (else the figure is only kept for the store).
    pub applied: bool,
    /// What measured it: `hover` (a still hover flown) or `MOT_THST_HOVER` (the pack's V·I
    /// while the throttle was at ArduPilot's learned hover throttle).
    pub source: HoverSource,
}

/// What measured a first hover (in `--json`: `hover_calibration.source`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize)]
pub enum HoverSource {
    /// A still hover flown.
    #[serde(rename = "hover")]
    Hover,
    /// The pack's V·I while the throttle was at ArduPilot's learned hover throttle.
    #[serde(rename = "MOT_THST_HOVER")]
    HoverThrottle,
}

impl HoverCalibration {
    /// `k = η_prior / η_h`: what the member's non-avionics power is multiplied by.
    pub fn scale(&self) -> f64 {
        self.prior_eta_h / self.eta_h
    }

    /// A power of the momentum-theory member under the prior, rescaled to the vehicle's η_h.
    pub fn power_w(&self, prior_w: f64) -> f64 {
        (prior_w - self.avionics_w) * self.scale() + self.avionics_w
    }

    /// An energy over `seconds` forecast under the prior, rescaled likewise, Wh.
    pub fn energy_wh(&self, prior_wh: f64, seconds: f64) -> f64 {
        let avio_wh = self.avionics_w * seconds.max(0.0) / 3600.0;
        ((prior_wh - avio_wh) * self.scale() + avio_wh).max(0.0)
    }
}
