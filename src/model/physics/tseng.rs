//! Tseng et al.'s regression models: the nine-term Matrice 100 model and the 3DR Solo form.
//!
//! Nine-term (M100):
//! P = β₁‖v_xy‖ + β₂‖a_xy‖ + β₃‖v_xy‖‖a_xy‖ + β₄‖v_z‖ + β₅‖a_z‖ + β₆‖v_z‖‖a_z‖ + β₇·m + β₈·(v_xy·w_xy) + β₉
//!
//! Simplified (3DR Solo, as printed in the comparative study): P = c₁·v_a + c₂·m₃ + c₃
//!
//! | symbol | meaning | unit |
//! |---|---|---|
//! | v_xy, v_z | horizontal / vertical ground velocity | m/s |
//! | a_xy, a_z | horizontal / vertical ground acceleration (window finite difference) | m/s² |
//! | w_xy | horizontal ambient wind (ground − air velocity) | m/s |
//! | m, m₃ | payload | g |
//! | v_a | horizontal airspeed | m/s |
//! | β₁…β₉, c₁…c₃ | regression coefficients, in the units that make each term W | — |
//! | P | electrical power | W |
//!
//! Source: C.-M. Tseng, C.-K. Chau, K. Elbassioni, M. Khonji, "Autonomous recharging and
//! flight mission planning for battery-operated autonomous drones", arXiv:1703.10049 (2017),
//! fitted on a DJI Matrice 100 with 0, 0.3 and 0.6 kg payloads; published coefficients as
//! tabulated by Zhang et al. 2021. The Solo form is the comparative study's eq. (5).
//! Both are linear in their coefficients, so calibration is an ordinary least-squares fit
//! of [`features`] / [`solo_features`].

use serde::{Deserialize, Serialize};

use super::Kinematics;

/// `[tseng]` parameters: β₁…β₉.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Params {
    pub beta: [f64; 9],
}

/// `[tseng_solo]` parameters: c₁ (W·s/m), c₂ (W/g), c₃ (W).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SoloParams {
    pub coef: [f64; 3],
}

/// The nine regressors of the M100 model, in β order.
pub fn features(k: &Kinematics) -> [f64; 9] {
    let v = k.ground_m_s.xy().norm();
    let a = k.accel_m_s2.xy().norm();
    let vz = k.ground_m_s.z.abs();
    let az = k.accel_m_s2.z.abs();
    [
        v,
        a,
        v * a,
        vz,
        az,
        vz * az,
        k.payload_g,
        k.ground_m_s.xy().dot(&k.wind_m_s.xy()),
        1.0,
    ]
}

/// The three regressors of the Solo form, in c order.
pub fn solo_features(k: &Kinematics) -> [f64; 3] {
    [k.airspeed_h(), k.payload_g, 1.0]
}

/// Nine-term model power, W.
pub fn power_w(k: &Kinematics, m: &Params) -> f64 {
    features(k).iter().zip(&m.beta).map(|(x, b)| x * b).sum()
}

/// Solo form power, W.
pub fn solo_power_w(k: &Kinematics, m: &SoloParams) -> f64 {
    solo_features(k)
        .iter()
        .zip(&m.coef)
        .map(|(x, b)| x * b)
        .sum()
}

#[cfg(test)]
mod tests {
    use super::super::testutil::*;
    use super::*;

    #[test]
    fn hand_computed() {
        // Heading north at 10 m/s, anemometer 12 m/s north → wind (0, −2): v·w = −20 m²/s².
        // Window: 0.9 s earlier the same velocity → a = 0. Payload 500 g.
        // P = −1.526·10 + 0.220·500 + 1.332·(−20) + 433.9 = −15.26 + 110 − 26.64 + 433.9 = 502.0 W.
        let (p, k) = m100_north_at_10(12.0, 0.0);
        assert!((power_w(&k, &p.tseng) - 502.0).abs() < 1e-3);
        // Solo: −2.595·12 + 0.197·500 + 251.7 = −31.14 + 98.5 + 251.7 = 319.06 W.
        assert!((solo_power_w(&k, &p.tseng_solo) - 319.06).abs() < 1e-3);
        // Acceleration 1 m/s² forward over the window adds β₂·1 + β₃·10·1 = 3.934 + 9.68.
        let mut w = window(north_at_10(12.0, 0.0));
        w.samples[0].features[crate::features::idx::VX] = 9.1;
        let k = Kinematics::from_window(&w, &p);
        assert!((power_w(&k, &p.tseng) - (502.0 + 3.934 + 9.68)).abs() < 1e-3);
    }
}
