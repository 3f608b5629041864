//! The five physics power models of the comparative study, six model names plus Tseng's
//! simplified 3DR Solo form: `dandrea`, `dandrea_headwind`, `dorling`, `stolaroff`,
//! `kirschstein`, `tseng`, `tseng_solo` (calibrated variants suffixed `_cal`).
//!
//! Every model is a pure function of a [`Kinematics`] (derived from the window's newest
//! sample, and the window for accelerations), the [`VehicleProfile`] and its own parameters.
//!
//! ## How the data set's columns become airspeed, wind and attitude
//!
//! Frames are those of `../shared/data/m100/SOURCE.md`, checked again on flights 100, 150,
//! 200, 250 and 276 (see the physics helper's report):
//!
//! * **Attitude.** The quaternion `orientation_*` rotates the vehicle's body frame into
//!   world ENU with body z up: the body-up axis R·ẑ tilts *along* the ground velocity in
//!   cruise (mean projection +0.16, ≈ 9° nose-down at 10 m/s), as a multirotor's must. That
//!   axis is the thrust axis **n**. ψ = atan2(R₁₀, R₀₀) is the ENU bearing of body x.
//! * **Ground velocity.** `velocity_x/y` are the ground velocity along the quaternion's own
//!   body x and y axes, levelled (the telemetry module names them right/forward, SOURCE.md
//!   forward/left — only their being the quaternion's axes matters here): the world
//!   ground velocity is (v_x, v_y) rotated by ψ, with `velocity_z` (up) as is.
//! * **Airspeed.** `wind_speed` is the anemometer's airspeed (it grows with the drone's own
//!   speed: ≈ 1.5 m/s hovering, ≈ 11 m/s at 10 m/s). `wind_angle` (deg clockwise from
//!   north) is the bearing the apparent wind comes *from*, i.e. the bearing the drone moves
//!   through the air: the airspeed vector is u = s·(sin θ, cos θ, 0) + v_z·ẑ (no vertical
//!   wind assumed). Of the four readings (from/to × north/heading-relative), this one makes
//!   the implied ambient wind w = v_ground − u steadiest within a flight (std 1–4 m/s
//!   against 5–15 m/s for the others, flights 100, 150, 200, 250, 276); the telemetry
//!   module reached the same reading independently.
//! * **Headwind** is −w·v̂_ground (positive when the wind opposes the track).
//! * **Mass** = airframe + battery (profile) + `payload` feature (g → kg). In a VTOL's
//!   transitions the rotors carry only the weight its wing does not ([`wing_lift_n`],
//!   [`Kinematics::weight_n`]), and in the forward transition every model adds the
//!   pusher's power ([`pusher_w`]).
//! * **Acceleration** (Tseng only) is the finite difference of the world ground velocity
//!   across the window (first to last sample): the IMU's specific force carries vibration
//!   noise of several m/s², and Tseng's regressors are motion, not vibration.
//!
//! Non-finite feature values are read as 0, so no model can emit NaN or infinity.

pub mod dandrea;
pub mod dorling;
pub mod fixed_wing;
pub mod kirschstein;
pub mod stolaroff;
pub mod tseng;

use nalgebra::{Quaternion, UnitQuaternion, Vector3};

use super::profile::VehicleProfile;
use super::{PowerModel, Prediction};
use crate::features::{idx, Sample};
use crate::telemetry::window::Window;

/// The physical state every model reads, derived once per window. SI units, world ENU.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Kinematics {
    /// Total mass (airframe + battery + payload), kg.
    pub mass_kg: f64,
    /// Payload, g.
    pub payload_g: f64,
    /// Ground velocity, m/s, ENU.
    pub ground_m_s: Vector3<f64>,
    /// Airspeed vector (vehicle relative to air), m/s, ENU.
    pub air_m_s: Vector3<f64>,
    /// Ambient wind (air relative to ground) = ground − air, m/s, ENU (horizontal).
    pub wind_m_s: Vector3<f64>,
    /// Thrust axis (body up) in ENU, unit vector.
    pub thrust_axis: Vector3<f64>,
    /// Ground acceleration over the window, m/s², ENU.
    pub accel_m_s2: Vector3<f64>,
    /// The lift a VTOL's wing gives while the rotors fly it, N ([`wing_lift_n`]); 0 for
    /// every other vehicle and state.
    pub wing_lift_n: f64,
    /// A VTOL's pusher power in its forward transition, W ([`pusher_w`]); 0 otherwise.
    pub pusher_w: f64,
}

fn feat(s: &Sample, i: usize) -> f64 {
    let v = f64::from(s.features[i]);
    if v.is_finite() {
        v
    } else {
        0.0
    }
}

fn attitude(s: &Sample) -> UnitQuaternion<f64> {
    let q = Quaternion::new(
        feat(s, idx::QW),
        feat(s, idx::QX),
        feat(s, idx::QY),
        feat(s, idx::QZ),
    );
    if q.norm() > 1e-6 {
        UnitQuaternion::from_quaternion(q)
    } else {
        UnitQuaternion::identity()
    }
}

fn ground_velocity(s: &Sample, q: &UnitQuaternion<f64>) -> Vector3<f64> {
    let r = q.to_rotation_matrix();
    let m = r.matrix();
    let yaw = m[(1, 0)].atan2(m[(0, 0)]);
    let (sn, cs) = yaw.sin_cos();
    let (vx, vy) = (feat(s, idx::VX), feat(s, idx::VY));
    Vector3::new(vx * cs - vy * sn, vx * sn + vy * cs, feat(s, idx::VZ))
}

impl Kinematics {
    /// Derive the state at the window's newest sample (see the module docs for the frames).
    pub fn from_window(w: &Window, profile: &VehicleProfile) -> Self {
        let s = w.last();
        let q = attitude(s);
        let ground = ground_velocity(s, &q);
        let speed = feat(s, idx::WIND_SPEED).max(0.0);
        let bearing = feat(s, idx::WIND_ANGLE).to_radians();
        let air = Vector3::new(speed * bearing.sin(), speed * bearing.cos(), ground.z);
        let first = &w.samples[0];
        let dt = s.t_s - first.t_s;
        let accel = if dt.is_finite() && dt > 0.05 {
            (ground - ground_velocity(first, &attitude(first))) / dt
        } else {
            Vector3::zeros()
        };
        let payload_g = feat(s, idx::PAYLOAD).max(0.0);
        let lift = wing_lift_n(s, profile);
        Kinematics {
            wing_lift_n: lift,
            pusher_w: pusher_w(w, profile, lift),
            mass_kg: profile.mass_kg(payload_g / 1000.0),
            payload_g,
            ground_m_s: ground,
            air_m_s: air,
            wind_m_s: ground - air,
            thrust_axis: q * Vector3::z(),
            accel_m_s2: accel,
        }
    }

    /// Horizontal airspeed, m/s.
    pub fn airspeed_h(&self) -> f64 {
        self.air_m_s.xy().norm()
    }

    /// Headwind: the wind component against the ground track, m/s (positive = head-on).
    /// With no track to speak of (ground speed < 0.5 m/s) the whole horizontal wind is
    /// taken as head-on, the conservative reading.
    pub fn headwind(&self) -> f64 {
        let g = self.ground_m_s.xy();
        let w = self.wind_m_s.xy();
        let gs = g.norm();
        if gs < 0.5 {
            w.norm()
        } else {
            -w.dot(&g) / gs
        }
    }

    /// The weight the rotors carry, N: m·g less the wing's lift ([`Kinematics::wing_lift_n`],
    /// 0 but in a VTOL's transitions), never under [`ROTOR_SHARE_MIN`] of m·g.
    pub fn weight_n(&self, p: &VehicleProfile) -> f64 {
        let w = self.mass_kg * p.air.g_m_s2;
        (w - self.wing_lift_n).max(ROTOR_SHARE_MIN * w)
    }

    /// Steady-flight thrust, N: the vector sum of weight and parasite drag
    /// D = ½ρ·C_D A·|u|·u (drag opposes the airspeed u, so thrust supplies +D along u).
    /// The paper prints the scalar sum W + D, an upper bound that ignores that the two act
    /// at right angles in level flight; the vector sum is the physical form.
    pub fn thrust_n(&self, p: &VehicleProfile, drag_area_m2: f64) -> f64 {
        let drag =
            0.5 * p.air.rho_kg_m3 * drag_area_m2.max(0.0) * self.air_m_s.norm() * self.air_m_s;
        (Vector3::new(0.0, 0.0, self.weight_n(p)) + drag).norm()
    }
}

/// The least share of a VTOL's weight its rotors are taken to carry in a transition: 10 %
/// (they stay spun up, holding height and attitude; and a rotor model at zero thrust would
/// say only its constant). ASSUMPTION: on the validation flights any floor from 0 to 30 %
/// gives the same figures within 0.01 point.
pub const ROTOR_SHARE_MIN: f64 = 0.1;

/// The lift a VTOL's wing gives while its rotors fly it in a transition, N:
/// L = ½ρV²·S·C_L,max, the wing at its maximum lift coefficient (of which no more than the
/// weight is taken: [`Kinematics::weight_n`]), with V the
/// fixed-wing model's airspeed ([`fixed_wing::airspeed`]: VFR_HUD's with a healthy sensor,
/// else ground velocity − WIND), ρ from the altitude ([`fixed_wing::air_density`]), S and
/// C_L,max from `[fixed_wing]` (the generic plane's without it). 0 for every vehicle but a
/// VTOL, and in its other states: forward flight is the fixed-wing model's, and in MC the
/// wing is taken to carry nothing (with lift in MC too the validation flights' MC error
/// went from 4.7 to 8.0 %).
pub fn wing_lift_n(s: &Sample, p: &VehicleProfile) -> f64 {
    use crate::features::{VehicleClass, VtolState};
    let transition = matches!(
        s.vehicle.vtol_state,
        VtolState::TransitionToFw | VtolState::TransitionToMc
    );
    if s.vehicle.class != VehicleClass::Vtol || !transition {
        return 0.0;
    }
    let w = p.fixed_wing.unwrap_or_default();
    let v = fixed_wing::airspeed(s).0.min(fixed_wing::MAX_AIRSPEED_M_S);
    let rho = fixed_wing::air_density(feat(s, idx::POS_Z), s.air.temperature_c.map(f64::from));
    let l = 0.5 * rho * v * v * w.wing_area_m2 * w.cl_max;
    if l.is_finite() {
        l.max(0.0)
    } else {
        0.0
    }
}

/// A VTOL's pusher in its forward transition, W: the wing's drag and the acceleration along
/// the air path over the fixed-wing model's η, (½ρV³·S·C_D0 + 2L²/(ρV·S·π·e·AR) + m·V·V̇)/η
/// (≥ 0), with L the lift the wing gives (`wing_lift_n`, from [`wing_lift_n`()], taken at
/// most the weight) and V̇ [`fixed_wing::path_acceleration`]; 0 in every other state (the
/// back transition flies with the pusher off) and for every other vehicle.
pub fn pusher_w(win: &Window, p: &VehicleProfile, wing_lift_n: f64) -> f64 {
    use crate::features::{VehicleClass, VtolState};
    let s = win.last();
    if s.vehicle.class != VehicleClass::Vtol || s.vehicle.vtol_state != VtolState::TransitionToFw {
        return 0.0;
    }
    let w = p.fixed_wing.unwrap_or_default();
    let v = fixed_wing::airspeed(s)
        .0
        .clamp(fixed_wing::MIN_FLYING_M_S, fixed_wing::MAX_AIRSPEED_M_S);
    let rho = fixed_wing::air_density(feat(s, idx::POS_Z), s.air.temperature_c.map(f64::from));
    let m = p.mass_kg(feat(s, idx::PAYLOAD).max(0.0) / 1000.0);
    let lift = wing_lift_n.min(m * p.air.g_m_s2);
    let aero = 0.5 * rho * v.powi(3) * w.wing_area_m2 * w.cd0
        + 2.0 * lift * lift
            / (rho * v * w.wing_area_m2 * std::f64::consts::PI * w.oswald_e * w.aspect_ratio())
        + m * v * fixed_wing::path_acceleration(win);
    let pw = aero.max(0.0) / w.eta;
    if pw.is_finite() {
        pw
    } else {
        0.0
    }
}

/// Induced velocity v_i (m/s) of an actuator disk of total area `area_m2` (m²) giving
/// thrust `thrust_n` (N) in a stream with components `v_t` along the disk and `v_n`
/// through it (m/s, positive when air flows down through the disk as in forward flight
/// with the disk tilted into the motion or in a climb):
///
/// v_i = T / (2ρA·√(v_t² + (v_n + v_i)²))   (Glauert; Leishman, *Principles of Helicopter
/// Aerodynamics*, 2006, §2.14), i.e. the quartic
/// v_i⁴ + 2v_n·v_i³ + (v_t² + v_n²)·v_i² − v_h⁴ = 0 with v_h = √(T/(2ρA)) (hover, closed form).
///
/// Solved on its bracket [0, v_h + max(0, −v_n)], where g(v) = v·√(v_t² + (v_n+v)²) − v_h²
/// changes sign, by Newton steps kept inside the bracket (bisection when a step leaves it),
/// so it converges for every input; in steep descent (vortex-ring state, where momentum
/// theory is invalid anyway) it returns one root of the bracket.
pub fn induced_velocity(thrust_n: f64, rho: f64, area_m2: f64, v_t: f64, v_n: f64) -> f64 {
    if !(thrust_n > 0.0 && rho > 0.0 && area_m2 > 0.0) {
        return 0.0;
    }
    let vh2 = thrust_n / (2.0 * rho * area_m2);
    let (v_t, v_n) = (
        if v_t.is_finite() { v_t } else { 0.0 },
        if v_n.is_finite() { v_n } else { 0.0 },
    );
    let g = |v: f64| {
        let s = (v_t * v_t + (v_n + v) * (v_n + v)).sqrt();
        (
            v * s - vh2,
            if s > 0.0 { s + v * (v_n + v) / s } else { 0.0 },
        )
    };
    let (mut lo, mut hi) = (0.0, vh2.sqrt() + (-v_n).max(0.0));
    let mut v = hi;
    for _ in 0..60 {
        let (f, df) = g(v);
        if f.abs() <= 1e-12 * vh2 {
            break;
        }
        if f > 0.0 {
            hi = v;
        } else {
            lo = v;
        }
        let newton = v - f / df;
        v = if df > 0.0 && newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        if hi - lo < 1e-12 * (1.0 + hi) {
            break;
        }
    }
    v
}

/// Which physics model. Its name (strum's `IntoStaticStr`) is the snake-case variant,
/// but for D'Andrea's, written without the underscore.
#[derive(Debug, Clone, Copy, PartialEq, Eq, strum::IntoStaticStr, strum::VariantArray)]
#[strum(serialize_all = "snake_case")]
pub enum Kind {
    #[strum(serialize = "dandrea")]
    DAndrea,
    #[strum(serialize = "dandrea_headwind")]
    DAndreaHeadwind,
    Dorling,
    Stolaroff,
    Kirschstein,
    Tseng,
    TsengSolo,
}

impl Kind {
    /// Every physics model, in the order tables show them (the paper's order).
    pub const ALL: &'static [Kind] = <Kind as strum::VariantArray>::VARIANTS;

    /// The model's base name (without `_cal`): `dandrea`, `dandrea_headwind`, `dorling`,
    /// `stolaroff`, `kirschstein`, `tseng`, `tseng_solo`.
    pub fn name(self) -> &'static str {
        self.into()
    }

    /// Predicted electrical power, W, for this state under this profile.
    pub fn power_w(self, k: &Kinematics, p: &VehicleProfile) -> f64 {
        let w = match self {
            Kind::DAndrea => dandrea::power_w(k, p, &p.dandrea, false),
            Kind::DAndreaHeadwind => dandrea::power_w(k, p, &p.dandrea_headwind, true),
            Kind::Dorling => dorling::power_w(k, p, &p.dorling),
            Kind::Stolaroff => stolaroff::power_w(k, p, &p.stolaroff),
            Kind::Kirschstein => kirschstein::power_w(k, p, &p.kirschstein),
            Kind::Tseng => tseng::power_w(k, &p.tseng),
            Kind::TsengSolo => tseng::solo_power_w(k, &p.tseng_solo),
        } + k.pusher_w;
        if w.is_finite() {
            w
        } else {
            0.0
        }
    }
}

/// One physics model bound to a profile: what the ensemble runs.
pub struct PhysicsModel {
    kind: Kind,
    name: String,
    profile: VehicleProfile,
}

impl PhysicsModel {
    /// This model with this profile; named `kind.name()` plus `_cal` for a calibrated profile.
    pub fn new(kind: Kind, profile: VehicleProfile) -> Self {
        Self {
            kind,
            name: format!("{}{}", kind.name(), profile.name_suffix()),
            profile,
        }
    }
    /// Power for one window, W.
    pub fn power_w(&self, w: &Window) -> f64 {
        self.kind
            .power_w(&Kinematics::from_window(w, &self.profile), &self.profile)
    }
}

impl PowerModel for PhysicsModel {
    fn name(&self) -> &str {
        &self.name
    }
    fn predict(&mut self, windows: &[Window], out: &mut Vec<Prediction>) {
        out.clear();
        out.extend(windows.iter().map(|w| Prediction {
            power_w: self.power_w(w) as f32,
            band_w: None,
        }));
    }
}

/// Every physics model for this profile, in [`Kind::ALL`] order.
pub fn models(profile: &VehicleProfile) -> Vec<Box<dyn PowerModel>> {
    Kind::ALL
        .iter()
        .map(|&k| Box::new(PhysicsModel::new(k, profile.clone())) as Box<dyn PowerModel>)
        .collect()
}

#[cfg(test)]
mod name_tests {
    /// The models' names, as tables, JSON and the config write them.
    #[test]
    fn kinds_are_named_in_the_papers_order() {
        let names: Vec<&str> = super::Kind::ALL.iter().map(|k| k.name()).collect();
        assert_eq!(
            names,
            [
                "dandrea",
                "dandrea_headwind",
                "dorling",
                "stolaroff",
                "kirschstein",
                "tseng",
                "tseng_solo"
            ]
        );
    }
}

#[cfg(test)]
pub(crate) mod testutil {
    use super::Kinematics;
    use crate::features::{idx, Sample, N_FEATURES};
    use crate::model::profile::VehicleProfile;
    use crate::telemetry::window::Window;

    /// A level sample: velocity along body (x, y, up), anemometer speed and bearing (deg),
    /// payload g, and yaw (deg, ENU bearing of body x from east: 90° = body x north).
    pub fn sample(
        t_s: f64,
        v_body: [f32; 3],
        wind_speed: f32,
        wind_angle_deg: f32,
        payload_g: f32,
        yaw_deg: f32,
    ) -> Sample {
        let mut f = [0.0f32; N_FEATURES];
        let h = yaw_deg.to_radians() / 2.0;
        f[idx::QW] = h.cos();
        f[idx::QZ] = h.sin();
        f[idx::VX] = v_body[0];
        f[idx::VY] = v_body[1];
        f[idx::VZ] = v_body[2];
        f[idx::WIND_SPEED] = wind_speed;
        f[idx::WIND_ANGLE] = wind_angle_deg;
        f[idx::PAYLOAD] = payload_g;
        f[idx::AZ] = -9.81;
        Sample::new(t_s, f, None)
    }

    /// Level flight with body x north at 10 m/s carrying 500 g, the anemometer at
    /// `wind_speed` m/s, bearing `wind_angle_deg`: the hand-computed cases' flight.
    pub fn north_at_10(wind_speed: f32, wind_angle_deg: f32) -> Sample {
        sample(
            1.0,
            [10.0, 0.0, 0.0],
            wind_speed,
            wind_angle_deg,
            500.0,
            90.0,
        )
    }

    /// What every model reads from a window of `s` (and `s` 0.9 s earlier), for `p`.
    pub fn kinematics(s: Sample, p: &VehicleProfile) -> Kinematics {
        Kinematics::from_window(&window(s), p)
    }

    /// The M100 and what its models read in [`north_at_10`]'s flight: the hand-computed
    /// cases' vehicle and window.
    pub fn m100_north_at_10(wind_speed: f32, wind_angle_deg: f32) -> (VehicleProfile, Kinematics) {
        let p = VehicleProfile::m100();
        let k = kinematics(north_at_10(wind_speed, wind_angle_deg), &p);
        (p, k)
    }

    pub fn window(s: Sample) -> Window {
        let mut a = s.clone();
        a.t_s -= 0.9;
        Window {
            samples: vec![a, s],
            arrived: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::testutil::*;
    use super::*;

    #[test]
    fn hover_closed_form() {
        for t in [5.0, 30.0, 300.0] {
            let v = induced_velocity(t, 1.225, 0.3425, 0.0, 0.0);
            let vh = (t / (2.0 * 1.225 * 0.3425f64)).sqrt();
            assert!((v - vh).abs() < 1e-9 * vh, "{v} vs {vh}");
        }
    }

    #[test]
    fn climb_closed_form_and_forward_flight_root() {
        // Axial climb: v_i = −v_c/2 + √((v_c/2)² + v_h²).
        let (t, rho, a, vc): (f64, f64, f64, f64) = (30.0, 1.225, 0.3425, 3.0);
        let vh2 = t / (2.0 * rho * a);
        let exact = -vc / 2.0 + (vc * vc / 4.0 + vh2).sqrt();
        assert!((induced_velocity(t, rho, a, 0.0, vc) - exact).abs() < 1e-9);
        // Forward flight: the root satisfies the quartic, and is below hover's.
        for (vt, vn) in [
            (10.0, 1.5),
            (20.0, 3.0),
            (3.0, -2.0),
            (0.0, -12.0),
            (1e-9, 0.0),
        ] {
            let v = induced_velocity(t, rho, a, vt, vn);
            let q = v.powi(4) + 2.0 * vn * v.powi(3) + (vt * vt + vn * vn) * v * v - vh2 * vh2;
            assert!(
                q.abs() < 1e-7 * vh2 * vh2,
                "({vt},{vn}) → {v}: residual {q}"
            );
            assert!(v.is_finite() && v >= 0.0);
        }
    }

    /// A quadplane at `v` m/s of sensor airspeed, level at sea level, body x north, in `state`.
    fn vtol_window(state: crate::features::VtolState, v: f32) -> (Window, VehicleProfile) {
        use crate::features::{VehicleClass, VehicleKind};
        let p = VehicleProfile::named_or_file("quadplane").expect("built in");
        let mut s = sample(1.0, [v, 0.0, 0.0], v, 0.0, 0.0, 90.0);
        s.vehicle = VehicleKind {
            class: VehicleClass::Vtol,
            mav_type: Some(1),
            vtol_state: state,
            from_config: false,
        };
        s.air.airspeed_m_s = Some(v);
        s.air.airspeed_sensor = true;
        (window(s), p)
    }

    #[test]
    fn a_vtol_wing_carries_its_share_in_transitions_only() {
        use crate::features::VtolState;
        let g = 9.81;
        // X8 quadplane: 3.9 kg, S 0.75 m², C_L,max 1.0; ISA sea level ρ 1.2250 kg/m³.
        let w_full = 3.9 * g;
        // Back transition at 5 m/s: L = ½·1.225·25·0.75·1.0 = 11.484 N; rotors 38.259 − 11.484.
        let (w, p) = vtol_window(VtolState::TransitionToMc, 5.0);
        let k = Kinematics::from_window(&w, &p);
        assert!((k.wing_lift_n - 11.484).abs() < 0.01, "{}", k.wing_lift_n);
        assert!((k.weight_n(&p) - (w_full - 11.484)).abs() < 0.01);
        assert_eq!(
            k.pusher_w, 0.0,
            "the back transition flies with the pusher off"
        );
        // At 17 m/s the wing could carry it all: the rotors keep their 10 % floor.
        let (w, p) = vtol_window(VtolState::TransitionToMc, 17.0);
        let k = Kinematics::from_window(&w, &p);
        assert!((k.weight_n(&p) - ROTOR_SHARE_MIN * w_full).abs() < 1e-9);
        // MC and FW at the same speed: the rotor models see the whole weight.
        for st in [VtolState::Mc, VtolState::Fw, VtolState::Undefined] {
            let (w, p) = vtol_window(st, 5.0);
            let k = Kinematics::from_window(&w, &p);
            assert_eq!(k.wing_lift_n, 0.0);
            assert!((k.weight_n(&p) - w_full).abs() < 1e-9);
        }
        // A multirotor flying fast: unchanged.
        let p = VehicleProfile::m100();
        let k = kinematics(north_at_10(13.0, 0.0), &p);
        assert_eq!((k.wing_lift_n, k.pusher_w), (0.0, 0.0));
        assert!((k.weight_n(&p) - k.mass_kg * p.air.g_m_s2).abs() < 1e-12);
    }

    #[test]
    fn the_forward_transition_adds_the_pusher() {
        use crate::features::VtolState;
        // Steady 10 m/s (no acceleration): L = ½·1.225·100·0.75 = 45.94 N, over the weight
        // 38.259 N, so L = 38.259 N; parasitic ½·1.225·1000·0.75·0.0197 = 9.050 W; induced
        // 2·38.259² / (1.225·10·0.75·π·0.87·5.88) = 19.83 W; over η 0.5: 57.75 W.
        let (w, p) = vtol_window(VtolState::TransitionToFw, 10.0);
        let k = Kinematics::from_window(&w, &p);
        assert!((k.pusher_w - 57.75).abs() < 0.05, "{}", k.pusher_w);
        let base = Kind::Dorling.power_w(&Kinematics { pusher_w: 0.0, ..k }, &p);
        assert!((Kind::Dorling.power_w(&k, &p) - base - k.pusher_w).abs() < 1e-9);
    }

    #[test]
    fn frames_airspeed_and_headwind() {
        // Body x north (yaw 90° ENU), 10 m/s along it, anemometer 13 m/s bearing 0° (north):
        // the air moves past at 13 m/s while the ground track is 10 m/s → 3 m/s headwind.
        let (_, k) = m100_north_at_10(13.0, 0.0);
        assert!((k.ground_m_s - Vector3::new(0.0, 10.0, 0.0)).norm() < 1e-5);
        assert!((k.air_m_s - Vector3::new(0.0, 13.0, 0.0)).norm() < 1e-5);
        assert!((k.headwind() - 3.0).abs() < 1e-5);
        assert!((k.mass_kg - 2.931).abs() < 1e-9);
        assert!((k.thrust_axis - Vector3::z()).norm() < 1e-9);
    }
}
