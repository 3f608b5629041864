//! The fixed-wing power model: a plane's electrical power from its airspeed, bank, climb
//! and the air it flies in. It runs on the windows of a plane, and of a VTOL in forward
//! flight ([`crate::features::Lift::Wing`]); never on a multirotor's.
//!
//! ```text
//! P = ( ½·ρ·V³·S·C_D0  +  2·(n·m·g)² / (ρ·V·S·π·e·AR)  +  m·g·(v_z + V·V̇/g) ) / η  +  P_0
//!        parasitic          induced (n = 1/cos φ)            climb and acceleration
//! ```
//!
//! | symbol | meaning | unit | from |
//! |---|---|---|---|
//! | ρ | air density | kg/m³ | ISA at the altitude (`position_z`, m above sea level), with the measured air temperature where the vehicle sends one ([`air_density`]) |
//! | V | airspeed | m/s | VFR_HUD `airspeed` with a healthy airspeed sensor, else ground velocity − WIND, else the autopilot's own VFR_HUD airspeed, else the ground speed ([`airspeed`]) |
//! | S | wing area | m² | profile `[fixed_wing] wing_area_m2` |
//! | AR | aspect ratio b²/S | 1 | profile `span_m` |
//! | C_D0 | zero-lift drag coefficient | 1 | profile `cd0` |
//! | e | Oswald efficiency | 1 | profile `oswald_e` |
//! | n | load factor 1/cos φ, φ the bank (roll) angle, capped at 60° | 1 | the attitude |
//! | m | mass: profile `mass_kg` + the `payload` feature | kg | |
//! | v_z | climb rate (up positive) | m/s | `velocity_z` |
//! | V̇ | acceleration along the air path | m/s² | the window's ground velocity ([`path_acceleration`]); the kinetic-energy rate of the total-energy (TECS) balance |
//! | η | propulsive × motor × ESC efficiency | 1 | profile `eta` |
//! | P_0 | avionics and servos | W | profile `offset_w` |
//!
//! The aerodynamic power is never below 0 (a glide does not charge the pack): P ≥ P_0.
//! Below [`MIN_FLYING_M_S`] of airspeed and ground speed the plane is taken to stand on the
//! ground, motor idle: P = P_0 (the induced term would grow without bound as V → 0).
//!
//! **Airspeed 0 in forward flight** (the sensor reads under 1 m/s while the ground speed is
//! over [`MIN_FLYING_M_S`]) is a failed sensor, not a stall: the window is counted
//! ([`FixedWing::sensor_failures`]), warned about once, and flown on the next source.
//! A missing airspeed falls back the same way, said once.
//!
//! The model is linear in its own four regressors ([`regressors`]: ρV³, (n·m·g)²/(ρV),
//! m·g·(v_z + V·V̇/g), 1), with the coefficients S·C_D0/(2η), 2/(S·π·e·AR·η), 1/η and P_0
//! ([`FixedWing::coefficients`]). Online adaptation fits those four coefficients on the
//! vehicle (`model::adapt::regression`: bounded, the published ones as the prior), then
//! corrects the result like every model's (a·P + b, bounded), teaching while the motor
//! runs (measured power over twice `offset_w`). Airspeeds over
//! [`MAX_AIRSPEED_M_S`] and climb rates beyond ±[`MAX_CLIMB_M_S`] are clamped.
//!
//! Defaults: a generic ~2 kg foam plane of 1.8 m span (see [`Params::default`] for the
//! source of each figure), for a plane whose profile has no `[fixed_wing]` section.

use serde::{Deserialize, Serialize};

mod flight;
pub use flight::{bank_for_radius, Flight};

use crate::features::{frames, idx, Lift, Sample};
use crate::model::{PowerModel, Prediction};
use crate::telemetry::window::Window;

/// Below this airspeed and ground speed, m/s, a plane is taken to be on the ground.
pub const MIN_FLYING_M_S: f64 = 3.0;
/// Airspeed and climb rate beyond these, m/s, are clamped (a glitch, not a flight).
pub const MAX_AIRSPEED_M_S: f64 = 100.0;
pub const MAX_CLIMB_M_S: f64 = 30.0;
/// The bank angle the load factor is capped at, rad (60°: n = 2).
const MAX_BANK_RAD: f64 = std::f64::consts::FRAC_PI_3;
use crate::features::units::{wrap_pi, G};

/// `[fixed_wing]` of a vehicle profile: the plane's figures.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Params {
    /// Take-off mass without payload, kg.
    pub mass_kg: f64,
    /// Wing area S, m².
    pub wing_area_m2: f64,
    /// Wing span b, m.
    pub span_m: f64,
    /// Zero-lift drag coefficient C_D0 (whole aircraft, on S), 1.
    pub cd0: f64,
    /// Oswald span efficiency e, 1.
    pub oswald_e: f64,
    /// Propulsive × motor × ESC efficiency η, 1.
    pub eta: f64,
    /// Avionics, servos and everything drawn with the motor stopped, W.
    pub offset_w: f64,
    /// The wing's maximum lift coefficient C_L,max, 1: a VTOL's wing carries at most
    /// ½ρV²·S·C_L,max of the weight while its rotors fly it (see
    /// [`crate::model::physics::Kinematics::weight_n`]); the fixed-wing model does not read it.
    pub cl_max: f64,
}

impl Default for Params {
    /// A generic ~2 kg foam plane of 1.8 m span (the class of the Volantex Ranger EX or the
    /// Skywalker 1800; figures of that class, as remembered, not re-checked):
    /// - `mass_kg` 2.0, `span_m` 1.8, `wing_area_m2` 0.36 (AR 9): the class's typical
    ///   take-off mass, span and wing area. ASSUMPTION within the class.
    /// - `cd0` 0.035: small UAVs span about 0.02–0.05 (Gryte et al., "Aerodynamic modeling
    ///   of the Skywalker X8 fixed-wing UAV", ICUAS 2018, near 0.02 for a clean flying
    ///   wing; Beard & McLain, *Small Unmanned Aircraft*, 2012, app. E, about 0.04 for the
    ///   Aerosonde); a foam plane with a fuselage and landing gear sits mid-range.
    /// - `oswald_e` 0.78: Raymer's straight-wing estimate e = 1.78·(1 − 0.045·AR^0.68) − 0.64
    ///   at AR 9 (Raymer, *Aircraft Design: A Conceptual Approach*, eq. 12.48).
    /// - `eta` 0.5: propeller 0.6–0.75 × motor 0.75–0.85 × ESC ~0.95 for small electric
    ///   planes (the usual published ranges). ASSUMPTION mid-range.
    /// - `offset_w` 5: flight controller, GPS, radios and servos. ASSUMPTION.
    /// - `cl_max` 1.0: the whole wing's maximum lift coefficient, the low end of the
    ///   1.0–1.4 usually quoted for small UAV wings without flaps, and about where Gryte et
    ///   al. 2018's Skywalker X8 lift curve stalls (as remembered, not re-checked).
    ///   ASSUMPTION within that range.
    fn default() -> Self {
        Self {
            mass_kg: 2.0,
            wing_area_m2: 0.36,
            span_m: 1.8,
            cd0: 0.035,
            oswald_e: 0.78,
            eta: 0.5,
            offset_w: 5.0,
            cl_max: 1.0,
        }
    }
}

impl Params {
    /// Range checks; each message names the key.
    pub fn validate(&self) -> Result<(), String> {
        let checks = [
            ("mass_kg", self.mass_kg, 0.05, 500.0),
            ("wing_area_m2", self.wing_area_m2, 0.01, 50.0),
            ("span_m", self.span_m, 0.1, 50.0),
            ("cd0", self.cd0, 0.005, 0.5),
            ("oswald_e", self.oswald_e, 0.3, 1.0),
            ("eta", self.eta, 0.05, 1.0),
            ("offset_w", self.offset_w, 0.0, 5000.0),
            ("cl_max", self.cl_max, 0.1, 3.0),
        ];
        check_ranges("fixed_wing", &checks)
    }

    /// Aspect ratio b²/S.
    pub fn aspect_ratio(&self) -> f64 {
        self.span_m * self.span_m / self.wing_area_m2
    }
}

/// Each `(key, value, lo, hi)` of table `section` within `[lo, hi]`; every broken key in
/// one message, each line naming `section.key`.
fn check_ranges(section: &str, checks: &[(&str, f64, f64, f64)]) -> Result<(), String> {
    let errs: Vec<String> = checks
        .iter()
        .filter(|(_, v, lo, hi)| !(v.is_finite() && v >= lo && v <= hi))
        .map(|(k, v, lo, hi)| format!("{section}.{k} = {v}: must be in [{lo}, {hi}]"))
        .collect();
    if errs.is_empty() {
        Ok(())
    } else {
        Err(errs.join("\n"))
    }
}

/// Where the airspeed of a window came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AirspeedFrom {
    /// VFR_HUD `airspeed` with a healthy airspeed sensor.
    Sensor,
    /// Ground velocity minus the WIND estimate.
    Wind,
    /// The autopilot's VFR_HUD airspeed without a sensor (its own estimate).
    Estimate,
    /// The ground speed: nothing better was sent.
    Ground,
}

/// The airspeed of `s`, m/s, where it came from, and whether a sensor reading of 0 in
/// forward flight was passed over (a failed sensor).
pub fn airspeed(s: &Sample) -> (f64, AirspeedFrom, bool) {
    let ok = |v: Option<f32>| v.map(f64::from).filter(|v| v.is_finite() && *v >= 0.0);
    let ground = ground_speed(s);
    let mut failed = false;
    if s.air.airspeed_sensor {
        if let Some(v) = ok(s.air.airspeed_m_s) {
            if v < 1.0 && ground > MIN_FLYING_M_S {
                failed = true;
            } else {
                return (v, AirspeedFrom::Sensor, false);
            }
        }
    }
    if let Some(v) = ok(s.air.wind_airspeed_m_s) {
        return (v, AirspeedFrom::Wind, failed);
    }
    if !failed {
        if let Some(v) = ok(s.air.airspeed_m_s).filter(|v| !(*v < 1.0 && ground > MIN_FLYING_M_S)) {
            return (v, AirspeedFrom::Estimate, false);
        }
    }
    (ground, AirspeedFrom::Ground, failed)
}

fn feat(s: &Sample, i: usize) -> f64 {
    let v = f64::from(s.features[i]);
    if v.is_finite() {
        v
    } else {
        0.0
    }
}

/// Horizontal ground speed, m/s.
fn ground_speed(s: &Sample) -> f64 {
    feat(s, idx::VX).hypot(feat(s, idx::VY))
}

/// ISA air density at `altitude_m` (above sea level), kg/m³; with a measured air
/// temperature (°C), the ISA pressure at that altitude over R·T instead.
pub fn air_density(altitude_m: f64, temperature_c: Option<f64>) -> f64 {
    // Troposphere (ICAO standard atmosphere): T = 288.15 − 0.0065·h, p = p0·(T/T0)^5.25588.
    let h = if altitude_m.is_finite() {
        altitude_m.clamp(-500.0, 11_000.0)
    } else {
        0.0
    };
    let t_isa = 288.15 - 0.0065 * h;
    let p = 101_325.0 * (t_isa / 288.15).powf(5.255_88);
    let t = temperature_c
        .filter(|c| c.is_finite() && (-60.0..=60.0).contains(c))
        .map_or(t_isa, |c| c + 273.15);
    p / (287.053 * t)
}

/// The load factor 1/cos φ from the attitude of `s` (φ the bank, MAVLink's roll: the
/// data set's RFU→ENU quaternion turned back into FRD→NED; capped at 60°).
pub fn load_factor(s: &Sample) -> f64 {
    let q = [idx::QW, idx::QX, idx::QY, idx::QZ].map(|i| feat(s, i));
    let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    if norm.is_nan() || norm <= 1e-6 {
        return 1.0;
    }
    let [roll, _, _] = frames::euler_ned(frames::ds_to_ned(q.map(|x| x / norm)));
    let c = roll.cos();
    if c.is_finite() {
        1.0 / c.clamp(MAX_BANK_RAD.cos(), 1.0)
    } else {
        1.0
    }
}

/// The acceleration along the air path over the window, m/s²: the inertial (ground)
/// velocity's change from the oldest sample to the newest, projected on the mean heading
/// (a coordinated plane flies without sideslip, so its heading is its air path's): the
/// horizontal part (the climb is the model's own term). What the thrust does beyond
/// drag and climb: the kinetic-energy rate m·V·V̇ of the total-energy (TECS) balance. From
/// the ground velocity, not the airspeed: a gust changes the airspeed at once and costs no
/// power, the thrust that answers it does. 0 for a window under 0.3 s; clamped to ±2 g.
pub fn path_acceleration(w: &Window) -> f64 {
    let (Some(a), b) = (w.samples.first(), w.last()) else {
        return 0.0;
    };
    let dt = b.t_s - a.t_s;
    if !(dt.is_finite() && dt >= 0.3) {
        return 0.0;
    }
    let (ya, yb) = (heading(a), heading(b));
    // The mean heading, and each sample's heading from it.
    let half = wrap_pi(yb - ya) / 2.0;
    let along = |s: &Sample, d: f64| feat(s, idx::VY) * d.cos() - feat(s, idx::VX) * d.sin();
    let dv = along(b, half) - along(a, -half);
    let acc = dv / dt;
    if acc.is_finite() {
        acc.clamp(-2.0 * G, 2.0 * G)
    } else {
        0.0
    }
}

/// The heading (yaw, NED, clockwise from north) of `s`, rad; 0 without an attitude.
fn heading(s: &Sample) -> f64 {
    let q = [idx::QW, idx::QX, idx::QY, idx::QZ].map(|i| feat(s, i));
    let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    if norm.is_nan() || norm <= 1e-6 {
        return 0.0;
    }
    let [_, _, yaw] = frames::euler_ned(frames::ds_to_ned(q.map(|x| x / norm)));
    if yaw.is_finite() {
        yaw
    } else {
        0.0
    }
}

/// The energy climb rate, m/s: the climb rate `vz` plus the kinetic-energy rate over m·g,
/// V·V̇/g, so that m·g·(this) is the total-energy rate the motor pays for besides drag.
/// Clamped to ±[`MAX_CLIMB_M_S`].
pub fn energy_climb(vz: f64, v: f64, accel: f64) -> f64 {
    let c = vz + v * accel / G;
    if c.is_finite() {
        c.clamp(-MAX_CLIMB_M_S, MAX_CLIMB_M_S)
    } else {
        0.0
    }
}

/// The model's four regressors at one sample: ρV³, (n·m·g)²/(ρV), m·g·v_z and 1 (W-free
/// units: kg·m²/s³ for the first three over their coefficients), with V the airspeed
/// (floored at [`MIN_FLYING_M_S`]).
pub fn regressors(rho: f64, v: f64, n: f64, mass_kg: f64, climb_m_s: f64) -> [f64; 4] {
    let v = v.max(MIN_FLYING_M_S);
    let w = n * mass_kg * G;
    [
        rho * v * v * v,
        w * w / (rho * v),
        mass_kg * G * climb_m_s,
        1.0,
    ]
}

/// Electrical power, W, for these conditions.
pub fn power_w(p: &Params, rho: f64, v: f64, n: f64, mass_kg: f64, climb_m_s: f64) -> f64 {
    let [pv3, ind, climb, _] = regressors(rho, v, n, mass_kg, climb_m_s);
    let s = p.wing_area_m2;
    let aero = 0.5 * s * p.cd0 * pv3
        + 2.0 * ind / (s * std::f64::consts::PI * p.oswald_e * p.aspect_ratio())
        + climb;
    aero.max(0.0) / p.eta + p.offset_w
}

/// The fixed-wing model on one profile's `[fixed_wing]` figures.
pub struct FixedWing {
    params: Params,
    failures: u64,
    said_fallback: bool,
}

impl FixedWing {
    /// The model for these figures.
    pub fn new(params: Params) -> Self {
        Self {
            params,
            failures: 0,
            said_fallback: false,
        }
    }

    /// Windows whose airspeed sensor read 0 in forward flight (a failed sensor).
    pub fn sensor_failures(&self) -> u64 {
        self.failures
    }

    /// The conditions at `s` for airspeed `v`: (ρ, V, n, mass, climb), `None` on the ground.
    /// `accel` is the acceleration along the air path, m/s² ([`path_acceleration`]): the
    /// climb is the energy climb rate v_z + V·V̇/g ([`energy_climb`]).
    fn conditions(&self, s: &Sample, v: f64, accel: f64) -> Option<(f64, f64, f64, f64, f64)> {
        if v < MIN_FLYING_M_S && ground_speed(s) < MIN_FLYING_M_S {
            return None;
        }
        let rho = air_density(feat(s, idx::POS_Z), s.air.temperature_c.map(f64::from));
        let mass = self.params.mass_kg + feat(s, idx::PAYLOAD).max(0.0) / 1000.0;
        // No small plane flies these: a glitch must not read as megawatts.
        let v = v.min(MAX_AIRSPEED_M_S);
        let climb = energy_climb(feat(s, idx::VZ), v, accel);
        Some((rho, v, load_factor(s), mass, climb))
    }

    /// The model's own coefficients θ₀ on [`regressors`]: S·C_D0/(2η), 2/(S·π·e·AR·η),
    /// 1/η and P_0.
    pub fn coefficients(&self) -> [f64; 4] {
        let p = &self.params;
        let s = p.wing_area_m2;
        [
            0.5 * s * p.cd0 / p.eta,
            2.0 / (s * std::f64::consts::PI * p.oswald_e * p.aspect_ratio() * p.eta),
            1.0 / p.eta,
            p.offset_w,
        ]
    }

    /// The power for one sample alone, W (no acceleration: a window of one).
    pub fn predict_one(&mut self, s: &Sample) -> f64 {
        self.predict_at(s, 0.0)
    }

    /// The power for the window's newest sample, W, with the window's acceleration along
    /// the air path ([`path_acceleration`]).
    pub fn predict_window(&mut self, w: &Window) -> f64 {
        self.predict_at(w.last(), path_acceleration(w))
    }

    fn predict_at(&mut self, s: &Sample, accel: f64) -> f64 {
        let (v, from, failed) = airspeed(s);
        if failed {
            self.failures += 1;
            if self.failures == 1 {
                tracing::warn!("fixed_wing: the airspeed sensor reads 0 in forward flight: a failed sensor (counted), flown on {from:?} instead");
            }
        }
        if !self.said_fallback && from == AirspeedFrom::Ground && ground_speed(s) > MIN_FLYING_M_S {
            self.said_fallback = true;
            tracing::warn!("fixed_wing: no airspeed (no airspeed sensor, no VFR_HUD airspeed, no WIND): the ground speed stands in for it");
        }
        match self.conditions(s, v, accel) {
            Some((rho, v, n, mass, climb)) => power_w(&self.params, rho, v, n, mass, climb),
            None => self.params.offset_w,
        }
    }
}

impl PowerModel for FixedWing {
    fn name(&self) -> &str {
        "fixed_wing"
    }

    fn predict(&mut self, windows: &[Window], out: &mut Vec<Prediction>) {
        out.clear();
        out.extend(windows.iter().map(|w| Prediction {
            power_w: self.predict_window(w) as f32,
            band_w: None,
        }));
    }

    fn lift(&self) -> Lift {
        Lift::Wing
    }

    /// The motor runs: measured power over twice what the avionics draw (a plane's cruise
    /// is far below the multirotor hover the other models' threshold is made of).
    fn min_teach_w(&self) -> Option<f64> {
        Some(2.0 * self.params.offset_w)
    }

    /// Linear in [`regressors`] while it flies and the motor pulls (not on the ground, not
    /// in a glide, where the model is its floor P_0 and not θ·φ).
    fn regressors(&self, window: &Window) -> Option<([f64; 4], [f64; 4])> {
        let s = window.last();
        let (v, _, _) = airspeed(s);
        let (rho, v, n, mass, climb) = self.conditions(s, v, path_acceleration(window))?;
        let phi = regressors(rho, v, n, mass, climb);
        let theta0 = self.coefficients();
        let aero: f64 = (0..3).map(|k| theta0[k] * phi[k]).sum();
        (aero > 0.0 && phi.iter().all(|x| x.is_finite())).then_some((phi, theta0))
    }
}

/// What [`fit`] did: the coefficients before and after, the windows, the RMSE before and
/// after on them, and the physical figures that hit their range (clamped).
#[derive(Debug, Clone, PartialEq)]
pub struct Fit {
    pub params: Params,
    pub theta_before: [f64; 4],
    pub theta_after: [f64; 4],
    pub windows: usize,
    pub rmse_before_w: f64,
    pub rmse_after_w: f64,
    pub clamped: Vec<&'static str>,
}

/// Fit the model's four coefficients ([`FixedWing::coefficients`]) to `data`, pairs of
/// [`regressors`] and measured power (W), by least squares with the published figures as a
/// weak prior (σ = 50 % of each coefficient, 20 % of P_0, against σ_y = 20 W per window, as
/// online adaptation's; it only decides directions the data leave open) and within ×¼…×4;
/// then back to the figures, the geometry (S, b) and the mass kept:
/// η = 1/θ₃, C_D0 = 2η·θ₁/S, e = 2/(S·π·AR·η·θ₂), P_0 = θ₄, each within
/// [`Params::validate`]'s range (the clamped ones are named). None under 20 windows.
pub fn fit(params: &Params, data: &[([f64; 4], f64)]) -> Option<Fit> {
    if data.len() < 20 {
        return None;
    }
    let theta0 = FixedWing::new(*params).coefficients();
    let sigma_y2 = 20.0f64 * 20.0;
    let mut a = nalgebra::Matrix4::<f64>::zeros();
    let mut b = nalgebra::Vector4::<f64>::zeros();
    for (phi, y) in data {
        let x = nalgebra::Vector4::from_column_slice(phi);
        a += x * x.transpose() / sigma_y2;
        b += x * (*y / sigma_y2);
    }
    for k in 0..4 {
        // P_0 (avionics, servos) is what a bench measures: held close (σ 20 %, at least
        // 1 W); in steady cruise 1, V³ and 1/V barely differ and a free offset would soak
        // up the drag.
        let sd = if k == 3 {
            (0.2 * theta0[k]).max(1.0)
        } else {
            (0.5 * theta0[k]).max(1e-9)
        };
        a[(k, k)] += 1.0 / (sd * sd);
        b[k] += theta0[k] / (sd * sd);
    }
    let sol = a.lu().solve(&b)?;
    let mut theta = [0.0; 4];
    for k in 0..4 {
        let (lo, hi) = if k == 3 {
            (0.0, 4.0 * theta0[k] + 50.0)
        } else {
            (0.25 * theta0[k], 4.0 * theta0[k])
        };
        theta[k] = if sol[k].is_finite() {
            sol[k].clamp(lo, hi)
        } else {
            theta0[k]
        };
    }
    let rmse = |t: &[f64; 4]| {
        let se: f64 = data
            .iter()
            .map(|(phi, y)| {
                let aero: f64 = (0..3).map(|k| t[k] * phi[k]).sum();
                let p = aero.max(0.0) + t[3];
                (p - y).powi(2)
            })
            .sum();
        (se / data.len() as f64).sqrt()
    };
    let s = params.wing_area_m2;
    let mut clamped = Vec::new();
    let mut keep = |name: &'static str, v: f64, lo: f64, hi: f64| {
        if v.is_finite() && (lo..=hi).contains(&v) {
            v
        } else {
            clamped.push(name);
            if v.is_finite() {
                v.clamp(lo, hi)
            } else {
                lo
            }
        }
    };
    let eta = keep("eta", 1.0 / theta[2], 0.05, 1.0);
    let cd0 = keep("cd0", 2.0 * eta * theta[0] / s, 0.005, 0.5);
    let e = keep(
        "oswald_e",
        2.0 / (s * std::f64::consts::PI * params.aspect_ratio() * eta * theta[1]),
        0.3,
        1.0,
    );
    let offset = keep("offset_w", theta[3], 0.0, 5000.0);
    let fitted = Params {
        eta,
        cd0,
        oswald_e: e,
        offset_w: offset,
        ..*params
    };
    let theta_after = FixedWing::new(fitted).coefficients();
    Some(Fit {
        params: fitted,
        theta_before: theta0,
        theta_after,
        windows: data.len(),
        rmse_before_w: rmse(&theta0),
        rmse_after_w: rmse(&theta_after),
        clamped,
    })
}

#[cfg(test)]
mod tests;
