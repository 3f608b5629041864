//! Dorling et al.'s hover model (momentum theory for n rotors).
//!
//! P = (m·g)^1.5 / (η·√(2·n·ρ·ζ)) + p_avio
//!
//! | symbol | meaning | unit |
//! |---|---|---|
//! | m | total mass: airframe + battery + payload | kg |
//! | g | gravitational acceleration | m/s² |
//! | n | number of rotors | 1 |
//! | ρ | air density | kg/m³ |
//! | ζ | disk area of one rotor, π·(D/2)² | m² |
//! | η | overall efficiency (1 = ideal; not in Dorling's equation, free in calibration) | 1 |
//! | p_avio | constant draw (0 in Dorling's equation, free in calibration) | W |
//! | P | electrical power | W |
//!
//! Source: K. Dorling, J. Heinrichs, G. G. Messier, S. Magierowski, "Vehicle routing
//! problems for drone delivery", IEEE T-SMC: Systems 47(1), 2017, eq. (4).
//!
//! **Units.** The comparative study prints g·(Σm)^1.5 / √(2nρζ), which is not a power
//! (kg^1.5·m/s² ÷ (kg^0.5/m^0.5) = kg·m^1.5/s²). Dorling's own form is the ideal induced
//! power of the thrust m·g spread over n disks, T^1.5/√(2ρ·nζ) = (m·g)^1.5/√(2nρζ), in W;
//! that is what is implemented. It ignores motion entirely: a hover model.

use serde::{Deserialize, Serialize};

use super::Kinematics;
use crate::model::profile::VehicleProfile;

/// `[dorling]` parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Params {
    /// Overall efficiency η, 1.
    pub eta: f64,
    /// Constant draw, W.
    pub p_avio_w: f64,
}

/// Electrical power, W.
pub fn power_w(k: &Kinematics, p: &VehicleProfile, m: &Params) -> f64 {
    let zeta = p.disk_area_m2() / f64::from(p.vehicle.rotors);
    let n = f64::from(p.vehicle.rotors);
    k.weight_n(p).powf(1.5) / (m.eta * (2.0 * n * p.air.rho_kg_m3 * zeta).sqrt()) + m.p_avio_w
}

#[cfg(test)]
mod tests {
    use super::super::testutil::*;
    use super::*;

    #[test]
    fn hand_computed() {
        let p = VehicleProfile::m100();
        // m = 2.431 kg (no payload): W = 23.84811 N; W^1.5 = 116.4626;
        // 2·n·ρ·ζ = 2 × 1.225 × 0.342530 m² = 0.839199; √ = 0.916079; P = 127.131 W.
        let k = kinematics(sample(1.0, [0.0; 3], 0.0, 0.0, 0.0, 0.0), &p);
        let w = power_w(&k, &p, &p.dorling);
        assert!((w - 127.13).abs() < 0.02, "{w}");
        // Hover induced power T·v_h equals it (same physics).
        let t = k.weight_n(&p);
        let vi = super::super::induced_velocity(t, 1.225, p.disk_area_m2(), 0.0, 0.0);
        assert!((t * vi - w).abs() < 1e-6);
    }
}
