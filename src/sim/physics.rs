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
//! The project's pack model ([`crate::battery`]), chosen for the profile's pack as the
//! monitor chooses it ([`crate::energy::pack::pack_model`]: the TB48D's fitted curve and
//! circuit for the M100, else the chemistry's default curve scaled to the capacity):
//! `V = OCV(E) − R0·f·I − R1·x1`, with the polarisation `x1` (one RC pair, τ1) and the
//! cold-pack factor `f` that falls as the pack warms. For a draw P the current solves
//! `P = V·I` over the step; the energy above the floor `E` falls by `V·I·dt`. The start is
//! a full pack, a state of charge or a resting voltage ([`BatteryStart`]).

use crate::features::units::G;
use std::f64::consts::PI;

use anyhow::Context;
use nalgebra::Vector3;

use crate::battery::{Chemistry, CircuitParams, Estimator};
use crate::energy::pack::pack_model;
use crate::model::profile::{self, VehicleProfile};
use crate::report::{BatteryFacts, Provenance, Sourced};

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
        let (rotor, body, power) = (
            section(&p.rotor, "rotor", p)?,
            section(&p.body, "body", p)?,
            section(&p.powertrain, "powertrain", p)?,
        );
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
    pub fn thrust_ned(
        &self,
        mass_kg: f64,
        v_air_ned: Vector3<f64>,
        accel_ned: Vector3<f64>,
    ) -> Vector3<f64> {
        mass_kg * (accel_ned - Vector3::new(0.0, 0.0, G))
            + 0.5 * self.rho * self.drag_area_m2 * v_air_ned.norm() * v_air_ned
    }

    /// Electrical power for a vehicle of `mass_kg` moving at `v_air_ned` through the air
    /// (NED, m/s) while accelerating at `accel_ned` (NED, m/s²); the formulas are in the
    /// module docs. The floor `P_i/2` keeps a fast descent from drawing less than the
    /// rotors need to turn.
    pub fn power(
        &self,
        mass_kg: f64,
        v_air_ned: Vector3<f64>,
        accel_ned: Vector3<f64>,
    ) -> PowerBreakdown {
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
        let profile_w = self.rotors * self.solidity * self.cd0 / 8.0
            * self.rho
            * a
            * tip.powi(3)
            * (1.0 + 4.65 * mu * mu);
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

/// Where the simulated pack starts: full, at a state of charge, or at a resting voltage.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum BatteryStart {
    /// A freshly charged pack (the OCV curve's top).
    #[default]
    Full,
    /// State of charge, 0..1 of the OCV curve's energy.
    Soc(f64),
    /// Resting (open-circuit) pack voltage, V.
    RestV(f64),
}

/// A battery pack being discharged: its spec (from the profile), the project's pack model
/// ([`crate::battery`], chosen by [`crate::energy::pack::pack_model`]) and its state.
#[derive(Debug, Clone)]
pub struct Battery {
    /// Cells and capacity (the profile's `[battery]`).
    pub spec: profile::Battery,
    /// Capacity, Ah.
    pub capacity_ah: f64,
    /// Cells in series.
    pub cells: f64,
    /// The chemistry: LiHV when the profile's full cell voltage is over 4.3 V, else LiPo.
    pub chemistry: Chemistry,
    /// Warm ohmic resistance R0 of the circuit, Ω.
    pub r_ohm: f64,
    /// State of charge, 0..1 (energy fraction of the OCV curve).
    pub soc: f64,
    /// Charge drawn so far, Ah.
    pub drawn_ah: f64,
    /// Energy drawn so far, Wh.
    pub drawn_wh: f64,
    /// The circuit, driven open loop: OCV(energy), R0·f, the RC pair, the heat proxy.
    est: Estimator,
}

impl Battery {
    /// The pack a profile describes, starting at `start`; an error names a missing
    /// `[battery]` section or a start outside the pack's window.
    pub fn from_profile(p: &VehicleProfile, start: BatteryStart) -> anyhow::Result<Self> {
        Self::new(section(&p.battery, "battery", p)?.clone(), start)
    }

    /// The battery facts the monitor would resolve for this pack: its cells, its chemistry
    /// (from the profile's full cell voltage) and its capacity (mAh × cells × nominal).
    pub fn facts(spec: &profile::Battery) -> BatteryFacts {
        let full = spec.ocv_cell_v.last().map_or(4.2, |p| p[1]);
        let chem = if full > 4.3 {
            Chemistry::LiHv
        } else {
            Chemistry::LiPo
        };
        let cap = spec.capacity_mah / 1000.0 * f64::from(spec.cells) * chem.nominal_v();
        BatteryFacts {
            capacity_wh: Some(Sourced::new(cap, Provenance::Config)),
            cell_count: Sourced::new(spec.cells, Provenance::Config),
            chemistry: Sourced::new(chem.name().into(), Provenance::Config),
            ..BatteryFacts::default()
        }
    }

    /// A pack of `spec` starting at `start`: the OCV curve and circuit of
    /// [`pack_model`] for its facts, with no measurement
    /// offset (`bias_v` 0: the simulated pack is the truth), cold (no heat).
    pub fn new(spec: profile::Battery, start: BatteryStart) -> anyhow::Result<Self> {
        let facts = Self::facts(&spec);
        let chem = Chemistry::from_name(&facts.chemistry.value).unwrap_or(Chemistry::LiPo);
        let (curve, params) = pack_model(&facts).with_context(|| {
            format!("no pack model for {} cells of {}", spec.cells, chem.name())
        })?;
        let params = CircuitParams {
            bias_v: 0.0,
            ..params
        };
        let n = f64::from(spec.cells);
        let (lo, hi) = (
            n * chem.floor_v(),
            n * (chem.full_v() + crate::battery::chemistry::FULL_TOL_V),
        );
        let v_rest = match start {
            BatteryStart::Full => n * curve.v_cell(1.0),
            BatteryStart::Soc(s) if (0.0..=1.0).contains(&s) => n * curve.v_cell(s),
            BatteryStart::Soc(s) => {
                anyhow::bail!("state of charge {:.1} %: must be 0-100 %", s * 100.0)
            }
            BatteryStart::RestV(v) if v.is_finite() && (lo..=hi).contains(&v) => v,
            BatteryStart::RestV(v) => {
                anyhow::bail!(
                    "resting voltage {v} V: a {}S {} pack rests between {lo:.2} and {hi:.2} V",
                    spec.cells,
                    chem.name()
                )
            }
        };
        let est = Estimator::new(params, curve, v_rest, 0.0)
            .context("the pack model rejected the start state")?;
        let mut b = Self {
            capacity_ah: spec.capacity_mah / 1000.0,
            cells: n,
            chemistry: chem,
            r_ohm: params.r0,
            spec,
            soc: 0.0,
            drawn_ah: 0.0,
            drawn_wh: 0.0,
            est,
        };
        b.soc = b.soc_now();
        Ok(b)
    }

    fn soc_now(&self) -> f64 {
        self.est
            .curve
            .soc(self.est.ocv() / self.cells)
            .clamp(0.0, 1.0)
    }

    /// Open-circuit pack voltage, V.
    pub fn ocv_v(&self) -> f64 {
        self.est.ocv()
    }

    /// Resistance factor of a cold pack, `1 + a·exp(−H/Hs)`.
    fn factor(&self) -> f64 {
        let p = &self.est.p;
        1.0 + p.warm_a * (-self.est.heat / p.heat_scale).exp()
    }

    /// The current that draws `power_w` from a source `e − r·I`: the smaller root of
    /// `r·I² − e·I + P = 0` (past the pack's maximum power, the current at that maximum).
    fn solve(e: f64, r: f64, power_w: f64) -> f64 {
        let p = power_w.max(0.0);
        if r <= 0.0 {
            return if e > 0.0 { p / e } else { 0.0 };
        }
        let disc = (e * e - 4.0 * r * p).max(0.0);
        (e - disc.sqrt()) / (2.0 * r)
    }

    /// Terminal voltage and current for a power draw now (the instantaneous response:
    /// OCV less the polarisation held and R0·f·I), (V, A); `V·I = P`.
    pub fn load(&self, power_w: f64) -> (f64, f64) {
        let th = &self.est.theta;
        let e = self.ocv_v() - th[2] - th[1] * self.est.x1;
        let r = th[0] * self.factor();
        let i = Self::solve(e, r, power_w);
        (e - r * i, i)
    }

    /// Draw `power_w` for `dt_s` seconds: the current solved from `P = V·I` with the RC
    /// pair's response over the step, then the circuit stepped open loop
    /// ([`Estimator::step_open_loop`]); returns the terminal voltage and current, (V, A).
    pub fn step(&mut self, power_w: f64, dt_s: f64) -> (f64, f64) {
        let th = self.est.theta;
        let f = self.factor();
        let e1 = (-dt_s / self.est.p.tau1_s).exp();
        // V = OCV − b − R1·x1·e1 − (R0·f + R1·f·(1 − e1))·I
        let e = self.ocv_v() - th[2] - th[1] * self.est.x1 * e1;
        let r = th[0] * f + th[1] * f * (1.0 - e1);
        let i = Self::solve(e, r, power_w);
        let v = self.est.step_open_loop(dt_s, i);
        let v = if v.is_finite() { v } else { e - r * i };
        self.drawn_ah += i * dt_s / 3600.0;
        self.drawn_wh += power_w * dt_s / 3600.0;
        self.soc = self.soc_now();
        (v, i)
    }
}
