//! Kirschstein's component model: induced, parasite and profile power plus avionics.
//!
//! P = (κ·T·w + ½ρ·C_D A·v_a³ + κ₂·W^1.5 + κ₃·W^0.5·v_a²) / η + p_avio / η_c
//!
//! | symbol | meaning | unit |
//! |---|---|---|
//! | W | weight m·g (m = airframe + battery + payload) | N |
//! | T | thrust, vector sum of weight and drag (see [`super::Kinematics::thrust_n`]) | N |
//! | w | downwash (induced velocity) in level flight: w = T / (2ρA·√(v_a² + w²)) | m/s |
//! | v_a | airspeed magnitude | m/s |
//! | ρ | air density | kg/m³ |
//! | A | total rotor disk area | m² |
//! | C_D A | Σ C_D·A | m² |
//! | κ | induced power factor | 1 |
//! | κ₂ | profile power coefficient | W/N^1.5 |
//! | κ₃ | profile power growth with speed | W·s²/(m²·N^0.5) |
//! | η | motor + propeller efficiency | 1 |
//! | η_c | the efficiency Kirschstein divides avionics power by | 1 |
//! | p_avio | avionics power | W |
//! | P | electrical power | W |
//!
//! Source: T. Kirschstein, "Comparison of energy demands of drone-based and ground-based
//! parcel delivery services", Transp. Res. D 78, 102209, 2020; notation of Zhang et al. 2021
//! as printed in the comparative study. The level-flight form is implemented, as printed:
//! the downwash is solved with the disk level (v_t = v_a, v_n = 0), and there is no climb
//! term (the paper's equation has none).

use serde::{Deserialize, Serialize};

use super::{induced_velocity, Kinematics};
use crate::model::profile::VehicleProfile;

/// `[kirschstein]` parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Params {
    /// Induced power factor κ, 1.
    pub kappa: f64,
    /// Profile power coefficient κ₂, W/N^1.5.
    pub kappa2: f64,
    /// Profile power speed coefficient κ₃, W·s²/(m²·N^0.5).
    pub kappa3: f64,
    /// Σ C_D·A, m².
    pub drag_area_m2: f64,
    /// Motor + propeller efficiency η, 1.
    pub eta: f64,
    /// Efficiency dividing avionics power, η_c, 1.
    pub eta_c: f64,
    /// Avionics power, W.
    pub p_avio_w: f64,
}

/// Electrical power, W.
pub fn power_w(k: &Kinematics, p: &VehicleProfile, m: &Params) -> f64 {
    let va = k.air_m_s.norm();
    let t = k.thrust_n(p, m.drag_area_m2);
    let w = induced_velocity(t, p.air.rho_kg_m3, p.disk_area_m2(), va, 0.0);
    let wt = k.weight_n(p);
    let aero = m.kappa * t * w
        + 0.5 * p.air.rho_kg_m3 * m.drag_area_m2 * va.powi(3)
        + m.kappa2 * wt.powf(1.5)
        + m.kappa3 * wt.sqrt() * va * va;
    aero.max(0.0) / m.eta + m.p_avio_w / m.eta_c
}

#[cfg(test)]
mod tests {
    use super::super::testutil::*;
    use super::*;

    #[test]
    fn hand_computed_hover() {
        let p = VehicleProfile::m100();
        // Hover, no payload: W = T = 23.84811 N, w = 5.33078 m/s.
        // κTw = 1.15 × 127.129 = 146.198 W; κ₂W^1.5 = 0.23 × 116.4611 = 26.786 W; others 0.
        // P = (146.198 + 26.786)/0.7 + 10/0.9 = 247.120 + 11.111 = 258.23 W.
        let k = kinematics(sample(1.0, [0.0; 3], 0.0, 0.0, 0.0, 0.0), &p);
        let w = power_w(&k, &p, &p.kirschstein);
        assert!((w - 258.23).abs() < 0.05, "{w}");
    }
}
