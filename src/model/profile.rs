//! Vehicle profiles: the airframe facts and the physics models' parameters, in one TOML
//! file per vehicle (`config/vehicles/*.toml`). The physics models read nothing else, so a
//! profile is the whole difference between "as published" and "calibrated".
//!
//! The built-in default ([`VehicleProfile::m100`]) is `config/vehicles/m100.toml`, compiled
//! in, so a fresh install without the config folder still gets the DJI Matrice 100.
//!
//! ## What the simulator reads
//!
//! `dronewatt simulate` flies the same profile: `[vehicle]` (masses, rotor count and
//! diameter), `[air]` (density) and four sections the physics models do not read —
//! `[rotor]` (induced-power factor, solidity, blade drag, thrust coefficient), `[body]`
//! (flat-plate drag area), `[powertrain]` (efficiency, avionics and idle power) and
//! `[battery]` (cells, capacity, internal resistance, open-circuit voltage curve). They are
//! optional, so a profile written for the models alone still loads; the simulator refuses
//! one that lacks them, naming the section. One airframe, one file: the M100 the models
//! assume is the M100 the simulator flies.

use std::path::Path;

use anyhow::Context;
use serde::{Deserialize, Serialize};

use super::physics::{dandrea, dorling, kirschstein, stolaroff, tseng};

/// The M100 profile as shipped (`config/vehicles/m100.toml`).
pub const M100_TOML: &str = include_str!("../../config/vehicles/m100.toml");

/// The profiles compiled in, by the name `--vehicle` takes: the M100, a Holybro X500 V2
/// class 4S quad, a 1 kg 3S quad, a 2 kg foam plane, a quadplane (`config/vehicles/NAME.toml`).
pub const BUILT_IN: [(&str, &str); 5] = [
    ("m100", M100_TOML),
    ("x500", include_str!("../../config/vehicles/x500.toml")),
    (
        "quad-3s",
        include_str!("../../config/vehicles/quad-3s.toml"),
    ),
    ("plane", include_str!("../../config/vehicles/plane.toml")),
    (
        "quadplane",
        include_str!("../../config/vehicles/quadplane.toml"),
    ),
];

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
    /// `[fixed_wing]`: the plane's figures for the fixed-wing model (optional: a generic
    /// 2 kg foam plane's without it; [`crate::model::physics::fixed_wing::Params`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fixed_wing: Option<crate::model::physics::fixed_wing::Params>,
    /// `[fixed_wing_flight]`: how the plane flies a mission (cruise airspeed, bank limit,
    /// climb and sink, loiter radius, glide slope; a VTOL's hover climb, landing and
    /// transitions), for the mission forecast (optional: the autopilots' defaults without
    /// it; [`crate::model::physics::fixed_wing::Flight`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fixed_wing_flight: Option<crate::model::physics::fixed_wing::Flight>,
    /// `[rotor]`: the simulator's rotor aerodynamics (optional; see the module docs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotor: Option<Rotor>,
    /// `[body]`: the simulator's body drag (optional).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub body: Option<Body>,
    /// `[powertrain]`: the simulator's motor/ESC efficiency and constant loads (optional).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub powertrain: Option<Powertrain>,
    /// `[battery]`: the pack (optional; the simulator needs it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub battery: Option<Battery>,
    /// `[plane]`: the simulator's wing and forward-flight powertrain, the truth a simulated
    /// plane or quadplane flies (optional; `simulate` flies a plane when it is present).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plane: Option<PlaneSim>,
    /// Present only in a profile written by `dronewatt-lab calibrate`: models built from it
    /// are named with a `_cal` suffix.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration: Option<Calibration>,
    /// `[forecast]`: the model the forecast starts from on this vehicle (written by
    /// `dronewatt learn`, picked on held-out logs; optional).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub forecast: Option<ForecastDefault>,
    /// The LSTM model folder fine-tuned for this vehicle (`dronewatt learn --fine-tune`),
    /// relative to the profile file; it runs instead of the shipped one unless the config
    /// sets `[models.lstm] path`. Optional.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lstm: Option<std::path::PathBuf>,
    /// Physics models whose published parameters do not describe this airframe (e.g. the
    /// M100's and the 3DR Solo's regressions on another quad): they still run, but `plan`
    /// leaves them out of the forecast's mean, saying so. A top-level key. Default none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub does_not_transfer: Vec<String>,
}

/// `[forecast]`: which model the energy forecast starts from on this vehicle, unless the
/// config's `[energy] model` says otherwise (online selection, `[energy.select]`, may still
/// move it on the vehicle's own evidence).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ForecastDefault {
    /// The model's name as it runs from this profile (`stolaroff_cal`, `lstm`, …).
    pub model: String,
    /// Why it was picked (shown as the forecast's reason).
    #[serde(default)]
    pub why: String,
    /// Multipliers on models' power in the pre-flight forecast (`dronewatt plan`), by model
    /// name (a VTOL's rotor model and `fixed_wing`), fitted on fit plans
    /// (`lab/scripts/plane-mission-eval.py --set fit` for the simulated planes); absent: 1.
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub scale: std::collections::BTreeMap<String, f64>,
    /// P90 over P50 of the pre-flight forecast, fitted beside `scale`; absent: 1.15.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub p90_ratio: Option<f64>,
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
    /// Maximum take-off mass, kg (no model uses it; the simulator's payload limit is
    /// `mtow_kg − airframe_kg − battery_kg`).
    pub mtow_kg: f64,
    /// The vehicle class, `multirotor`, `fixed_wing`, `vtol` or `other`: wins over the
    /// HEARTBEAT's type (which picks it when this is absent). Optional.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub class: Option<crate::features::VehicleClass>,
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

/// `[rotor]`: momentum theory with a blade-element profile term, per rotor of diameter
/// `vehicle.prop_diameter_m`:
/// `P_induced = kappa·T·v_i`, `P_profile = N·(solidity·blade_cd0/8)·ρ·A·(ΩR)³·(1 + 4.65 μ²)`
/// with the tip speed `ΩR = √(T_r / (thrust_coefficient·ρ·A))`. Their ratio to the ideal
/// hover power `T^1.5/√(2ρA_total)` is the rotor's figure of merit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rotor {
    /// Induced-power factor κ (non-uniform inflow, tip loss), 1; usually 1.1–1.2.
    pub kappa: f64,
    /// Rotor solidity σ = blades·chord / (π·R), 1.
    pub solidity: f64,
    /// Blade section profile drag coefficient C_d0, 1.
    pub blade_cd0: f64,
    /// Hover thrust coefficient C_T = T / (ρ·A·(ΩR)²), 1: sets the tip speed for a thrust.
    pub thrust_coefficient: f64,
}

/// `[body]`: parasitic drag `D = ½ρ·drag_area_m2·|v_a|²` against the air-relative velocity.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Body {
    /// Flat-plate drag area C_D·A of body, arms, battery and payload, m².
    pub drag_area_m2: f64,
}

/// `[powertrain]`: `P_elec = P_mech / efficiency + avionics_w` in the air; `idle_w` on the
/// ground with the motors armed and idling.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Powertrain {
    /// Rotor mechanical power (momentum theory) → battery power efficiency, 1, in (0, 1]:
    /// motors × ESCs × what momentum theory leaves out.
    pub efficiency: f64,
    /// Constant electrical draw of flight controller, GNSS, radios and sensors, W.
    pub avionics_w: f64,
    /// Draw on the ground, armed, props idling (avionics included), W.
    pub idle_w: f64,
}

/// `[plane]`: what a simulated plane (or a quadplane's wing and pusher) really is, the
/// simulator's truth (`crate::sim::plane`; never read by the power models, whose figures
/// are `[fixed_wing]`). The mass is `[vehicle] airframe_kg + battery_kg` (+ payload).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlaneSim {
    /// Wing area S, m².
    pub wing_area_m2: f64,
    /// Span b, m.
    pub span_m: f64,
    /// Zero-lift drag coefficient at `cd0_ref_mps` (skin friction falls as Re^-0.2 above it), 1.
    pub cd0: f64,
    /// Airspeed at which `cd0` holds, m/s.
    pub cd0_ref_mps: f64,
    /// Oswald efficiency of the real wing, 1.
    pub oswald_e: f64,
    /// Maximum lift coefficient (sets the stall speed), 1.
    pub cl_max: f64,
    /// Cruise airspeed, m/s (the default commanded speed).
    pub cruise_mps: f64,
    /// Bank limit, deg (ArduPlane `ROLL_LIMIT_DEG`).
    pub bank_limit_deg: f64,
    /// Forward propeller diameter, m.
    pub prop_diameter_m: f64,
    /// Forward propeller pitch, m.
    pub prop_pitch_m: f64,
    /// Best blade (profile) efficiency of the propeller, 1 (ideal momentum loss apart).
    pub prop_blade_eff: f64,
    /// Static thrust at full throttle, N.
    pub max_thrust_n: f64,
    /// Motor velocity constant, rpm/V.
    pub motor_kv: f64,
    /// Motor winding resistance, Ω.
    pub motor_r_ohm: f64,
    /// Motor no-load current, A.
    pub motor_i0_a: f64,
    /// ESC efficiency, 1.
    pub esc_eff: f64,
    /// Flight controller, GNSS, radios, W.
    pub avionics_w: f64,
    /// Servos holding the surfaces in calm air, W (more in turbulence and turns).
    pub servo_w: f64,
    /// The quadplane's transition airspeed (ArduPlane `ARSPD_FBW_MIN`), m/s; unused on a plane.
    #[serde(default)]
    pub transition_mps: f64,
}

impl PlaneSim {
    fn validate(&self) -> Result<(), String> {
        use crate::validate::{above, in_range};
        for (k, v) in [
            ("plane.wing_area_m2", self.wing_area_m2),
            ("plane.span_m", self.span_m),
            ("plane.cd0", self.cd0),
            ("plane.cd0_ref_mps", self.cd0_ref_mps),
            ("plane.cl_max", self.cl_max),
            ("plane.cruise_mps", self.cruise_mps),
            ("plane.prop_diameter_m", self.prop_diameter_m),
            ("plane.prop_pitch_m", self.prop_pitch_m),
            ("plane.max_thrust_n", self.max_thrust_n),
            ("plane.motor_kv", self.motor_kv),
        ] {
            in_range(k, v, above(0.0), "")?;
        }
        for (k, v) in [
            ("plane.oswald_e", self.oswald_e),
            ("plane.prop_blade_eff", self.prop_blade_eff),
            ("plane.esc_eff", self.esc_eff),
        ] {
            in_range(k, v, crate::validate::above_to(0.0, 1.0), "")?;
        }
        in_range(
            "plane.bank_limit_deg",
            self.bank_limit_deg,
            5.0..=75.0,
            "deg",
        )?;
        for (k, v) in [
            ("plane.motor_r_ohm", self.motor_r_ohm),
            ("plane.motor_i0_a", self.motor_i0_a),
            ("plane.avionics_w", self.avionics_w),
            ("plane.servo_w", self.servo_w),
            ("plane.transition_mps", self.transition_mps),
        ] {
            in_range(k, v, 0.0.., "")?;
        }
        Ok(())
    }
}

/// `[battery]`: a pack of `cells` in series behind an internal resistance. Terminal voltage
/// `V = OCV(SoC)·cells − I·R`; a power draw P gives the current that solves `V·I = P`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Battery {
    /// Cells in series.
    pub cells: u32,
    /// Rated capacity, mAh (what ArduPilot's `BATT_CAPACITY` and PX4's `BAT1_CAPACITY` hold).
    pub capacity_mah: f64,
    /// Pack internal resistance including wiring and connectors, Ω.
    pub internal_resistance_ohm: f64,
    /// Cell open-circuit voltage against state of charge: `[[soc, volts], …]`, soc from 0
    /// to 1 strictly rising, volts rising; linear in between.
    pub ocv_cell_v: Vec<[f64; 2]>,
}

impl Battery {
    /// Rated energy at the mean of the OCV curve, Wh (capacity × cells × mean cell OCV).
    pub fn energy_wh(&self) -> f64 {
        let area: f64 = self
            .ocv_cell_v
            .windows(2)
            .map(|w| (w[1][0] - w[0][0]) * (w[0][1] + w[1][1]) / 2.0)
            .sum();
        self.capacity_mah / 1000.0 * f64::from(self.cells) * area
    }

    /// Cell open-circuit voltage at state of charge `soc` (clamped to 0..1), V.
    pub fn ocv_cell_at(&self, soc: f64) -> f64 {
        let s = soc.clamp(0.0, 1.0);
        let curve = &self.ocv_cell_v;
        let mut cell = curve.last().map_or(0.0, |p| p[1]);
        for w in curve.windows(2) {
            let ([s0, v0], [s1, v1]) = (w[0], w[1]);
            if s <= s1 {
                cell = v0 + (v1 - v0) * (s - s0) / (s1 - s0);
                break;
            }
        }
        cell
    }

    fn validate(&self) -> Result<(), String> {
        use crate::validate::{above, in_range};
        in_range("battery.cells", self.cells, 1.., "")?;
        in_range("battery.capacity_mah", self.capacity_mah, above(0.0), "mAh")?;
        in_range(
            "battery.internal_resistance_ohm",
            self.internal_resistance_ohm,
            above(0.0),
            "Ω",
        )?;
        let c = &self.ocv_cell_v;
        let ends = c.first().map(|p| p[0]) == Some(0.0) && c.last().map(|p| p[0]) == Some(1.0);
        if c.len() < 2 || !ends {
            return Err(
                "battery.ocv_cell_v: needs at least two [soc, volts] points, from soc 0 to soc 1"
                    .into(),
            );
        }
        for (i, w) in c.windows(2).enumerate() {
            if !(w[1][0] > w[0][0] && w[1][1] > w[0][1] && w[0][1] > 0.0) {
                return Err(format!(
                    "battery.ocv_cell_v[{}]: soc and volts must both rise (and volts be > 0)",
                    i + 1
                ));
            }
        }
        Ok(())
    }
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
    /// A spec sheet (`[vehicle] takeoff_kg`, [`super::spec`]) becomes a profile from priors.
    pub fn from_toml(text: &str, origin: &str) -> anyhow::Result<Self> {
        if let Ok(t) = toml::from_str::<toml::Table>(text) {
            if super::spec::is_spec(&t) {
                return super::spec::profile(t, origin);
            }
        }
        let p: VehicleProfile = toml::from_str(text)
            .with_context(|| format!("{origin}: not a valid vehicle profile"))?;
        p.validate().map_err(|e| anyhow::anyhow!("{origin}: {e}"))?;
        Ok(p)
    }

    /// A built-in profile by name ([`BUILT_IN`]), else a profile file at that path.
    pub fn named_or_file(name_or_path: &str) -> anyhow::Result<Self> {
        match BUILT_IN.iter().find(|(n, _)| *n == name_or_path) {
            Some((n, text)) => Self::from_toml(text, &format!("built-in {n}.toml")),
            None if Path::new(name_or_path).exists() => Self::load(Path::new(name_or_path)),
            None => {
                let names: Vec<&str> = BUILT_IN.iter().map(|b| b.0).collect();
                anyhow::bail!(
                    "vehicle '{name_or_path}': neither a built-in profile ({}) nor a file",
                    names.join(", ")
                )
            }
        }
    }

    /// Read a profile file; a bare built-in name (`plane`, `x500`, …) that is not a file
    /// names the built-in profile, so `--vehicle plane` works everywhere.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        if !path.exists() {
            if let Some((n, text)) = BUILT_IN.iter().find(|(n, _)| Path::new(n) == path) {
                return Self::from_toml(text, &format!("built-in {n}.toml"));
            }
        }
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("{}: cannot read vehicle profile", path.display()))?;
        Self::from_toml(&text, &path.display().to_string())
    }

    /// The `[forecast]` default: which model the energy forecast starts from, and why (None:
    /// the profile has no `[forecast]`).
    pub fn forecast_default(&self) -> Option<(String, String)> {
        let f = self.forecast.as_ref()?;
        let why = if f.why.is_empty() {
            String::new()
        } else {
            format!(": {}", f.why)
        };
        Some((
            f.model.clone(),
            format!("vehicle profile {}{why}", self.name),
        ))
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
        // The physics models a profile's `does_not_transfer` may name.
        let physics = || super::physics::Kind::ALL.iter().map(|k| k.name());
        if let Some(n) = self
            .does_not_transfer
            .iter()
            .find(|n| !physics().any(|k| k == n.as_str()))
        {
            let all: Vec<&str> = physics().collect();
            return Err(format!(
                "does_not_transfer: '{n}' is not a physics model ({})",
                all.join(", ")
            ));
        }
        use crate::validate::{above, in_range};
        let pos = |k: &str, v: f64| in_range(k, v, above(0.0), "");
        pos("vehicle.airframe_kg", self.vehicle.airframe_kg)?;
        pos("vehicle.battery_kg", self.vehicle.battery_kg)?;
        pos("vehicle.prop_diameter_m", self.vehicle.prop_diameter_m)?;
        pos("air.rho_kg_m3", self.air.rho_kg_m3)?;
        pos("air.g_m_s2", self.air.g_m_s2)?;
        in_range("vehicle.rotors", self.vehicle.rotors, 1.., "")?;
        pos("dandrea.eta", self.dandrea.eta)?;
        pos("dandrea.lift_drag", self.dandrea.lift_drag)?;
        pos("dandrea_headwind.eta", self.dandrea_headwind.eta)?;
        pos(
            "dandrea_headwind.lift_drag",
            self.dandrea_headwind.lift_drag,
        )?;
        pos("dorling.eta", self.dorling.eta)?;
        pos("stolaroff.eta", self.stolaroff.eta)?;
        in_range(
            "stolaroff.profile_share",
            self.stolaroff.profile_share,
            0.0..=0.9,
            "",
        )?;
        pos("kirschstein.eta", self.kirschstein.eta)?;
        pos("kirschstein.eta_c", self.kirschstein.eta_c)?;
        let fin = |k: &str, v: f64| in_range(k, v, .., "");
        for (i, b) in self.tseng.beta.iter().enumerate() {
            fin(&format!("tseng.beta[{i}]"), *b)?;
        }
        for (i, b) in self.tseng_solo.coef.iter().enumerate() {
            fin(&format!("tseng_solo.coef[{i}]"), *b)?;
        }
        if let Some(r) = &self.rotor {
            pos("rotor.kappa", r.kappa)?;
            pos("rotor.solidity", r.solidity)?;
            pos("rotor.blade_cd0", r.blade_cd0)?;
            pos("rotor.thrust_coefficient", r.thrust_coefficient)?;
        }
        if let Some(b) = &self.body {
            in_range("body.drag_area_m2", b.drag_area_m2, 0.0.., "m²")?;
        }
        if let Some(p) = &self.powertrain {
            in_range(
                "powertrain.efficiency",
                p.efficiency,
                crate::validate::above_to(0.0, 1.0),
                "",
            )?;
            in_range("powertrain.avionics_w", p.avionics_w, 0.0.., "W")?;
            in_range("powertrain.idle_w", p.idle_w, 0.0.., "W")?;
        }
        if let Some(b) = &self.battery {
            b.validate()?;
        }
        if let Some(f) = &self.fixed_wing_flight {
            f.validate()?;
        }
        if let Some(p) = &self.plane {
            p.validate()?;
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

/// The M100's calibrated profile, as compiled in ([`crate::assets`]).
pub fn m100_calibrated() -> anyhow::Result<VehicleProfile> {
    VehicleProfile::from_toml(
        crate::assets::M100_CALIBRATED_TOML,
        "built-in m100-calibrated.toml",
    )
}

/// A calibrated profile: the file given, else the M100's compiled in. A file given that does
/// not read is an error (never silently the built-in).
pub fn calibrated_profile(file: Option<&std::path::Path>) -> anyhow::Result<VehicleProfile> {
    match file {
        Some(p) => VehicleProfile::load(p),
        None => m100_calibrated(),
    }
}

#[cfg(test)]
#[path = "profile_tests.rs"]
mod tests;
