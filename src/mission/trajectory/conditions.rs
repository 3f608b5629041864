//! What a plan is flown with: the vehicle's kinematics (`[forecast.kinematics]`), the wind
//! and the rest of the conditions.

use nalgebra::Vector3;

/// How the vehicle flies a mission (`[forecast.kinematics]`).
#[derive(Debug, Clone, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct KinematicsConfig {
    /// Motors running on the ground before lift-off (the spin-up from arming to leaving
    /// the ground), s: part of the take-off, flown at hover. Default 4.4 (the M100's).
    pub spinup_s: f64,
    /// Vertical climb rate on take-off and on climbing legs, m/s. Default 3.0.
    pub climb_m_s: f64,
    /// Vertical descent rate above `slow_below_m`, m/s. Default 2.7.
    pub descent_m_s: f64,
    /// Descent rate below `slow_below_m` (the landing), m/s. Default 1.0.
    pub land_m_s: f64,
    /// Height above home under which the descent slows to `land_m_s`, m. Default 20.
    pub slow_below_m: f64,
    /// Horizontal acceleration and deceleration, m/s². Default 2.5.
    pub accel_m_s2: f64,
    /// Pause at every stop (after take-off, at each waypoint, before landing), s. Default 1.9.
    pub waypoint_pause_s: f64,
    /// Cruise speed when neither the plan nor the command line gives one, m/s. Default 10.
    pub default_speed_m_s: f64,
    /// Thrust tilt per airspeed², 1/m: tan θ = c·|u|². Default 0.0016 (9° at 10 m/s).
    pub tilt_per_airspeed2: f64,
}

impl Default for KinematicsConfig {
    fn default() -> Self {
        Self {
            spinup_s: 4.4,
            climb_m_s: 3.0,
            descent_m_s: 2.7,
            land_m_s: 1.0,
            slow_below_m: 20.0,
            accel_m_s2: 2.5,
            waypoint_pause_s: 1.9,
            default_speed_m_s: 10.0,
            tilt_per_airspeed2: 0.0016,
        }
    }
}

impl KinematicsConfig {
    /// Range checks; the message names the key.
    pub fn validate(&self) -> Result<(), String> {
        use crate::validate::{above, in_range};
        let key = |k: &str| format!("forecast.kinematics.{k}");
        for (k, v, unit) in [
            ("climb_m_s", self.climb_m_s, "m/s"),
            ("descent_m_s", self.descent_m_s, "m/s"),
            ("land_m_s", self.land_m_s, "m/s"),
            ("accel_m_s2", self.accel_m_s2, "m/s²"),
            ("default_speed_m_s", self.default_speed_m_s, "m/s"),
        ] {
            in_range(&key(k), v, above(0.0), unit)?;
        }
        for (k, v, unit) in [
            ("spinup_s", self.spinup_s, "s"),
            ("slow_below_m", self.slow_below_m, "m"),
            ("waypoint_pause_s", self.waypoint_pause_s, "s"),
            ("tilt_per_airspeed2", self.tilt_per_airspeed2, ""),
        ] {
            in_range(&key(k), v, 0.0.., unit)?;
        }
        Ok(())
    }
}

impl KinematicsConfig {
    /// The same kinematics with the thrust tilted as a body of drag area `drag_area_m2` (m²)
    /// and mass `mass_kg` tilts it: tan θ = D / W = ½ρ·C_D·A·u² / (m·g), so
    /// `tilt_per_airspeed2` = ρ·C_D·A / (2·m·g). The default (0.0016, 9° at 10 m/s) is the
    /// M100's, as its data set shows; a vehicle whose forecast is momentum theory with its
    /// own drag (a spec sheet's) flies its plans at its own tilt, so the member's parasite
    /// power (thrust × the airspeed along the tilted thrust axis) is its own drag × airspeed,
    /// not the M100's (a 10.7 kg octocopter at 0.0006 paid 2.6 × its drag's parasite power
    /// at the M100's tilt). A value the configuration sets (another than the default) is
    /// kept, and so is the default when the drag or the mass is not a number it can use.
    pub fn with_tilt_of(mut self, drag_area_m2: f64, mass_kg: f64, rho: f64, g: f64) -> Self {
        let own = rho * drag_area_m2 / (2.0 * mass_kg * g);
        let unset = self.tilt_per_airspeed2 == Self::default().tilt_per_airspeed2;
        if unset && own.is_finite() && own >= 0.0 && mass_kg > 0.0 {
            self.tilt_per_airspeed2 = own;
        }
        self
    }

    /// [`Self::with_tilt_of`] the momentum-theory member's drag (`[stolaroff] drag_area_m2`)
    /// and the profile's mass with `payload_g` on board: how `plan` and the live mission
    /// forecast fly a vehicle whose forecast is that member (a spec sheet's, or the store's
    /// hover-calibrated one).
    pub fn tilted_as(&self, p: &crate::model::profile::VehicleProfile, payload_g: f64) -> Self {
        self.clone().with_tilt_of(
            p.stolaroff.drag_area_m2,
            p.mass_kg(payload_g / 1000.0),
            p.air.rho_kg_m3,
            p.air.g_m_s2,
        )
    }
}

/// Ambient wind: speed and the bearing it blows from (meteorological convention).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Wind {
    /// m/s.
    pub speed_m_s: f64,
    /// Bearing the wind comes from, deg clockwise from north.
    pub from_deg: f64,
}

impl Wind {
    /// The air's velocity over the ground, ENU m/s (it blows *toward* `from_deg + 180°`).
    pub fn velocity_enu(&self) -> Vector3<f64> {
        let b = self.from_deg.to_radians();
        Vector3::new(-self.speed_m_s * b.sin(), -self.speed_m_s * b.cos(), 0.0)
    }
}

impl std::str::FromStr for Wind {
    type Err = String;
    /// `SPEED@FROM_DEG`, e.g. `5@270` (5 m/s from the west).
    fn from_str(s: &str) -> Result<Self, String> {
        let (a, b) = s
            .split_once('@')
            .ok_or_else(|| format!("wind {s:?}: expected SPEED@FROM_DEG, e.g. 5@270"))?;
        let speed_m_s: f64 = a
            .trim()
            .parse()
            .map_err(|_| format!("wind {s:?}: speed {a:?} is not a number"))?;
        let from_deg: f64 = b
            .trim()
            .parse()
            .map_err(|_| format!("wind {s:?}: bearing {b:?} is not a number"))?;
        if !(speed_m_s.is_finite() && (0.0..=40.0).contains(&speed_m_s)) {
            return Err(format!("wind {s:?}: speed must be 0..40 m/s"));
        }
        if !from_deg.is_finite() {
            return Err(format!("wind {s:?}: bearing must be a number of degrees"));
        }
        Ok(Wind {
            speed_m_s,
            from_deg: from_deg.rem_euclid(360.0),
        })
    }
}

/// What the trajectory needs besides the plan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Conditions {
    /// Ambient wind.
    pub wind: Wind,
    /// Payload, g.
    pub payload_g: f64,
    /// Cruise speed until a DO_CHANGE_SPEED, m/s (overrides the plan's `hoverSpeed`).
    pub speed_m_s: Option<f64>,
    /// Sample rate, Hz (the models' rate).
    pub rate_hz: f64,
}

#[cfg(test)]
mod tests {
    use super::KinematicsConfig;

    #[test]
    fn the_tilt_is_the_vehicles_own_drag_over_its_weight() {
        let k = KinematicsConfig::default().with_tilt_of(0.106, 10.66, 1.225, 9.81);
        let c = 1.225 * 0.106 / (2.0 * 10.66 * 9.81);
        assert!(
            (k.tilt_per_airspeed2 - c).abs() < 1e-12,
            "{}",
            k.tilt_per_airspeed2
        );
        // at 10 m/s: tan θ = D / W
        let d = 0.5 * 1.225 * 0.106 * 100.0;
        assert!((k.tilt_per_airspeed2 * 100.0 - d / (10.66 * 9.81)).abs() < 1e-12);
        // the rest of the kinematics is untouched
        assert_eq!(
            KinematicsConfig {
                tilt_per_airspeed2: 0.0016,
                ..k.clone()
            },
            KinematicsConfig::default()
        );
    }

    #[test]
    fn a_spec_sheet_flies_at_the_tilt_of_its_own_drag_and_loaded_mass() {
        let p = crate::model::profile::VehicleProfile::from_toml(
            "name = \"Spec quad\"\n[vehicle]\ntakeoff_kg = 1.3\nrotors = 4\nprop_diameter_m = 0.254\n\
             [battery]\ncells = 3\ncapacity_mah = 5100\nchemistry = \"lipo\"\n",
            "spec.toml",
        )
        .unwrap();
        let (rho, g) = (p.air.rho_kg_m3, p.air.g_m_s2);
        let cda = p.stolaroff.drag_area_m2;
        assert!(
            (cda - 0.0249 * 1.3f64.powf(2.0 / 3.0)).abs() < 1e-9,
            "{cda}"
        );
        let k = KinematicsConfig::default().tilted_as(&p, 0.0);
        let c = rho * cda / (2.0 * 1.3 * g);
        assert!(
            (k.tilt_per_airspeed2 - c).abs() < 1e-9,
            "{}",
            k.tilt_per_airspeed2
        );
        // 500 g on board: the same drag over a heavier weight tilts it less
        let loaded = KinematicsConfig::default().tilted_as(&p, 500.0);
        assert!((loaded.tilt_per_airspeed2 - c * 1.3 / 1.8).abs() < 1e-9);
    }

    #[test]
    fn a_configured_tilt_or_an_unusable_drag_keeps_the_tilt() {
        let set = KinematicsConfig {
            tilt_per_airspeed2: 0.003,
            ..KinematicsConfig::default()
        };
        assert_eq!(set.clone().with_tilt_of(0.1, 2.0, 1.225, 9.81), set);
        let d = KinematicsConfig::default();
        for (cda, kg) in [(f64::NAN, 2.0), (-0.1, 2.0), (0.1, 0.0), (0.1, f64::NAN)] {
            assert_eq!(
                d.clone().with_tilt_of(cda, kg, 1.225, 9.81),
                d,
                "{cda} {kg}"
            );
        }
    }
}
