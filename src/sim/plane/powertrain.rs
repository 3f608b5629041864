//! The truth power's parts: the wing's lift and drag polar, the pusher's thrust and its
//! electrical draw (the formulas are the parent module's docs').

use super::*;

/// The wing of a plane of a given mass: lift and drag (the truth polar).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wing {
    /// The `[plane]` figures.
    pub p: PlaneSim,
    /// Mass, kg.
    pub mass_kg: f64,
}

impl Wing {
    /// The wing of `p` flying `mass_kg`.
    pub fn new(p: &PlaneSim, mass_kg: f64) -> Self {
        Self { p: *p, mass_kg }
    }

    /// Aspect ratio b²/S.
    pub fn aspect_ratio(&self) -> f64 {
        self.p.span_m * self.p.span_m / self.p.wing_area_m2
    }

    /// Level stall speed at density `rho`, m/s.
    pub fn stall_mps(&self, rho: f64) -> f64 {
        (2.0 * self.mass_kg * G / (rho * self.p.wing_area_m2 * self.p.cl_max)).sqrt()
    }

    /// The lift coefficient that gives `lift_n` at airspeed `v`.
    pub fn cl(&self, lift_n: f64, v: f64, rho: f64) -> f64 {
        lift_n / (0.5 * rho * v.max(1.0).powi(2) * self.p.wing_area_m2)
    }

    /// Drag at airspeed `v` with lift coefficient `cl`, N (the truth polar of the module docs).
    pub fn drag_n(&self, v: f64, cl: f64, rho: f64) -> f64 {
        let v = v.max(1.0);
        let cd0 = self.p.cd0 * (self.p.cd0_ref_mps / v.max(3.0)).powf(0.2);
        let knee = 0.75 * self.p.cl_max;
        let cd = cd0
            + cl * cl / (PI * self.p.oswald_e * self.aspect_ratio())
            + 0.1 * (cl.abs() - knee).max(0.0).powi(2);
        0.5 * rho * v * v * self.p.wing_area_m2 * cd
    }
}

/// The forward motor and propeller.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pusher {
    p: PlaneSim,
    /// Thrust coefficient at J = 0.
    ct0: f64,
    /// Advance ratio of zero thrust.
    j0: f64,
}

/// What the pusher draws for a thrust.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PusherDraw {
    /// Battery power, W.
    pub electrical_w: f64,
    /// Shaft power, W.
    pub shaft_w: f64,
    /// Thrust × airspeed, W.
    pub thrust_power_w: f64,
    /// Throttle, 0..1 (motor voltage over the bus voltage).
    pub throttle: f64,
}

impl Pusher {
    /// The pusher of `p` on a pack of `cells` (its full revolutions at 85 % of K_v × 3.7 V a cell).
    pub fn new(p: &PlaneSim, cells: f64) -> Self {
        let d = p.prop_diameter_m;
        let n_max = p.motor_kv * 3.7 * cells * 0.85 / 60.0;
        Self {
            p: *p,
            ct0: p.max_thrust_n / (1.225 * n_max * n_max * d.powi(4)),
            j0: 1.1 * p.prop_pitch_m / d,
        }
    }

    /// The most thrust at airspeed `v` on a bus of `bus_v`, N.
    pub fn max_thrust_n(&self, v: f64, bus_v: f64, cells: f64, rho: f64) -> f64 {
        let d = self.p.prop_diameter_m;
        let n = self.p.motor_kv * bus_v.max(0.0) * 0.85 / 60.0;
        let j = v.max(0.0) / (n.max(1.0) * d);
        let t = self.ct0 * rho * n * n * d.powi(4) * (1.0 - j / self.j0);
        // the static figure holds for a full pack; a sagging one gives less
        t.clamp(
            0.0,
            self.p.max_thrust_n * (bus_v / (4.2 * cells)).clamp(0.5, 1.2),
        )
    }

    /// The battery power for `thrust_n` at airspeed `v` on a bus of `bus_v` (module docs).
    pub fn draw(&self, thrust_n: f64, v: f64, bus_v: f64, rho: f64) -> PusherDraw {
        if thrust_n <= 1e-3 {
            return PusherDraw {
                electrical_w: 0.0,
                shaft_w: 0.0,
                thrust_power_w: 0.0,
                throttle: 0.0,
            };
        }
        let v = v.max(0.0);
        let d = self.p.prop_diameter_m;
        let area = PI * d * d / 4.0;
        let vi = 0.5 * (-v + (v * v + 2.0 * thrust_n / (rho * area)).sqrt());
        let p_ideal = thrust_n * (v + vi);
        // T = a·n² − b·n with a = C_T0·ρ·D⁴, b = C_T0·ρ·D³·V/J_0
        let a = self.ct0 * rho * d.powi(4);
        let b = self.ct0 * rho * d.powi(3) * v / self.j0;
        let n = (b + (b * b + 4.0 * a * thrust_n).sqrt()) / (2.0 * a);
        let j = v / (n * d);
        let x = (j / self.j0 - 0.65) / 0.65;
        let eta_b = self.p.prop_blade_eff * (1.0 - 0.3 * x * x).clamp(0.3, 1.0);
        let shaft = p_ideal / eta_b;
        let omega = 2.0 * PI * n;
        let kv_rad = self.p.motor_kv * 2.0 * PI / 60.0;
        let current = shaft / omega * kv_rad + self.p.motor_i0_a;
        let v_emf = omega / kv_rad;
        let p_in = v_emf * current + current * current * self.p.motor_r_ohm;
        PusherDraw {
            electrical_w: p_in / self.p.esc_eff,
            shaft_w: shaft,
            thrust_power_w: thrust_n * v,
            throttle: ((v_emf + current * self.p.motor_r_ohm) / bus_v.max(1.0)).clamp(0.0, 1.0),
        }
    }
}
