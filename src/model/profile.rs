//! Vehicle profiles: the airframe facts and the physics models' parameters, in one TOML
//! file per vehicle (`config/vehicles/*.toml`). The physics models read nothing else, so a
//! profile is the whole difference between "as published" and "calibrated".
//!
//! The built-in default ([`VehicleProfile::m100`]) is `config/vehicles/m100.toml`, compiled
//! in, so a fresh install without the config folder still gets the DJI Matrice 100.

use std::path::Path;

use anyhow::Context;
use serde::{Deserialize, Serialize};

use super::physics::{dandrea, dorling, kirschstein, stolaroff, tseng};

/// The M100 profile as shipped (`config/vehicles/m100.toml`).
pub const M100_TOML: &str = include_str!("../../config/vehicles/m100.toml");

/// One vehicle: airframe, air, and each physics model's parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VehicleProfile {
    /// Human-readable name, shown in reports.
    pub name: String,
    /// Masses and geometry.
    pub vehicle: Airframe,
    /// Air density and gravity.
    pub air: Air,
    /// D'Andrea (no wind): `[dandrea]`.
    pub dandrea: dandrea::Params,
    /// D'Andrea with headwind: `[dandrea_headwind]` (same parameters, fitted separately).
    pub dandrea_headwind: dandrea::Params,
    /// Dorling et al.: `[dorling]`.
    pub dorling: dorling::Params,
    /// Stolaroff et al.: `[stolaroff]`.
    pub stolaroff: stolaroff::Params,
    /// Kirschstein: `[kirschstein]`.
    pub kirschstein: kirschstein::Params,
    /// Tseng et al., nine-term Matrice 100 regression: `[tseng]`.
    pub tseng: tseng::Params,
    /// Tseng et al., simplified 3DR Solo form as printed in the paper: `[tseng_solo]`.
    pub tseng_solo: tseng::SoloParams,
    /// Present only in a profile written by `dronewatt calibrate`: models built from it
    /// are named with a `_cal` suffix.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration: Option<Calibration>,
}

/// Airframe facts (DJI's published figures for the M100).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Airframe {
    /// Airframe mass without battery, kg.
    pub airframe_kg: f64,
    /// Battery mass, kg.
    pub battery_kg: f64,
    /// Number of rotors.
    pub rotors: u32,
    /// Propeller diameter, m.
    pub prop_diameter_m: f64,
    /// Motor-to-motor diagonal, m (documentation; no model uses it).
    pub diagonal_m: f64,
    /// Maximum take-off mass, kg (documentation; no model uses it).
    pub mtow_kg: f64,
}

/// The atmosphere the models assume.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Air {
    /// Air density, kg/m³.
    pub rho_kg_m3: f64,
    /// Gravitational acceleration, m/s².
    pub g_m_s2: f64,
}

/// Where a calibrated profile's numbers came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Calibration {
    /// sha256 of the data file fitted on.
    pub data_sha256: String,
    /// The training flights used (never one of `offline::data::TEST_FLIGHTS`).
    pub flights: Vec<u32>,
    /// In-flight windows (measured > 100 W) used in the fit.
    pub windows: usize,
}

impl VehicleProfile {
    /// The built-in DJI Matrice 100 profile (identical to `config/vehicles/m100.toml`).
    pub fn m100() -> Self {
        // The embedded file is checked by a unit test; a parse failure here is a build defect.
        Self::from_toml(M100_TOML, "built-in m100.toml").unwrap_or_else(|e| panic!("{e:#}"))
    }

    /// Parse and validate profile text; `origin` names it in errors.
    pub fn from_toml(text: &str, origin: &str) -> anyhow::Result<Self> {
        let p: VehicleProfile = toml::from_str(text).with_context(|| format!("{origin}: not a valid vehicle profile"))?;
        p.validate().map_err(|e| anyhow::anyhow!("{origin}: {e}"))?;
        Ok(p)
    }

    /// Read a profile file.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| format!("{}: cannot read vehicle profile", path.display()))?;
        Self::from_toml(&text, &path.display().to_string())
    }

    /// Total mass for a payload, kg.
    pub fn mass_kg(&self, payload_kg: f64) -> f64 {
        self.vehicle.airframe_kg + self.vehicle.battery_kg + payload_kg
    }

    /// Total rotor disk area n·π·(D/2)², m².
    pub fn disk_area_m2(&self) -> f64 {
        let r = self.vehicle.prop_diameter_m / 2.0;
        f64::from(self.vehicle.rotors) * std::f64::consts::PI * r * r
    }

    /// Range checks serde cannot express; the message names the key.
    pub fn validate(&self) -> Result<(), String> {
        let pos = |k: &str, v: f64| if v.is_finite() && v > 0.0 { Ok(()) } else { Err(format!("{k} = {v}: must be > 0")) };
        pos("vehicle.airframe_kg", self.vehicle.airframe_kg)?;
        pos("vehicle.battery_kg", self.vehicle.battery_kg)?;
        pos("vehicle.prop_diameter_m", self.vehicle.prop_diameter_m)?;
        pos("air.rho_kg_m3", self.air.rho_kg_m3)?;
        pos("air.g_m_s2", self.air.g_m_s2)?;
        if self.vehicle.rotors == 0 {
            return Err("vehicle.rotors = 0: must be ≥ 1".into());
        }
        pos("dandrea.eta", self.dandrea.eta)?;
        pos("dandrea.lift_drag", self.dandrea.lift_drag)?;
        pos("dandrea_headwind.eta", self.dandrea_headwind.eta)?;
        pos("dandrea_headwind.lift_drag", self.dandrea_headwind.lift_drag)?;
        pos("dorling.eta", self.dorling.eta)?;
        pos("stolaroff.eta", self.stolaroff.eta)?;
        pos("kirschstein.eta", self.kirschstein.eta)?;
        pos("kirschstein.eta_c", self.kirschstein.eta_c)?;
        let fin = |k: &str, v: f64| if v.is_finite() { Ok(()) } else { Err(format!("{k} = {v}: must be finite")) };
        for (i, b) in self.tseng.beta.iter().enumerate() {
            fin(&format!("tseng.beta[{i}]"), *b)?;
        }
        for (i, b) in self.tseng_solo.coef.iter().enumerate() {
            fin(&format!("tseng_solo.coef[{i}]"), *b)?;
        }
        Ok(())
    }

    /// `"_cal"` for a calibrated profile, `""` otherwise: appended to model names.
    pub fn name_suffix(&self) -> &'static str {
        if self.calibration.is_some() {
            "_cal"
        } else {
            ""
        }
    }
}

impl Default for VehicleProfile {
    fn default() -> Self {
        Self::m100()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_parses_and_matches_dji_figures() {
        let p = VehicleProfile::m100();
        assert_eq!(p.vehicle.rotors, 4);
        assert!((p.mass_kg(0.0) - (1.755 + 0.676)).abs() < 1e-12);
        // 13-inch props: 4·π·0.1651² = 0.3425 m².
        assert!((p.disk_area_m2() - 0.34253).abs() < 1e-4);
        assert!(p.calibration.is_none());
    }

    #[test]
    fn roundtrip_and_unknown_keys_rejected() {
        let p = VehicleProfile::m100();
        let text = toml::to_string(&p).unwrap();
        assert_eq!(VehicleProfile::from_toml(&text, "x").unwrap(), p);
        let bad = format!("{text}\nbogus = 1\n");
        let e = VehicleProfile::from_toml(&bad, "bad.toml").unwrap_err();
        assert!(format!("{e:#}").contains("bad.toml"));
        let neg = text.replace("rho_kg_m3 = 1.225", "rho_kg_m3 = -1.0");
        assert!(format!("{:#}", VehicleProfile::from_toml(&neg, "n").unwrap_err()).contains("rho_kg_m3"));
    }
}
