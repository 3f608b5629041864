//! Stolaroff et al.'s thrust × inflow model with momentum-theory induced velocity.
//!
//! P = [(1 − s)·T·(v_a·sin α + v_i) + s·T^1.5/√(2ρA)] / η + p_avio,
//! T = |m·g·ẑ + ½ρ·C_D A·|u|·u|,
//! v_i = T / (2ρA·√((v_a cos α)² + (v_a sin α + v_i)²))   (solved by [`super::induced_velocity`])
//!
//! | symbol | meaning | unit |
//! |---|---|---|
//! | m | total mass | kg |
//! | g | gravitational acceleration | m/s² |
//! | u, v_a | airspeed vector and its magnitude | m/s |
//! | α | angle between the airspeed and the rotor plane (disk normal = measured thrust axis n): v_a·sin α = u·n, v_a·cos α = ‖u − (u·n)n‖ | rad |
//! | ρ | air density | kg/m³ |
//! | C_D A | Σ C_D,k·A_k over body, battery, payload (`drag_area_m2`) | m² |
//! | A | total rotor disk area n·π(D/2)² | m² |
//! | T | thrust | N |
//! | v_i | induced velocity | m/s |
//! | η | power transfer efficiency: `eta` × (m / take-off mass)^`eta_per_ln_mass` (0 but for a spec sheet) | 1 |
//! | s | profile share: the part of the rotors' hover power that is the blades' profile drag, 1 − the figure of merit (`profile_share`; 0 but for a spec sheet) | 1 |
//! | p_avio | constant draw (0 in Stolaroff's equation, free in calibration) | W |
//! | P | electrical power | W |
//!
//! Source: J. K. Stolaroff, C. Samaras, E. R. O'Neill, A. Lubers, A. S. Mitchell,
//! D. Ceperley, "Energy use and life cycle greenhouse gas emissions of drones for commercial
//! package delivery", Nature Communications 9:409, 2018 (Supplementary Note 1).
//!
//! **Physical form.** The comparative study writes T as the scalar sum of weight and drag;
//! in steady flight they are perpendicular and the thrust is their vector sum (what
//! Stolaroff derives), implemented here. α comes from the measured attitude, so climbs
//! (u·n > 0) and descents are covered. Windmilling descents can drive T·(v_a sin α + v_i)
//! negative; motors do not regenerate, so the aerodynamic term is clamped at 0.
//!
//! **Profile power** (`profile_share` s, 2026-11-29). η lumps the rotors' figure of merit
//! (FM) with the motors' and ESCs' efficiency (η_e): η = FM·η_e. With s = 0 every loss
//! scales the induced and parasite power T·(v_n + v_i), so in forward flight the translational
//! lift (v_i falling with the airspeed) relieves the blades' profile drag too, and the
//! parasite power D·v pays 1/FM as well. Blade-element momentum theory keeps them apart:
//! P_rotor = T·(v_n + v_i) + P_0, the profile power P_0 = (1/FM − 1)·T·v_h at the
//! thrust's own rpm (a fixed-pitch rotor's P_0 ∝ Ω³ ∝ T^1.5, as T·v_h is), electrical
//! P_rotor / η_e. With s = 1 − FM that is the form above: the same hover power
//! (T·v_h/η) whatever s, so a measured hover calibrates η alone; in cruise the
//! translational lift relieves only the induced part and the parasite power pays η_e, not
//! η. The profile power's rise with the advance ratio (× (1 + 4.65 μ²), Leishman) is not
//! modelled: a spec sheet does not give the tip speed (about +2 % of the hover power at
//! 10 m/s for the airframes here).

use serde::{Deserialize, Serialize};

use super::{induced_velocity, Kinematics};
use crate::model::profile::VehicleProfile;

/// `[stolaroff]` parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Params {
    /// Power transfer efficiency η, 1.
    pub eta: f64,
    /// Σ C_D·A, m².
    pub drag_area_m2: f64,
    /// Constant draw, W.
    pub p_avio_w: f64,
    /// How η grows with the mass flown, d ln η / d ln m (0: η the same at any mass). A
    /// spec sheet sets the hover-efficiency prior's slope in the disk loading (a rotor's
    /// figure of merit grows with its disk loading, which is the weight's over the same
    /// disk): η at a mass m (payload on board) is `eta` × (m / take-off mass)^this, `eta`
    /// the take-off mass's.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub eta_per_ln_mass: f64,
    /// The share of the rotors' hover power that is the blades' profile power, 1 − the
    /// figure of merit (0–0.9; 0: all of it scales with the induced velocity, as before). A
    /// spec sheet sets the prior ([`crate::model::spec::PROFILE_SHARE`]).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub profile_share: f64,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

impl Params {
    /// η at `mass_kg` for a vehicle whose take-off mass is `takeoff_kg`; the mass ratio held
    /// to 0.5–2 (the payloads a vehicle flies, not an extrapolation of the slope).
    pub fn eta_at(&self, mass_kg: f64, takeoff_kg: f64) -> f64 {
        if self.eta_per_ln_mass == 0.0 || !(mass_kg > 0.0 && takeoff_kg > 0.0) {
            return self.eta;
        }
        self.eta
            * (mass_kg / takeoff_kg)
                .clamp(0.5, 2.0)
                .powf(self.eta_per_ln_mass)
    }
}

/// Electrical power, W.
pub fn power_w(k: &Kinematics, p: &VehicleProfile, m: &Params) -> f64 {
    let t = k.thrust_n(p, m.drag_area_m2);
    let v_n = k.air_m_s.dot(&k.thrust_axis);
    let v_t = (k.air_m_s - v_n * k.thrust_axis).norm();
    let (rho, area) = (p.air.rho_kg_m3, p.disk_area_m2());
    let vi = induced_velocity(t, rho, area, v_t, v_n);
    let s = m.profile_share.clamp(0.0, 0.9);
    let induced = (t * (v_n + vi)).max(0.0);
    let profile = if s > 0.0 {
        t.max(0.0).powf(1.5) / (2.0 * rho * area).sqrt()
    } else {
        0.0
    };
    ((1.0 - s) * induced + s * profile) / m.eta_at(k.mass_kg, p.mass_kg(0.0)) + m.p_avio_w
}

#[cfg(test)]
mod tests {
    use super::super::testutil::*;
    use super::*;

    #[test]
    fn hand_computed_hover_and_climb() {
        let p = VehicleProfile::m100();
        // Hover, no payload: T = W = 23.84811 N, v_i = v_h = √(T/(2ρA)) = √(23.84811/0.839210)
        // = 5.33078 m/s; P = T·v_h/η = 127.129 W / 0.5 = 254.26 W.
        let k = kinematics(sample(1.0, [0.0; 3], 0.0, 0.0, 0.0, 0.0), &p);
        let w = power_w(&k, &p, &p.stolaroff);
        assert!((w - 254.26).abs() < 0.05, "{w}");
        // Vertical climb at 2 m/s (drag 0.5·1.225·0.1·4 = 0.245 N adds to T = 24.09311 N):
        // v_h² = 24.09311/0.839210 = 28.70929; v_i = −1 + √(1 + 28.70929) = 4.45062;
        // P = 24.09311 × (2 + 4.45062) / 0.5 = 310.83 W.
        let k = kinematics(sample(1.0, [0.0, 0.0, 2.0], 0.0, 0.0, 0.0, 0.0), &p);
        let w = power_w(&k, &p, &p.stolaroff);
        assert!((w - 310.83).abs() < 0.05, "{w}");
    }

    #[test]
    fn eta_grows_with_the_mass_flown_when_the_profile_says_so() {
        let mut p = VehicleProfile::m100();
        // The M100's own member: η the same at any payload.
        assert_eq!(p.stolaroff.eta_per_ln_mass, 0.0);
        let loaded = kinematics(sample(1.0, [0.0; 3], 0.0, 0.0, 500.0, 0.0), &p);
        let w0 = power_w(&loaded, &p, &p.stolaroff);
        // d ln η / d ln m = 0.25: with 500 g on 2.431 kg, η × (2.931/2.431)^0.25 = 1.0478 η.
        p.stolaroff.eta_per_ln_mass = 0.25;
        let w1 = power_w(&loaded, &p, &p.stolaroff);
        let k = (2.931f64 / 2.431).powf(0.25);
        assert!((w1 - w0 / k).abs() < 1e-6, "{w0} {w1}");
        // At the take-off mass nothing changes; beyond twice it, no further growth.
        let empty = kinematics(sample(1.0, [0.0; 3], 0.0, 0.0, 0.0, 0.0), &p);
        assert!((power_w(&empty, &p, &p.stolaroff) - 254.26).abs() < 0.05);
        assert_eq!(
            p.stolaroff.eta_at(10.0, 2.431),
            p.stolaroff.eta * 2f64.powf(0.25)
        );
    }

    #[test]
    fn the_profile_share_keeps_the_hover_and_is_not_relieved_by_translational_lift() {
        let mut p = VehicleProfile::m100();
        let hover = kinematics(sample(1.0, [0.0; 3], 0.0, 0.0, 0.0, 0.0), &p);
        // 10 m/s of airspeed (the anemometer's), the thrust axis vertical
        let cruise = kinematics(sample(1.0, [10.0, 0.0, 0.0], 10.0, 0.0, 0.0, 0.0), &p);
        let h0 = power_w(&hover, &p, &p.stolaroff);
        let c0 = power_w(&cruise, &p, &p.stolaroff);
        p.stolaroff.profile_share = 0.35;
        // A hover is T·v_h/η whatever the split: a measured hover calibrates η alone.
        let h1 = power_w(&hover, &p, &p.stolaroff);
        assert!((h1 - h0).abs() < 1e-9, "{h0} {h1}");
        // At 10 m/s the induced velocity falls (v_i < v_h); only 65 % of the hover's rotor
        // power is induced, the profile 35 % stays at the thrust's T^1.5/√(2ρA)/η.
        let c1 = power_w(&cruise, &p, &p.stolaroff);
        let t = cruise.thrust_n(&p, p.stolaroff.drag_area_m2);
        let ideal = t.powf(1.5) / (2.0 * p.air.rho_kg_m3 * p.disk_area_m2()).sqrt();
        let avio = p.stolaroff.p_avio_w;
        let want = 0.65 * (c0 - avio) + 0.35 * ideal / p.stolaroff.eta + avio;
        assert!((c1 - want).abs() < 1e-9, "{c1} {want}");
        assert!(c0 < h0 && c1 > c0 && c1 < h0 + 1e-9, "{h0} {c0} {c1}");
        // Out of range is refused by the profile, naming the key.
        p.stolaroff.profile_share = 0.95;
        let e = p.validate().unwrap_err();
        assert!(e.contains("stolaroff.profile_share"), "{e}");
    }
}
