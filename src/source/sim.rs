//! A simulator: an M100-like delivery mission with a physically plausible power draw,
//! sent as the telemetry a real autopilot would send.
//!
//! Why: the project must run end to end without a drone. The M100 data set replays what was
//! flown; the simulator flies what was never flown (other payloads, speeds, winds) and
//! exercises the live path with an autopilot's message mix — ArduPilot's by default
//! (ATTITUDE, RAW_IMU, WIND, no quaternion), PX4's with `--autopilot px4`
//! (ATTITUDE_QUATERNION, HIGHRES_IMU, ALTITUDE, EXTENDED_SYS_STATE, no WIND).
//!
//! ## Mission
//! Pre-arm on the ground, arm and spin up, climb vertically to the set altitude, fly an
//! equilateral triangle of side `leg_m` (north, then south-east, then back home), hover
//! `hover_s` over home (the delivery), descend, land, disarm.
//!
//! ## Flight model (point mass, kinematic)
//! A guidance law turns the next waypoint into a desired velocity (commanded speed, braking
//! as `√(2·a_brake·d)` near the point); the commanded acceleration `K_v·(v_des − v)`,
//! clipped, passes a first-order lag (τ = 0.25 s) and is integrated into velocity and
//! position (NED, m, relative to home). Wind (mean plus a Gauss–Markov gust) changes the
//! air-relative velocity `v_a = v − w` and hence drag, tilt and power, not the track (the
//! position controller holds it). The thrust vector follows from Newton:
//! `T = m·(a − g) + ½ρ·f·|v_a|·v_a` (NED, g = (0, 0, 9.80665)); the body z axis is `−T/|T|`,
//! the yaw follows the track (rate-limited), and body rates come from successive attitudes.
//!
//! ## Power (momentum theory, see [`Airframe::power`])
//! `P_elec = (P_induced + P_profile + P_parasitic + P_climb) / η + P_avionics`, with the
//! induced velocity of forward flight solved iteratively. The battery ([`Battery`]) turns
//! that power into voltage and current with `V = OCV(SoC) − I·R`, `V·I = P`.
//!
//! Everything random (sensor noise, gusts) comes from one RNG seeded by `--seed`: the same
//! arguments give a byte-identical `.tlog`.

use std::f64::consts::PI;
use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;
use mavlink::{MavHeader, MavlinkVersion};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use rand::rngs::StdRng;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

use crate::dialect as d;
use crate::MavMessage;

/// Standard gravity, m/s².
const G: f64 = 9.80665;

/// Arguments of `dronewatt simulate`.
#[derive(Debug, Clone, clap::Args)]
pub struct SimulateArgs {
    /// Write the flight to this `.tlog` file.
    #[arg(long, value_name = "FILE.tlog", conflicts_with = "udp", required_unless_present = "udp")]
    pub out: Option<PathBuf>,
    /// Stream the flight's MAVLink frames to this UDP address (`dronewatt monitor udpin:…`).
    #[arg(long, value_name = "HOST:PORT")]
    pub udp: Option<String>,
    /// Commanded cruise ground speed, m/s.
    #[arg(long, default_value_t = 10.0)]
    pub speed_mps: f64,
    /// Cruise altitude above home, m.
    #[arg(long, default_value_t = 25.0)]
    pub altitude_m: f64,
    /// Payload, g.
    #[arg(long, default_value_t = 500.0)]
    pub payload_g: f64,
    /// Mean wind speed, m/s.
    #[arg(long, default_value_t = 3.0)]
    pub wind_mps: f64,
    /// Direction the wind comes FROM, degrees clockwise from north (meteorological).
    #[arg(long, default_value_t = 270.0)]
    pub wind_dir_deg: f64,
    /// Side of the triangle, m.
    #[arg(long, default_value_t = 300.0)]
    pub leg_m: f64,
    /// Hover time over home after the triangle (the delivery), s.
    #[arg(long, default_value_t = 20.0)]
    pub hover_s: f64,
    /// Seed of the noise and gusts.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Pace of `--udp`: `real` (wall clock, the default), `max` (flat out) or a factor such
    /// as `5` (five times real time). A `--out` tlog is always written at once.
    #[arg(long)]
    pub rate: Option<Rate>,
    /// Whose telemetry style to imitate.
    #[arg(long, value_enum, default_value_t = Autopilot::Ardupilot)]
    pub autopilot: Autopilot,
}

/// How fast the simulator emits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Rate {
    /// Flat out.
    Max,
    /// Simulated seconds per wall-clock second (1 = real time).
    Factor(f64),
}

impl std::str::FromStr for Rate {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "max" => Ok(Rate::Max),
            "real" => Ok(Rate::Factor(1.0)),
            other => match other.trim_end_matches('x').parse::<f64>() {
                Ok(f) if f > 0.0 && f.is_finite() => Ok(Rate::Factor(f)),
                _ => Err(format!("rate '{s}': expected real, max or a positive factor such as 5")),
            },
        }
    }
}

/// Whose message set and conventions the output follows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Autopilot {
    /// ArduPilot Copter: ATTITUDE, RAW_IMU (mG, mrad/s), WIND, VFR_HUD, no quaternion.
    Ardupilot,
    /// PX4: ATTITUDE_QUATERNION, HIGHRES_IMU (SI), ALTITUDE, EXTENDED_SYS_STATE, no WIND.
    Px4,
}

/// A mission: what `dronewatt simulate` flies. Built from [`SimulateArgs`]; tests build it
/// directly.
#[derive(Debug, Clone, PartialEq)]
pub struct Mission {
    /// Commanded cruise ground speed, m/s.
    pub speed_mps: f64,
    /// Cruise altitude above home, m.
    pub altitude_m: f64,
    /// Payload, g.
    pub payload_g: f64,
    /// Mean wind speed, m/s.
    pub wind_mps: f64,
    /// Direction the wind comes from, degrees clockwise from north.
    pub wind_dir_deg: f64,
    /// Triangle side, m.
    pub leg_m: f64,
    /// Hover time over home, s.
    pub hover_s: f64,
    /// RNG seed.
    pub seed: u64,
    /// Telemetry style.
    pub autopilot: Autopilot,
}

impl Default for Mission {
    fn default() -> Self {
        Self {
            speed_mps: 10.0,
            altitude_m: 25.0,
            payload_g: 500.0,
            wind_mps: 3.0,
            wind_dir_deg: 270.0,
            leg_m: 300.0,
            hover_s: 20.0,
            seed: 1,
            autopilot: Autopilot::Ardupilot,
        }
    }
}

impl Mission {
    fn validate(&self) -> anyhow::Result<()> {
        let check = |ok: bool, what: &str| if ok { Ok(()) } else { Err(anyhow::anyhow!("{what}")) };
        check(self.speed_mps > 0.5 && self.speed_mps <= 20.0, "--speed-mps must be in (0.5, 20] (the M100 tops out near 17–22 m/s)")?;
        check(self.altitude_m >= 2.0 && self.altitude_m <= 500.0, "--altitude-m must be in [2, 500]")?;
        check(self.payload_g >= 0.0 && self.payload_g <= 1200.0, "--payload-g must be in [0, 1200] (the M100's payload limit is about 1 kg)")?;
        check(self.wind_mps >= 0.0 && self.wind_mps <= 15.0, "--wind-mps must be in [0, 15]")?;
        check(self.wind_dir_deg.is_finite(), "--wind-dir-deg must be a number")?;
        check(self.leg_m >= 10.0 && self.leg_m <= 5000.0, "--leg-m must be in [10, 5000]")?;
        check(self.hover_s >= 0.0 && self.hover_s <= 3600.0, "--hover-s must be in [0, 3600]")?;
        Ok(())
    }

    /// Take-off mass, kg: airframe + battery + payload.
    pub fn mass_kg(&self) -> f64 {
        M100.airframe_kg + M100.battery_kg + self.payload_g / 1000.0
    }

    /// Mean wind velocity (where the air moves TO), NED, m/s.
    fn wind_ned(&self) -> Vector3<f64> {
        let from = self.wind_dir_deg.to_radians();
        Vector3::new(-self.wind_mps * from.cos(), -self.wind_mps * from.sin(), 0.0)
    }
}

/// The airframe and rotor constants of the power model.
///
/// | constant | value | source / assumption |
/// |---|---|---|
/// | `airframe_kg` | 1.755 | DJI M100 spec: 2355 g take-off weight with the TB47D battery (600 g), minus that battery |
/// | `battery_kg` | 0.676 | DJI TB48D spec (5700 mAh, 22.8 V, 6S LiPo) |
/// | `rotors` | 4 | quadcopter |
/// | `rotor_radius_m` | 0.1651 | DJI 1345 propellers: 13 in diameter (the 650 mm diagonal frame carries them) |
/// | `rho` | 1.225 kg/m³ | ISA sea level (the data set's site is ~270 m ASL: ρ ≈ 1.19; the 3 % is inside the calibration) |
/// | `kappa` | 1.15 | induced-power factor for non-uniform inflow and tip loss, a usual value for small rotors (Leishman, *Principles of Helicopter Aerodynamics*, ch. 3) |
/// | `solidity` | 0.085 | 2 blades × ~22 mm mean chord / (π R): assumption from the 1345 blade shape |
/// | `cd0` | 0.02 | blade profile drag coefficient at the low Reynolds numbers of 13-in props: assumption |
/// | `ct` | 0.011 | thrust coefficient `T/(ρ A (ΩR)²)`; gives ~4 600 rpm in a 500 g hover (assumption, typical of M100-class props) |
/// | `drag_area_m2` | 0.10 | flat-plate drag area `C_D·A` of body, arms, battery and payload (assumption; tuned so 10 m/s cruise draws ~5–10 % less than hover, as in the data set's flights) |
/// | `avionics_w` | 30 | N1 flight controller, GPS, Lightbridge link and the research sensors (anemometer, logger): assumption |
/// | `efficiency` | 0.48 | motor × ESC × (momentum theory → real small prop) efficiency; **calibrated** so a 500 g hover draws ~520 W, the data set's median hover power at 500 g (523 W over 3 024 hover rows; flight 276's median over the whole flight is 503 W) |
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Airframe {
    /// Airframe without battery, kg.
    pub airframe_kg: f64,
    /// Battery, kg.
    pub battery_kg: f64,
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
    /// Mechanical → electrical efficiency η.
    pub efficiency: f64,
}

/// The DJI Matrice 100 (see [`Airframe`] for every number's source).
pub const M100: Airframe = Airframe {
    airframe_kg: 1.755,
    battery_kg: 0.676,
    rotors: 4.0,
    rotor_radius_m: 0.1651,
    rho: 1.225,
    kappa: 1.15,
    solidity: 0.085,
    cd0: 0.02,
    ct: 0.011,
    drag_area_m2: 0.10,
    avionics_w: 30.0,
    efficiency: 0.48,
};

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

impl Airframe {
    /// Disk area of one rotor, m².
    pub fn disk_area_m2(&self) -> f64 {
        PI * self.rotor_radius_m * self.rotor_radius_m
    }

    /// Thrust vector (NED, N) needed to give a mass `mass_kg` the acceleration `accel_ned`
    /// against gravity and the drag of the air-relative velocity `v_air_ned`:
    /// `T = m·(a − g) + ½ρ·f·|v_a|·v_a`.
    pub fn thrust_ned(&self, mass_kg: f64, v_air_ned: Vector3<f64>, accel_ned: Vector3<f64>) -> Vector3<f64> {
        mass_kg * (accel_ned - Vector3::new(0.0, 0.0, G)) + 0.5 * self.rho * self.drag_area_m2 * v_air_ned.norm() * v_air_ned
    }

    /// Electrical power for a vehicle of `mass_kg` moving at `v_air_ned` through the air
    /// (NED, m/s) while accelerating at `accel_ned` (NED, m/s²).
    ///
    /// Per rotor, thrust `T_r = |T|/N` on disk area `A`. Momentum theory in forward flight
    /// (Glauert): `v_i = v_h² / √(V_p² + (V_n + v_i)²)` with `v_h² = T_r/(2ρA)`, `V_n = v_a·n`
    /// the flow through the disk along the thrust axis `n` and `V_p` the in-plane part;
    /// solved by damped fixed-point iteration. Then
    /// - induced `P_i = κ·|T|·v_i`
    /// - profile `P_0 = N·(σ·C_d0/8)·ρ·A·(ΩR)³·(1 + 4.65 μ²)`, `ΩR = √(T_r/(C_T ρ A))`, `μ = V_p/ΩR`
    /// - parasitic `P_p = ½ρ·f·|v_a|³`
    /// - climb `P_c = m·g·v_up`
    /// - `P_elec = max(P_i + P_0 + P_p + P_c, P_i/2) / η + P_avionics` (the floor keeps a
    ///   fast descent from drawing less than the rotors need to turn).
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

/// The TB48D battery: 6S LiPo, 5700 mAh, 22.8 V nominal.
///
/// Open-circuit voltage per cell vs state of charge is a typical LiPo curve (piecewise
/// linear, 3.30 V empty … 4.35 V full: the TB48D charges to 26.1 V); the pack's internal
/// resistance `R = 0.05 Ω` (about 8 mΩ a cell, an assumption) makes the voltage sag under
/// load. For a power draw P the current solves `P = (OCV − I·R)·I`, so `V·I = P` exactly.
/// The state of charge falls with the charge drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Battery {
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

/// (state of charge, cell open-circuit voltage V).
const OCV_CURVE: [(f64, f64); 11] = [
    (0.0, 3.30),
    (0.05, 3.60),
    (0.1, 3.68),
    (0.2, 3.74),
    (0.3, 3.78),
    (0.4, 3.82),
    (0.5, 3.87),
    (0.6, 3.93),
    (0.8, 4.08),
    (0.9, 4.20),
    (1.0, 4.35),
];

impl Battery {
    /// A TB48D at state of charge `soc`.
    pub fn tb48d(soc: f64) -> Self {
        Self { capacity_ah: 5.7, cells: 6.0, r_ohm: 0.05, soc: soc.clamp(0.0, 1.0), drawn_ah: 0.0, drawn_wh: 0.0 }
    }

    /// Open-circuit pack voltage, V.
    pub fn ocv_v(&self) -> f64 {
        let s = self.soc.clamp(0.0, 1.0);
        let mut cell = OCV_CURVE[OCV_CURVE.len() - 1].1;
        for w in OCV_CURVE.windows(2) {
            let ((s0, v0), (s1, v1)) = (w[0], w[1]);
            if s <= s1 {
                cell = v0 + (v1 - v0) * (s - s0) / (s1 - s0);
                break;
            }
        }
        cell * self.cells
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

/// One emitted message: tlog timestamp (µs since the Unix epoch), header, message.
#[derive(Debug, Clone)]
pub struct SimRecord {
    /// µs since the Unix epoch.
    pub t_us: u64,
    /// System 1, component 1, running sequence.
    pub header: MavHeader,
    /// The message.
    pub msg: MavMessage,
}

/// The simulator's ground truth at 10 Hz, for tests and the report: what the sensors saw
/// before noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthSample {
    /// s since the start of the simulation.
    pub t_s: f64,
    /// Mission phase.
    pub phase: Phase,
    /// Electrical power, W.
    pub power_w: f64,
    /// Terminal voltage, V.
    pub voltage_v: f64,
    /// Ground speed (horizontal), m/s.
    pub ground_speed_mps: f64,
    /// Height above home, m.
    pub height_m: f64,
}

/// Mission phases.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// On the ground, disarmed, before take-off.
    PreArm,
    /// Armed, props spinning on the ground.
    Spinup,
    /// Vertical climb to altitude.
    Climb,
    /// Flying the triangle leg `n` (0..3).
    Leg(u8),
    /// Hovering over home.
    Hover,
    /// Descending and landing.
    Descent,
    /// Landed, about to disarm.
    Landed,
    /// Disarmed after the flight.
    Done,
}

/// A simulated flight: every message in time order, plus the ground truth.
#[derive(Debug, Clone)]
pub struct SimFlight {
    /// Messages, in time order.
    pub records: Vec<SimRecord>,
    /// Ground truth at 10 Hz.
    pub truth: Vec<TruthSample>,
}

impl SimFlight {
    /// The flight as `.tlog` bytes (MAVLink 2 frames behind 8-byte µs timestamps).
    pub fn to_tlog(&self) -> Vec<u8> {
        let mut buf = Vec::with_capacity(self.records.len() * 48);
        for r in &self.records {
            super::tlog::write_record(&mut buf, r.t_us, r.header, &r.msg, MavlinkVersion::V2);
        }
        buf
    }
}

/// Start of every simulated flight: 2019-10-24 13:32:00 UTC (09:32 local at the data set's
/// site, the start of flight 276), so timestamps look like a real log.
pub const EPOCH_START_US: u64 = 1_571_923_920_000_000;

/// Home: the data set's site near Pittsburgh (flight 276 starts at 40.459060 N,
/// −79.782820 E, 268.7 m above sea level).
pub const HOME_LAT_DEG: f64 = 40.459_060;
/// Home longitude, deg.
pub const HOME_LON_DEG: f64 = -79.782_820;
/// Home altitude above sea level, m.
pub const HOME_ALT_M: f64 = 268.7;

/// Initial state of charge of the battery.
const START_SOC: f64 = 0.9;
/// Simulation step, s.
const DT: f64 = 0.01;
const PREARM_S: f64 = 5.0;
const SPINUP_S: f64 = 3.0;
const LANDED_S: f64 = 3.0;
const DONE_S: f64 = 3.0;
const CLIMB_MPS: f64 = 2.5;
const DESCENT_MPS: f64 = 1.5;
const LAND_MPS: f64 = 0.5;
const A_MAX_H: f64 = 3.0;
const A_MAX_V: f64 = 2.0;
const A_BRAKE: f64 = 1.5;
const K_V: f64 = 1.2;
const TAU_A: f64 = 0.25;
const YAW_RATE_MAX: f64 = 45.0 * PI / 180.0;
/// Power on the ground with the props idling, W (motors at idle, avionics on).
const IDLE_W: f64 = 60.0;

/// Gauss–Markov (first-order) noise: `x ← x·e^{−dt/τ} + σ·√(1−e^{−2dt/τ})·N(0,1)`.
#[derive(Debug, Clone, Copy)]
struct Markov {
    x: f64,
    sigma: f64,
    tau: f64,
}

impl Markov {
    fn step(&mut self, rng: &mut StdRng, dt: f64) -> f64 {
        let a = (-dt / self.tau).exp();
        self.x = self.x * a + self.sigma * (1.0 - a * a).sqrt() * std_normal(rng);
        self.x
    }
}

fn std_normal(rng: &mut StdRng) -> f64 {
    // Normal::new(0, 1) cannot fail.
    Normal::new(0.0, 1.0).map(|n| n.sample(rng)).unwrap_or(0.0)
}

/// Periodic emission schedule: period and phase offset, in ms of simulated time.
struct Every {
    period_ms: u64,
    offset_ms: u64,
}

impl Every {
    fn due(&self, t_ms: u64) -> bool {
        t_ms >= self.offset_ms && (t_ms - self.offset_ms).is_multiple_of(self.period_ms)
    }
}

/// The full vehicle state the telemetry is made from.
struct State {
    pos: Vector3<f64>,
    vel: Vector3<f64>,
    acc: Vector3<f64>,
    yaw: f64,
    rot: Rotation3<f64>,
    rates: Vector3<f64>,
    wind: Vector3<f64>,
    power_w: f64,
    voltage_v: f64,
    current_a: f64,
    armed: bool,
    in_air: bool,
    throttle: f64,
}

/// Fly `mission` and return every message and the ground truth. Pure computation.
pub fn simulate(mission: &Mission) -> anyhow::Result<SimFlight> {
    mission.validate()?;
    let mut rng = StdRng::seed_from_u64(mission.seed);
    let mass = mission.mass_kg();
    let mut battery = Battery::tb48d(START_SOC);
    let l = mission.leg_m;
    let h = -mission.altitude_m;
    let waypoints = [
        Vector3::new(l, 0.0, h),
        Vector3::new(l / 2.0, l * 3f64.sqrt() / 2.0, h),
        Vector3::new(0.0, 0.0, h),
    ];
    let mean_wind = mission.wind_ned();
    let gust_sigma = 0.1 * mission.wind_mps + 0.2;
    let mut gust = [Markov { x: 0.0, sigma: gust_sigma, tau: 4.0 }; 3];
    gust[2].sigma = 0.3 * gust_sigma;
    let mut gps_err = [
        Markov { x: 0.0, sigma: 0.6, tau: 20.0 },
        Markov { x: 0.0, sigma: 0.6, tau: 20.0 },
        Markov { x: 0.0, sigma: 0.4, tau: 10.0 },
    ];
    let mut wind_est = mean_wind;
    let hover_p = M100.power(mass, Vector3::zeros(), Vector3::zeros()).electrical_w;

    let mut st = State {
        pos: Vector3::zeros(),
        vel: Vector3::zeros(),
        acc: Vector3::zeros(),
        yaw: 0.0,
        rot: Rotation3::identity(),
        rates: Vector3::zeros(),
        wind: mean_wind,
        power_w: M100.avionics_w,
        voltage_v: battery.ocv_v(),
        current_a: 0.0,
        armed: false,
        in_air: false,
        throttle: 0.0,
    };
    let mut phase = Phase::PreArm;
    let mut phase_t = 0.0;
    let mut emitter = Emitter::new(mission);
    let mut truth = Vec::new();
    let mut step: u64 = 0;
    let max_steps = (4.0 * 3600.0 / DT) as u64;

    loop {
        let t = step as f64 * DT;
        let t_ms = step * 10;
        // Wind with gusts.
        let g = Vector3::new(gust[0].step(&mut rng, DT), gust[1].step(&mut rng, DT), gust[2].step(&mut rng, DT));
        st.wind = mean_wind + g;
        // The autopilot's wind estimate: a slow filter of the true wind.
        wind_est += (st.wind - wind_est) * (DT / 3.0);

        // Guidance: desired velocity for this phase, and phase changes.
        let mut v_des: Option<Vector3<f64>> = None;
        let mut next = None;
        match phase {
            Phase::PreArm if phase_t >= PREARM_S => next = Some(Phase::Spinup),
            Phase::Spinup if phase_t >= SPINUP_S => next = Some(Phase::Climb),
            Phase::Climb => {
                let target = Vector3::new(0.0, 0.0, h);
                v_des = Some(toward(&st.pos, &target, mission.speed_mps, CLIMB_MPS));
                if (st.pos.z - h).abs() < 0.3 && st.vel.norm() < 0.3 {
                    next = Some(Phase::Leg(0));
                }
            }
            Phase::Leg(i) => {
                let target = waypoints[i as usize];
                v_des = Some(toward(&st.pos, &target, mission.speed_mps, CLIMB_MPS));
                let d = (target - st.pos).norm();
                if d < 1.5 {
                    next = Some(if i < 2 { Phase::Leg(i + 1) } else { Phase::Hover });
                }
            }
            Phase::Hover => {
                v_des = Some(toward(&st.pos, &waypoints[2], mission.speed_mps, CLIMB_MPS));
                if phase_t >= mission.hover_s {
                    next = Some(Phase::Descent);
                }
            }
            Phase::Descent => {
                let height = -st.pos.z;
                // Below 3 m, aim 1 m under the ground so touch-down happens at LAND_MPS.
                let (rate, z) = if height > 3.0 { (DESCENT_MPS, 0.0) } else { (LAND_MPS, 1.0) };
                let target = Vector3::new(0.0, 0.0, z);
                v_des = Some(toward(&st.pos, &target, mission.speed_mps, rate));
                if height <= 0.02 {
                    st.pos.z = 0.0;
                    next = Some(Phase::Landed);
                }
            }
            Phase::Landed if phase_t >= LANDED_S => next = Some(Phase::Done),
            Phase::Done if phase_t >= DONE_S => break,
            _ => {}
        }
        if let Some(p) = next {
            phase = p;
            phase_t = 0.0;
        }
        st.armed = !matches!(phase, Phase::PreArm | Phase::Done);
        st.in_air = matches!(phase, Phase::Climb | Phase::Leg(_) | Phase::Hover | Phase::Descent);

        // Kinematics: lagged acceleration toward the commanded one.
        if let (true, Some(vd)) = (st.in_air, v_des) {
            let mut a_cmd = (vd - st.vel) * K_V;
            let ah = (a_cmd.x * a_cmd.x + a_cmd.y * a_cmd.y).sqrt();
            if ah > A_MAX_H {
                a_cmd.x *= A_MAX_H / ah;
                a_cmd.y *= A_MAX_H / ah;
            }
            a_cmd.z = a_cmd.z.clamp(-A_MAX_V, A_MAX_V);
            st.acc += (a_cmd - st.acc) * (DT / TAU_A);
            st.vel += st.acc * DT;
            st.pos += st.vel * DT;
            if st.pos.z > 0.0 {
                st.pos.z = 0.0;
                st.vel.z = st.vel.z.min(0.0);
            }
            // Yaw follows the desired track when moving.
            let vh = (vd.x * vd.x + vd.y * vd.y).sqrt();
            if vh > 1.0 {
                let want = vd.y.atan2(vd.x);
                let err = wrap_pi(want - st.yaw);
                st.yaw = wrap_pi(st.yaw + err.clamp(-YAW_RATE_MAX * DT, YAW_RATE_MAX * DT));
            }
        } else {
            st.acc = Vector3::zeros();
            st.vel = Vector3::zeros();
        }

        // Attitude from the thrust direction (in the air) or level (on the ground).
        let v_air = st.vel - st.wind;
        let (rot, power) = if st.in_air {
            let t_vec = M100.thrust_ned(mass, v_air, st.acc);
            let p = M100.power(mass, v_air, st.acc);
            (attitude_from_thrust(&t_vec, st.yaw), p.electrical_w)
        } else {
            let p = match phase {
                Phase::Spinup | Phase::Landed => IDLE_W,
                _ => M100.avionics_w,
            };
            (Rotation3::from_euler_angles(0.0, 0.0, st.yaw), p)
        };
        let d_rot = st.rot.inverse() * rot;
        let m = d_rot.matrix();
        st.rates = Vector3::new(m[(2, 1)] - m[(1, 2)], m[(0, 2)] - m[(2, 0)], m[(1, 0)] - m[(0, 1)]) / (2.0 * DT);
        st.rot = rot;
        st.power_w = power;
        let (v, i) = battery.load(power);
        st.voltage_v = v;
        st.current_a = i;
        battery.step(power, DT);
        st.throttle = if st.in_air { (50.0 * (power / hover_p).sqrt()).clamp(0.0, 100.0) } else if st.armed { 8.0 } else { 0.0 };

        let gps = Vector3::new(gps_err[0].step(&mut rng, DT), gps_err[1].step(&mut rng, DT), gps_err[2].step(&mut rng, DT));
        if t_ms.is_multiple_of(100) {
            truth.push(TruthSample {
                t_s: t,
                phase,
                power_w: power,
                voltage_v: v,
                ground_speed_mps: (st.vel.x * st.vel.x + st.vel.y * st.vel.y).sqrt(),
                height_m: -st.pos.z,
            });
        }
        emitter.emit(t_ms, &st, &battery, &gps, &wind_est, phase, &mut rng);

        step += 1;
        phase_t += DT;
        if step > max_steps {
            anyhow::bail!("the simulated mission did not finish within 4 hours of flight (leg {l} m at {} m/s)", mission.speed_mps);
        }
    }
    Ok(SimFlight { records: emitter.records, truth })
}

/// Desired velocity toward `target`: horizontal speed up to `speed`, vertical up to
/// `vz_max`, each braking as √(2·a_brake·d) near the target.
fn toward(pos: &Vector3<f64>, target: &Vector3<f64>, speed: f64, vz_max: f64) -> Vector3<f64> {
    let d = target - pos;
    let dh = (d.x * d.x + d.y * d.y).sqrt();
    let mut v = Vector3::zeros();
    if dh > 1e-6 {
        let s = speed.min((2.0 * A_BRAKE * dh).sqrt()).min(dh * K_V * 2.0);
        v.x = d.x / dh * s;
        v.y = d.y / dh * s;
    }
    let vz = vz_max.min((2.0 * A_BRAKE * d.z.abs()).sqrt()).min(d.z.abs() * 2.0);
    v.z = vz * d.z.signum();
    v
}

fn wrap_pi(a: f64) -> f64 {
    let mut a = (a + PI) % (2.0 * PI);
    if a < 0.0 {
        a += 2.0 * PI;
    }
    a - PI
}

/// Body-to-NED rotation whose body z axis (down, FRD) opposes the thrust and whose heading
/// is `yaw`.
fn attitude_from_thrust(t_ned: &Vector3<f64>, yaw: f64) -> Rotation3<f64> {
    let b3 = -t_ned.normalize();
    let heading = Vector3::new(yaw.cos(), yaw.sin(), 0.0);
    let b2 = b3.cross(&heading).normalize();
    let b1 = b2.cross(&b3);
    Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[b1, b2, b3]))
}

/// Turns the state into the autopilot's messages at its rates, with sensor noise.
struct Emitter {
    autopilot: Autopilot,
    mission: Mission,
    seq: u8,
    records: Vec<SimRecord>,
    home_sent: bool,
    last_phase: Option<Phase>,
}

impl Emitter {
    fn new(mission: &Mission) -> Self {
        Self { autopilot: mission.autopilot, mission: mission.clone(), seq: 0, records: Vec::new(), home_sent: false, last_phase: None }
    }

    fn push(&mut self, t_ms: u64, msg: MavMessage) {
        let header = MavHeader { system_id: 1, component_id: 1, sequence: self.seq };
        self.seq = self.seq.wrapping_add(1);
        self.records.push(SimRecord { t_us: EPOCH_START_US + t_ms * 1000, header, msg });
    }

    #[allow(clippy::too_many_arguments)]
    fn emit(&mut self, t_ms: u64, st: &State, bat: &Battery, gps: &Vector3<f64>, wind_est: &Vector3<f64>, phase: Phase, rng: &mut StdRng) {
        let px4 = self.autopilot == Autopilot::Px4;
        let boot_ms = t_ms as u32;
        let n = |rng: &mut StdRng, s: f64| s * std_normal(rng);
        let (roll, pitch, yaw) = st.rot.euler_angles();

        // Heartbeat at 1 Hz, and at once when the mode or arming changes (so HOME_POSITION
        // never precedes the armed heartbeat).
        if self.last_phase != Some(phase) {
            self.last_phase = Some(phase);
            self.push(t_ms, heartbeat(px4, st.armed, phase));
        }
        if (Every { period_ms: 1000, offset_ms: 0 }).due(t_ms) {
            self.push(t_ms, heartbeat(px4, st.armed, phase));
            for (name, value) in [
                ("cmd_speed", self.mission.speed_mps),
                ("payload_g", self.mission.payload_g),
                ("cmd_alt", self.mission.altitude_m),
            ] {
                self.push(
                    t_ms,
                    MavMessage::NAMED_VALUE_FLOAT(d::NAMED_VALUE_FLOAT_DATA { time_boot_ms: boot_ms, value: value as f32, name: name.into() }),
                );
            }
        }
        if px4 && (Every { period_ms: 1000, offset_ms: 500 }).due(t_ms) {
            let landed = match phase {
                Phase::Climb => d::MavLandedState::MAV_LANDED_STATE_TAKEOFF,
                Phase::Descent => d::MavLandedState::MAV_LANDED_STATE_LANDING,
                _ if st.in_air => d::MavLandedState::MAV_LANDED_STATE_IN_AIR,
                _ => d::MavLandedState::MAV_LANDED_STATE_ON_GROUND,
            };
            self.push(
                t_ms,
                MavMessage::EXTENDED_SYS_STATE(d::EXTENDED_SYS_STATE_DATA {
                    vtol_state: d::MavVtolState::MAV_VTOL_STATE_UNDEFINED,
                    landed_state: landed,
                }),
            );
        }
        // Battery: measured voltage and current carry sensor noise. σ_I = 0.1 A + 7 % of
        // the current (≈ 1.6 A in cruise) matches the sample-to-sample scatter of the data
        // set's V·I in steady cruise (≈ 35–40 W) and its ±0.3 A offsets at rest.
        if (Every { period_ms: 500, offset_ms: 50 }).due(t_ms) {
            let v_meas = (st.voltage_v + n(rng, 0.05)).max(0.0);
            let i_meas = st.current_a + n(rng, 0.1 + 0.07 * st.current_a);
            let mv = (v_meas * 1000.0).round().clamp(0.0, 65534.0) as u16;
            let ca = (i_meas * 100.0).round().clamp(-32768.0, 32767.0) as i16;
            let remaining = (bat.soc * 100.0).round().clamp(0.0, 100.0) as i8;
            let sensors = d::MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_3D_GYRO
                | d::MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_3D_ACCEL
                | d::MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_3D_MAG
                | d::MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
                | d::MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_GPS
                | d::MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_BATTERY;
            self.push(
                t_ms,
                MavMessage::SYS_STATUS(d::SYS_STATUS_DATA {
                    onboard_control_sensors_present: sensors,
                    onboard_control_sensors_enabled: sensors,
                    onboard_control_sensors_health: sensors,
                    load: 250,
                    voltage_battery: mv,
                    current_battery: ca,
                    battery_remaining: remaining,
                    ..Default::default()
                }),
            );
            let mut voltages = [u16::MAX; 10];
            voltages[0] = mv;
            self.push(
                t_ms,
                MavMessage::BATTERY_STATUS(d::BATTERY_STATUS_DATA {
                    current_consumed: (bat.drawn_ah * 1000.0).round() as i32,
                    // hJ: 1 Wh = 36 hJ.
                    energy_consumed: (bat.drawn_wh * 36.0).round() as i32,
                    temperature: i16::MAX,
                    voltages,
                    current_battery: ca,
                    id: 0,
                    battery_function: d::MavBatteryFunction::MAV_BATTERY_FUNCTION_ALL,
                    mavtype: d::MavBatteryType::MAV_BATTERY_TYPE_LIPO,
                    battery_remaining: remaining,
                    charge_state: d::MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_OK,
                    ..Default::default()
                }),
            );
        }
        // Position: GPS error (Gauss–Markov) on position, white noise on velocity.
        let (lat, lon, alt) = to_geodetic(&(st.pos + gps));
        let vel_meas = st.vel + Vector3::new(n(rng, 0.08), n(rng, 0.08), n(rng, 0.05));
        let hdg_deg = yaw.to_degrees().rem_euclid(360.0);
        if (Every { period_ms: 200, offset_ms: 20 }).due(t_ms) {
            self.push(
                t_ms,
                MavMessage::GLOBAL_POSITION_INT(d::GLOBAL_POSITION_INT_DATA {
                    time_boot_ms: boot_ms,
                    lat: (lat * 1e7).round() as i32,
                    lon: (lon * 1e7).round() as i32,
                    alt: (alt * 1000.0).round() as i32,
                    relative_alt: ((alt - HOME_ALT_M) * 1000.0).round() as i32,
                    vx: (vel_meas.x * 100.0).round() as i16,
                    vy: (vel_meas.y * 100.0).round() as i16,
                    vz: (vel_meas.z * 100.0).round() as i16,
                    hdg: ((hdg_deg * 100.0).round() as u16) % 36000,
                }),
            );
            let gs = (vel_meas.x.powi(2) + vel_meas.y.powi(2)).sqrt();
            self.push(
                t_ms,
                MavMessage::GPS_RAW_INT(d::GPS_RAW_INT_DATA {
                    time_usec: t_ms * 1000,
                    lat: (lat * 1e7).round() as i32,
                    lon: (lon * 1e7).round() as i32,
                    alt: (alt * 1000.0).round() as i32,
                    eph: 80,
                    epv: 120,
                    vel: (gs * 100.0).round() as u16,
                    cog: ((vel_meas.y.atan2(vel_meas.x).to_degrees().rem_euclid(360.0) * 100.0).round() as u16) % 36000,
                    fix_type: d::GpsFixType::GPS_FIX_TYPE_3D_FIX,
                    satellites_visible: 14,
                    ..Default::default()
                }),
            );
        }
        // Attitude.
        let att_noise = Vector3::new(n(rng, 0.004), n(rng, 0.004), n(rng, 0.006));
        let rate_meas = st.rates + Vector3::new(n(rng, 0.015), n(rng, 0.015), n(rng, 0.01));
        if (Every { period_ms: 100, offset_ms: 30 }).due(t_ms) {
            let (r, p, y) = (roll + att_noise.x, pitch + att_noise.y, wrap_pi(yaw + att_noise.z));
            if px4 {
                let q = UnitQuaternion::from_euler_angles(r, p, y);
                self.push(
                    t_ms,
                    MavMessage::ATTITUDE_QUATERNION(d::ATTITUDE_QUATERNION_DATA {
                        time_boot_ms: boot_ms,
                        q1: q.w as f32,
                        q2: q.i as f32,
                        q3: q.j as f32,
                        q4: q.k as f32,
                        rollspeed: rate_meas.x as f32,
                        pitchspeed: rate_meas.y as f32,
                        yawspeed: rate_meas.z as f32,
                        repr_offset_q: [0.0; 4],
                    }),
                );
            }
            if !px4 || (Every { period_ms: 200, offset_ms: 30 }).due(t_ms) {
                self.push(
                    t_ms,
                    MavMessage::ATTITUDE(d::ATTITUDE_DATA {
                        time_boot_ms: boot_ms,
                        roll: r as f32,
                        pitch: p as f32,
                        yaw: y as f32,
                        rollspeed: rate_meas.x as f32,
                        pitchspeed: rate_meas.y as f32,
                        yawspeed: rate_meas.z as f32,
                    }),
                );
            }
        }
        // IMU: specific force in the body frame (FRD), f = Rᵀ(a − g); ≈ (0, 0, −9.81) at
        // rest. Vibration noise grows when the props spin.
        if (Every { period_ms: 100, offset_ms: 40 }).due(t_ms) {
            let vib = if st.in_air { 0.3 } else if st.armed { 0.2 } else { 0.03 };
            let f = st.rot.inverse() * (st.acc - Vector3::new(0.0, 0.0, G)) + Vector3::new(n(rng, vib), n(rng, vib), n(rng, vib));
            let w = rate_meas;
            // Earth field near Pittsburgh ≈ (0.19, −0.03, 0.47) gauss NED.
            let mag = st.rot.inverse() * Vector3::new(0.19, -0.03, 0.47);
            if px4 {
                self.push(
                    t_ms,
                    MavMessage::HIGHRES_IMU(d::HIGHRES_IMU_DATA {
                        time_usec: t_ms * 1000,
                        xacc: f.x as f32,
                        yacc: f.y as f32,
                        zacc: f.z as f32,
                        xgyro: w.x as f32,
                        ygyro: w.y as f32,
                        zgyro: w.z as f32,
                        xmag: mag.x as f32,
                        ymag: mag.y as f32,
                        zmag: mag.z as f32,
                        abs_pressure: (pressure_pa(HOME_ALT_M - st.pos.z) / 100.0) as f32,
                        diff_pressure: 0.0,
                        pressure_alt: (HOME_ALT_M - st.pos.z) as f32,
                        temperature: 25.0,
                        fields_updated: d::HighresImuUpdatedFlags::all(),
                        id: 0,
                    }),
                );
            } else {
                // ArduPilot's RAW_IMU carries acceleration in mG, rates in mrad/s and the
                // field in mgauss (AP's send_raw_imu scales by 1000/GRAVITY_MSS).
                let mg = |x: f64| (x * 1000.0 / G).round().clamp(-32768.0, 32767.0) as i16;
                let milli = |x: f64| (x * 1000.0).round().clamp(-32768.0, 32767.0) as i16;
                self.push(
                    t_ms,
                    MavMessage::RAW_IMU(d::RAW_IMU_DATA {
                        time_usec: t_ms * 1000,
                        xacc: mg(f.x),
                        yacc: mg(f.y),
                        zacc: mg(f.z),
                        xgyro: milli(w.x),
                        ygyro: milli(w.y),
                        zgyro: milli(w.z),
                        xmag: milli(mag.x),
                        ymag: milli(mag.y),
                        zmag: milli(mag.z),
                        id: 0,
                        temperature: 2500,
                    }),
                );
            }
        }
        if (Every { period_ms: 250, offset_ms: 60 }).due(t_ms) {
            let air = if st.in_air { (st.vel - wind_est).norm() } else { 0.0 };
            self.push(
                t_ms,
                MavMessage::VFR_HUD(d::VFR_HUD_DATA {
                    airspeed: (air + n(rng, 0.1)).max(0.0) as f32,
                    groundspeed: (vel_meas.x.powi(2) + vel_meas.y.powi(2)).sqrt() as f32,
                    alt: alt as f32,
                    climb: (-vel_meas.z) as f32,
                    heading: hdg_deg.round() as i16 % 360,
                    throttle: st.throttle.round() as u16,
                }),
            );
        }
        if !px4 && (Every { period_ms: 500, offset_ms: 70 }).due(t_ms) {
            self.push(
                t_ms,
                MavMessage::WIND(d::WIND_DATA {
                    // ArduPilot: degrees(atan2(−wind.y, −wind.x)), the direction it comes from.
                    direction: (-wind_est.y).atan2(-wind_est.x).to_degrees() as f32,
                    speed: (wind_est.x.powi(2) + wind_est.y.powi(2)).sqrt() as f32,
                    speed_z: wind_est.z as f32,
                }),
            );
        }
        if px4 && (Every { period_ms: 200, offset_ms: 80 }).due(t_ms) {
            let amsl = (HOME_ALT_M - st.pos.z + gps.z * 0.3) as f32;
            self.push(
                t_ms,
                MavMessage::ALTITUDE(d::ALTITUDE_DATA {
                    time_usec: t_ms * 1000,
                    altitude_monotonic: amsl,
                    altitude_amsl: amsl,
                    altitude_local: amsl - HOME_ALT_M as f32,
                    altitude_relative: amsl - HOME_ALT_M as f32,
                    altitude_terrain: f32::NAN,
                    bottom_clearance: f32::NAN,
                }),
            );
        }
        // Home: once when armed, then every 5 s.
        let home_due = st.armed && (!self.home_sent || (Every { period_ms: 5000, offset_ms: 90 }).due(t_ms));
        if home_due {
            self.home_sent = true;
            let nan = f32::NAN;
            self.push(
                t_ms,
                MavMessage::HOME_POSITION(d::HOME_POSITION_DATA {
                    latitude: (HOME_LAT_DEG * 1e7).round() as i32,
                    longitude: (HOME_LON_DEG * 1e7).round() as i32,
                    altitude: (HOME_ALT_M * 1000.0).round() as i32,
                    x: 0.0,
                    y: 0.0,
                    z: 0.0,
                    q: [nan; 4],
                    approach_x: 0.0,
                    approach_y: 0.0,
                    approach_z: 0.0,
                    time_usec: t_ms * 1000,
                }),
            );
        }
    }
}

fn heartbeat(px4: bool, armed: bool, phase: Phase) -> MavMessage {
    let mut base = d::MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | d::MavModeFlag::MAV_MODE_FLAG_STABILIZE_ENABLED;
    if armed {
        base |= d::MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
    }
    let auto = !matches!(phase, Phase::PreArm | Phase::Done);
    if auto {
        base |= d::MavModeFlag::MAV_MODE_FLAG_GUIDED_ENABLED | d::MavModeFlag::MAV_MODE_FLAG_AUTO_ENABLED;
    }
    let custom_mode = if px4 {
        // PX4: main mode in bits 16..24, sub mode in 24..32. AUTO = 4; sub: TAKEOFF 2,
        // MISSION 4, LAND 6. Disarmed: POSCTL (3).
        let (main, sub) = match phase {
            Phase::Spinup | Phase::Climb => (4u32, 2u32),
            Phase::Descent | Phase::Landed => (4, 6),
            Phase::Leg(_) | Phase::Hover => (4, 4),
            Phase::PreArm | Phase::Done => (3, 0),
        };
        (main << 16) | (sub << 24)
    } else {
        // ArduCopter: STABILIZE 0, AUTO 3, LAND 9.
        match phase {
            Phase::PreArm | Phase::Done => 0,
            Phase::Descent | Phase::Landed => 9,
            _ => 3,
        }
    };
    MavMessage::HEARTBEAT(d::HEARTBEAT_DATA {
        custom_mode,
        mavtype: d::MavType::MAV_TYPE_QUADROTOR,
        autopilot: if px4 { d::MavAutopilot::MAV_AUTOPILOT_PX4 } else { d::MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA },
        base_mode: base,
        system_status: if armed { d::MavState::MAV_STATE_ACTIVE } else { d::MavState::MAV_STATE_STANDBY },
        mavlink_version: 3,
    })
}

/// NED offset from home (m) → latitude, longitude (deg), altitude above sea level (m), on
/// a local spherical-earth tangent plane (errors are millimetres over a few km).
fn to_geodetic(ned: &Vector3<f64>) -> (f64, f64, f64) {
    const R_EARTH: f64 = 6_378_137.0;
    let lat = HOME_LAT_DEG + (ned.x / R_EARTH).to_degrees();
    let lon = HOME_LON_DEG + (ned.y / (R_EARTH * HOME_LAT_DEG.to_radians().cos())).to_degrees();
    (lat, lon, HOME_ALT_M - ned.z)
}

/// ISA static pressure at an altitude, Pa.
fn pressure_pa(alt_m: f64) -> f64 {
    101_325.0 * (1.0 - 2.25577e-5 * alt_m).powf(5.25588)
}

/// Run `dronewatt simulate`: fly the mission, then write the `.tlog` or stream to UDP.
pub fn run(args: SimulateArgs) -> anyhow::Result<()> {
    let mission = Mission {
        speed_mps: args.speed_mps,
        altitude_m: args.altitude_m,
        payload_g: args.payload_g,
        wind_mps: args.wind_mps,
        wind_dir_deg: args.wind_dir_deg,
        leg_m: args.leg_m,
        hover_s: args.hover_s,
        seed: args.seed,
        autopilot: args.autopilot,
    };
    let flight = simulate(&mission)?;
    let duration_s = flight.truth.last().map(|s| s.t_s).unwrap_or(0.0);
    let energy_wh: f64 = flight.truth.iter().map(|s| s.power_w * 0.1 / 3600.0).sum();
    tracing::info!(messages = flight.records.len(), duration_s, energy_wh, "simulated mission");
    if let Some(path) = &args.out {
        let bytes = flight.to_tlog();
        let mut f = std::fs::File::create(path).with_context(|| format!("{}: cannot create the tlog", path.display()))?;
        f.write_all(&bytes).with_context(|| format!("{}: cannot write the tlog", path.display()))?;
        eprintln!(
            "{}: {} messages, {:.1} s of flight, {:.1} Wh drawn, {} bytes",
            path.display(),
            flight.records.len(),
            duration_s,
            energy_wh,
            bytes.len()
        );
        return Ok(());
    }
    let addr = args.udp.as_deref().context("give --out FILE.tlog or --udp HOST:PORT")?;
    let rate = args.rate.unwrap_or(Rate::Factor(1.0));
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().context("cannot start the tokio runtime")?;
    let sent = rt.block_on(async {
        tokio::select! {
            r = stream_udp(&flight.records, addr, rate) => r,
            _ = tokio::signal::ctrl_c() => Ok(0),
        }
    })?;
    eprintln!("sent {sent} frames to udp {addr}");
    Ok(())
}

/// Send `records` as MAVLink 2 frames, one datagram each, to `addr`, paced by `rate`.
/// Returns the number of frames sent.
pub async fn stream_udp(records: &[SimRecord], addr: &str, rate: Rate) -> anyhow::Result<u64> {
    let target = tokio::net::lookup_host(addr)
        .await
        .with_context(|| format!("--udp {addr}: cannot resolve (expected HOST:PORT)"))?
        .next()
        .with_context(|| format!("--udp {addr}: no address"))?;
    let bind = if target.is_ipv4() { "0.0.0.0:0" } else { "[::]:0" };
    let sock = tokio::net::UdpSocket::bind(bind).await.context("cannot open a UDP socket")?;
    let start = tokio::time::Instant::now();
    let t0 = records.first().map(|r| r.t_us).unwrap_or(0);
    let mut sent = 0;
    let mut frame = Vec::with_capacity(300);
    for r in records {
        if let Rate::Factor(f) = rate {
            let due = start + std::time::Duration::from_secs_f64((r.t_us - t0) as f64 / 1e6 / f);
            tokio::time::sleep_until(due).await;
        }
        frame.clear();
        mavlink::write_versioned_msg(&mut frame, MavlinkVersion::V2, r.header, &r.msg)
            .with_context(|| "cannot encode a MAVLink frame")?;
        match sock.send_to(&frame, target).await {
            Ok(_) => sent += 1,
            // Nobody listening yet (ICMP port unreachable): keep flying, as a drone would.
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => {}
            Err(e) => return Err(e).with_context(|| format!("--udp {addr}: send failed")),
        }
    }
    Ok(sent)
}
