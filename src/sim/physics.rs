//! The simulated vehicle's physics: rotor power by momentum theory ([`Airframe::power`])
//! and a battery that turns power into voltage and current ([`Battery`]). Both are built
//! from a [`VehicleProfile`] (its `[vehicle]`, `[air]`, `[rotor]`, `[body]`,
//! `[powertrain]` and `[battery]` sections), so the simulator flies the same airframe the
//! models are told about.
//!
//! ## Power
//! `P_elec = max(P_induced + P_profile + P_parasitic + P_climb, P_induced/2) / η + P_avionics`:
//! - induced `κ·|T|·v_i`, with the induced velocity of forward flight (Glauert)
//!   `v_i = v_h² / √(V_p² + (V_n + v_i)²)`, `v_h² = T_r/(2ρA)`, solved iteratively;
//! - profile `N·(σ·C_d0/8)·ρ·A·(ΩR)³·(1 + 4.65 μ²)`, tip speed `ΩR = √(T_r/(C_T·ρ·A))`,
//!   advance ratio `μ = V_p/ΩR`;
//! - parasitic `½ρ·f·|v_a|³` (f = flat-plate drag area);
//! - climb `m·g·v_up`.
//!
//! The thrust vector follows from Newton, `T = m·(a − g) + ½ρ·f·|v_a|·v_a` (NED,
//! g = (0, 0, 9.80665) m/s²).
//!
//! ## Battery
//! `V = OCV(SoC)·cells − I·R`; for a draw P the current solves `P = (OCV − I·R)·I`, so
//! `V·I = P` exactly. The state of charge falls with the charge drawn.

use std::f64::consts::PI;

use anyhow::Context;
use nalgebra::Vector3;

use crate::model::profile::{self, VehicleProfile};

/// Standard gravity, m/s² (also ArduPilot's `GRAVITY_MSS`, which scales RAW_IMU).
pub const G: f64 = 9.80665;

/// The airframe and rotor constants of the power model, from a profile.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Airframe {
    /// Airframe without battery, kg.
    pub airframe_kg: f64,
    /// Battery, kg.
    pub battery_kg: f64,
    /// Maximum take-off mass, kg.
    pub mtow_kg: f64,
    /// Number of rotors.
    pub rotors: f64,
    /// Rotor radius, m.
    pub rotor_radius_m: f64,
    /// Air density, kg/m³.
    pub rho: f64,
    /// Induced-power factor κ.
    pub kappa: f64,
    /// Rotor solidity σ.
    pub solidity: f64,
    /// Blade profile drag coefficient.
    pub cd0: f64,
    /// Thrust coefficient (sets the tip speed for a thrust).
    pub ct: f64,
    /// Flat-plate drag area C_D·A, m².
    pub drag_area_m2: f64,
    /// Constant electrical draw of the avionics, W.
    pub avionics_w: f64,
    /// Draw on the ground, armed, props idling, W.
    pub idle_w: f64,
    /// Mechanical → electrical efficiency η.
    pub efficiency: f64,
}

/// The terms of the power model at one instant, watts (mechanical terms before η).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PowerBreakdown {
    /// Total thrust, N.
    pub thrust_n: f64,
    /// Induced velocity at the disk, m/s.
    pub induced_velocity_mps: f64,
    /// κ·T·v_i.
    pub induced_w: f64,
    /// Blade profile power.
    pub profile_w: f64,
    /// ½ρ·f·|v_a|³.
    pub parasitic_w: f64,
    /// m·g·climb rate (negative when descending).
    pub climb_w: f64,
    /// Electrical power drawn from the battery.
    pub electrical_w: f64,
}

/// The section a simulated profile must have, or an error naming it.
fn section<'a, T>(s: &'a Option<T>, name: &str, p: &VehicleProfile) -> anyhow::Result<&'a T> {
    s.as_ref().with_context(|| {
        format!("vehicle profile '{}' has no [{name}] section: the simulator needs it (see config/vehicles/m100.toml)", p.name)
    })
}

impl Airframe {
    /// The airframe a profile describes; an error names a missing section.
    pub fn from_profile(p: &VehicleProfile) -> anyhow::Result<Self> {
        let (rotor, body, power) = (section(&p.rotor, "rotor", p)?, section(&p.body, "body", p)?, section(&p.powertrain, "powertrain", p)?);
        Ok(Self {
            airframe_kg: p.vehicle.airframe_kg,
            battery_kg: p.vehicle.battery_kg,
            mtow_kg: p.vehicle.mtow_kg,
            rotors: f64::from(p.vehicle.rotors),
            rotor_radius_m: p.vehicle.prop_diameter_m / 2.0,
            rho: p.air.rho_kg_m3,
            kappa: rotor.kappa,
            solidity: rotor.solidity,
            cd0: rotor.blade_cd0,
            ct: rotor.thrust_coefficient,
            drag_area_m2: body.drag_area_m2,
            avionics_w: power.avionics_w,
            idle_w: power.idle_w,
            efficiency: power.efficiency,
        })
    }

    /// Take-off mass with a payload, kg.
    pub fn mass_kg(&self, payload_kg: f64) -> f64 {
        self.airframe_kg + self.battery_kg + payload_kg
    }

    /// The most payload the maximum take-off mass allows, kg.
    pub fn max_payload_kg(&self) -> f64 {
        self.mtow_kg - self.airframe_kg - self.battery_kg
    }

    /// Disk area of one rotor, m².
    pub fn disk_area_m2(&self) -> f64 {
        PI * self.rotor_radius_m * self.rotor_radius_m
    }

    /// Ideal (momentum theory, uniform inflow) hover power of `mass_kg`, W:
    /// `T^1.5 / √(2ρ·A_total)`. The rotor's figure of merit is this over the mechanical
    /// power the model needs in the hover.
    pub fn ideal_hover_w(&self, mass_kg: f64) -> f64 {
        let t = mass_kg * G;
        t.powf(1.5) / (2.0 * self.rho * self.rotors * self.disk_area_m2()).sqrt()
    }

    /// Thrust vector (NED, N) needed to give a mass `mass_kg` the acceleration `accel_ned`
    /// against gravity and the drag of the air-relative velocity `v_air_ned`:
    /// `T = m·(a − g) + ½ρ·f·|v_a|·v_a`.
    pub fn thrust_ned(&self, mass_kg: f64, v_air_ned: Vector3<f64>, accel_ned: Vector3<f64>) -> Vector3<f64> {
        mass_kg * (accel_ned - Vector3::new(0.0, 0.0, G)) + 0.5 * self.rho * self.drag_area_m2 * v_air_ned.norm() * v_air_ned
    }

    /// Electrical power for a vehicle of `mass_kg` moving at `v_air_ned` through the air
    /// (NED, m/s) while accelerating at `accel_ned` (NED, m/s²); the formulas are in the
    /// module docs. The floor `P_i/2` keeps a fast descent from drawing less than the
    /// rotors need to turn.
    pub fn power(&self, mass_kg: f64, v_air_ned: Vector3<f64>, accel_ned: Vector3<f64>) -> PowerBreakdown {
        let t_vec = self.thrust_ned(mass_kg, v_air_ned, accel_ned);
        let thrust = t_vec.norm().max(1e-6);
        // Thrust axis points where the thrust pushes (up-ish: negative z in NED).
        let n = t_vec / thrust;
        let a = self.disk_area_m2();
        let t_r = thrust / self.rotors;
        let vh2 = t_r / (2.0 * self.rho * a);
        // Air flows through the disk against n when the vehicle moves along n.
        let v_n = v_air_ned.dot(&n);
        let v_p = (v_air_ned - v_n * n).norm();
        let mut vi = vh2.sqrt();
        for _ in 0..100 {
            let next = vh2 / (v_p * v_p + (v_n + vi).powi(2)).sqrt().max(1e-3);
            if (next - vi).abs() < 1e-6 {
                vi = next;
                break;
            }
            vi = 0.5 * vi + 0.5 * next;
        }
        let tip = (t_r / (self.ct * self.rho * a)).sqrt().max(1.0);
        let mu = v_p / tip;
        let induced_w = self.kappa * thrust * vi;
        let profile_w = self.rotors * self.solidity * self.cd0 / 8.0 * self.rho * a * tip.powi(3) * (1.0 + 4.65 * mu * mu);
        let va = v_air_ned.norm();
        let parasitic_w = 0.5 * self.rho * self.drag_area_m2 * va.powi(3);
        let climb_w = mass_kg * G * (-v_air_ned.z);
        let mech = (induced_w + profile_w + parasitic_w + climb_w).max(0.5 * induced_w);
        PowerBreakdown {
            thrust_n: thrust,
            induced_velocity_mps: vi,
            induced_w,
            profile_w,
            parasitic_w,
            climb_w,
            electrical_w: mech / self.efficiency + self.avionics_w,
        }
    }
}

/// A battery pack being discharged: its spec (from the profile) and its state.
#[derive(Debug, Clone, PartialEq)]
pub struct Battery {
    /// Cells, capacity, resistance, OCV curve.
    pub spec: profile::Battery,
    /// Capacity, Ah.
    pub capacity_ah: f64,
    /// Cells in series.
    pub cells: f64,
    /// Internal resistance, Ω.
    pub r_ohm: f64,
    /// State of charge, 0..1.
    pub soc: f64,
    /// Charge drawn so far, Ah.
    pub drawn_ah: f64,
    /// Energy drawn so far, Wh.
    pub drawn_wh: f64,
}

impl Battery {
    /// The pack a profile describes, at state of charge `soc`; an error names a missing
    /// `[battery]` section.
    pub fn from_profile(p: &VehicleProfile, soc: f64) -> anyhow::Result<Self> {
        Ok(Self::new(section(&p.battery, "battery", p)?.clone(), soc))
    }

    /// A pack of `spec` at state of charge `soc` (clamped to 0..1).
    pub fn new(spec: profile::Battery, soc: f64) -> Self {
        Self {
            capacity_ah: spec.capacity_mah / 1000.0,
            cells: f64::from(spec.cells),
            r_ohm: spec.internal_resistance_ohm,
            spec,
            soc: soc.clamp(0.0, 1.0),
            drawn_ah: 0.0,
            drawn_wh: 0.0,
        }
    }

    /// Open-circuit pack voltage, V.
    pub fn ocv_v(&self) -> f64 {
        self.spec.ocv_cell_at(self.soc) * self.cells
    }

    /// Terminal voltage and current for a power draw, (V, A).
    pub fn load(&self, power_w: f64) -> (f64, f64) {
        let ocv = self.ocv_v();
        let disc = (ocv * ocv - 4.0 * self.r_ohm * power_w.max(0.0)).max(0.0);
        let i = (ocv - disc.sqrt()) / (2.0 * self.r_ohm);
        (ocv - i * self.r_ohm, i)
    }

    /// Draw `power_w` for `dt_s` seconds.
    pub fn step(&mut self, power_w: f64, dt_s: f64) {
        let (_, i) = self.load(power_w);
        self.drawn_ah += i * dt_s / 3600.0;
        self.drawn_wh += power_w * dt_s / 3600.0;
        self.soc = (self.soc - i * dt_s / 3600.0 / self.capacity_ah).max(0.0);
    }
}
