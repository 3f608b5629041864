//! D'Andrea's lift-to-drag model, with and without headwind.
//!
//! P = m·g·v / (η·r) + p_avio
//!
//! | symbol | meaning | unit |
//! |---|---|---|
//! | m | total mass: airframe + battery + payload (m₁ + m₂ + m₃) | kg |
//! | g | gravitational acceleration | m/s² |
//! | v | `dandrea`: horizontal airspeed ‖u_xy‖ (the anemometer's); `dandrea_headwind`: ground speed + headwind, ‖v_xy‖ + h | m/s |
//! | η | power transfer efficiency | 1 |
//! | r | lift-to-drag ratio | 1 |
//! | p_avio | avionics power | W |
//! | P | electrical power | W |
//!
//! Source: R. D'Andrea, "Guest editorial: Can drones deliver?", IEEE T-ASE 11(3), 2014;
//! headwind variant and unified notation: Zhang et al., Transp. Res. D 90, 2021.
//!
//! **Units.** The comparative study prints P = Σm·v_a / (370·η·r) + p_avio: its 370 is
//! 3600/g ≈ 367, valid only for m in kg, v in km/h and P in kW. The form here is the same
//! law in SI (P in W), so the constant disappears into g.
//!
//! **Headwind.** The headwind variant charges the drone for the ground distance it covers
//! plus the wind it flies into: v = ‖v_xy‖ + h with h = −w·v̂ (see
//! [`super::Kinematics::headwind`]), clamped at 0. The two variants differ when the wind
//! blows across the track. Neither gives any lift power in hover (v = 0): the model is for
//! steady cruise, as D'Andrea says.

use serde::{Deserialize, Serialize};

use super::Kinematics;
use crate::model::profile::VehicleProfile;

/// `[dandrea]` / `[dandrea_headwind]` parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Params {
    /// Power transfer efficiency η, 1.
    pub eta: f64,
    /// Lift-to-drag ratio r, 1.
    pub lift_drag: f64,
    /// Avionics power, W.
    pub p_avio_w: f64,
}

/// The speed the model charges for, m/s.
pub fn speed_m_s(k: &Kinematics, headwind: bool) -> f64 {
    if headwind {
        (k.ground_m_s.xy().norm() + k.headwind()).max(0.0)
    } else {
        k.airspeed_h()
    }
}

/// Electrical power, W.
pub fn power_w(k: &Kinematics, p: &VehicleProfile, m: &Params, headwind: bool) -> f64 {
    k.weight_n(p) * speed_m_s(k, headwind) / (m.eta * m.lift_drag) + m.p_avio_w
}

#[cfg(test)]
mod tests {
    use super::super::testutil::*;
    use super::*;

    #[test]
    fn hand_computed() {
        // m = 1.755 + 0.676 + 0.5 = 2.931 kg; W = 28.753 N. Anemometer 12 m/s.
        // P = 28.753 N × 12 m/s / (0.5 × 3) + 100 W = 230.02 + 100 = 330.02 W.
        let (p, k) = m100_north_at_10(12.0, 0.0);
        let w = power_w(&k, &p, &p.dandrea, false);
        assert!((w - 330.0244).abs() < 1e-3, "{w}");
        // Headwind: ground 10 m/s north, air 12 m/s north → 2 m/s headwind, v = 12 m/s again.
        assert!((power_w(&k, &p, &p.dandrea_headwind, true) - w).abs() < 1e-3);
        // Crosswind: air 12 m/s toward 30° east of north while tracking north at 10 m/s:
        // w = (−6, 10 − 10.392) → headwind 0.392 m/s; v = 10.392 m/s; P = 28.753·10.392/1.5 + 100.
        let k = kinematics(north_at_10(12.0, 30.0), &p);
        let hw = power_w(&k, &p, &p.dandrea_headwind, true);
        assert!(
            (hw - (28.75311 * 10.392305 / 1.5 + 100.0)).abs() < 1e-2,
            "{hw}"
        );
        assert!((power_w(&k, &p, &p.dandrea, false) - w).abs() < 1e-3);
    }
}
