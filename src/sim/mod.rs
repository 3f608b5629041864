//! The simulator: a vehicle profile flying a waypoint route in wind, with a physically
//! plausible power draw, sent as the telemetry a real autopilot would send.
//!
//! Why: the project must run end to end without a drone. The M100 data set replays what was
//! flown; the simulator flies what was never flown (other payloads, speeds, winds, other
//! airframes) and exercises the live path with an autopilot's message mix — ArduPilot's
//! ([`ardupilot`]) or PX4's ([`px4`]).
//!
//! ## Parts
//! | part | job |
//! |---|---|
//! | [`crate::sim::guidance`] | the route: take-off, waypoints, holds, landing → desired velocity |
//! | this module | the loop: wind and gusts, the velocity loop and its lag, attitude, sensor errors |
//! | [`physics`] | rotor power by momentum theory and the battery, from the [`VehicleProfile`] |
//! | [`plane`] | a plane and a quadplane: fixed-wing flight (coordinated turns, TECS-like climb, loiter, approach), transitions, their truth power |
//! | [`emit`] | the state → MAVLink at an autopilot's rates, with sensor noise |
//! | [`ardupilot`], [`px4`] | what differs between the two: modes, attitude and IMU messages, parameters |
//! | [`output`] | `.tlog` bytes and the paced UDP stream |
//! | [`output`] → [`crate::source::logs::dataflash_writer`] | an ArduPilot flight as its DataFlash `.bin` log |
//! | [`output`] → [`crate::source::logs::ulog_writer`] | a PX4 flight as its ULog `.ulg` |
//!
//! ## Flight model (point mass, kinematic)
//! The guidance's desired velocity becomes the commanded acceleration `K_v·(v_des − v)`,
//! clipped (3 m/s² horizontal, 2 m/s² vertical), which passes a first-order lag
//! (τ = 0.25 s) and is integrated into velocity and position (NED, m, relative to home),
//! every 10 ms. Wind (mean plus a Gauss–Markov gust) changes the air-relative velocity
//! `v_a = v − w` and hence drag, tilt and power, not the track (the position controller
//! holds it). The body z axis opposes the thrust vector ([`physics`]), the yaw follows the
//! track (45°/s at most), and body rates come from successive attitudes.
//!
//! Everything random (sensor noise, gusts) comes from one RNG seeded by [`SimOptions::seed`]:
//! the same options give a byte-identical `.tlog`.

pub mod ardupilot;
pub mod emit;
mod fleet;
pub mod guidance;
pub mod output;
pub mod physics;
pub mod plane;
pub mod px4;
mod weather;

use physics::BatteryStart;
use std::f64::consts::PI;
use weather::Weather;

use mavlink::MavHeader;
use nalgebra::{Matrix3, Rotation3, Vector3};
use rand::rngs::StdRng;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

use crate::features::units::wrap_pi;
use crate::model::profile::VehicleProfile;
use crate::sim::guidance::{Guidance, Home, InvalidOption, Phase, Route};
use crate::MavMessage;
pub use fleet::{merge, simulate_fleet, MAX_FLEET};
use physics::{Airframe, Battery};

/// Whose message set and conventions the output follows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Autopilot {
    /// ArduPilot Copter: ATTITUDE, RAW_IMU (mG, mrad/s), WIND, VFR_HUD, no quaternion.
    Ardupilot,
    /// PX4: ATTITUDE_QUATERNION, HIGHRES_IMU (SI), ALTITUDE, EXTENDED_SYS_STATE, no WIND.
    Px4,
}

/// What airframe the profile describes, and so which flight model flies it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Frame {
    /// Rotors only (the profile has no `[plane]`).
    Multirotor,
    /// A plane: `[plane]`, class not `vtol`.
    Plane,
    /// A quadplane: `[plane]` for the wing and pusher, `[rotor]`… for the lift rotors,
    /// `[vehicle] class = "vtol"`.
    Quadplane,
}

impl Frame {
    /// The frame a profile describes.
    pub fn of(p: &VehicleProfile) -> Self {
        match (&p.plane, p.vehicle.class) {
            (None, _) => Frame::Multirotor,
            (Some(_), Some(crate::features::VehicleClass::Vtol)) => Frame::Quadplane,
            (Some(_), _) => Frame::Plane,
        }
    }
}

/// What to simulate: a vehicle, a route, the payload and the weather.
#[derive(Debug, Clone, PartialEq)]
pub struct SimOptions {
    /// The airframe and battery (needs the profile's simulator sections).
    pub vehicle: VehicleProfile,
    /// The route flown.
    pub route: Route,
    /// Payload, g.
    pub payload_g: f64,
    /// Mean wind speed, m/s.
    pub wind_mps: f64,
    /// Direction the wind comes FROM, degrees clockwise from north (meteorological).
    pub wind_dir_deg: f64,
    /// Seed of the noise and gusts.
    pub seed: u64,
    /// Telemetry style.
    pub autopilot: Autopilot,
    /// The mission the route was made from (`simulate --plan`), logged as a ground station
    /// logs a download (MISSION_COUNT, MISSION_ITEM_INT at the start) with MISSION_CURRENT
    /// at 1 Hz; None for the built-in triangle (no mission messages).
    pub mission: Option<SimMission>,
    /// The pack's state at the start: full (the default), a state of charge, or a resting
    /// voltage (`simulate --soc-pct`, `--battery-v`).
    pub battery: BatteryStart,
}

/// A mission as the simulated autopilot holds it, and which item each phase flies.
#[derive(Debug, Clone, PartialEq)]
pub struct SimMission {
    /// The items (ArduPilot's layout with item 0 home, PX4's without), positions around [`HOME`].
    pub items: Vec<crate::mission::protocol::MissionItem>,
    /// Mission `seq` per route waypoint.
    pub waypoint_seq: Vec<u16>,
    /// `seq` of the take-off, and of the item that ends the flight.
    pub takeoff_seq: u16,
    pub end_seq: u16,
}

impl SimMission {
    /// MISSION_CURRENT's `seq` in `phase`.
    pub fn current_seq(&self, phase: Phase) -> u16 {
        match phase {
            Phase::PreArm | Phase::Spinup | Phase::Climb => self.takeoff_seq,
            Phase::Leg(i) | Phase::Hold(i) => {
                self.waypoint_seq.get(i).copied().unwrap_or(self.end_seq)
            }
            Phase::Descent | Phase::Landed | Phase::Done => self.end_seq,
        }
    }

    /// A plan flown by the simulator: the plan moved to [`HOME`] (offsets kept), its route
    /// at `speed_mps` unless the plan says otherwise, and its items as the autopilot holds
    /// them (ArduPilot: item 0 is home; PX4: no home item).
    pub fn from_plan(
        plan: &crate::mission::plan::Plan,
        speed_mps: f64,
        autopilot: Autopilot,
    ) -> Result<(Route, SimMission), InvalidOption> {
        let plan = plan.relocated(crate::mission::plan::GeoPoint {
            lat_deg: HOME.lat_deg,
            lon_deg: HOME.lon_deg,
            alt_m: HOME.alt_amsl_m,
        });
        let pr = Route::from_plan(&plan, speed_mps)?;
        let home_item = usize::from(autopilot == Autopilot::Ardupilot);
        let seq = |i: usize| u16::try_from(i + home_item).unwrap_or(u16::MAX);
        let mut items = plan.to_mission_items();
        if home_item == 0 {
            items.remove(0);
            for (i, it) in items.iter_mut().enumerate() {
                it.seq = u16::try_from(i).unwrap_or(u16::MAX);
            }
        }
        let mission = SimMission {
            items,
            waypoint_seq: pr.waypoint_items.iter().map(|&i| seq(i)).collect(),
            takeoff_seq: seq(pr.takeoff_item),
            end_seq: seq(pr.end_item),
        };
        Ok((pr.route, mission))
    }
}

impl Default for SimOptions {
    /// The M100 with 500 g on a 300 m triangle at 10 m/s and 25 m, 20 s hover, 3 m/s wind
    /// from the west, seed 1, ArduPilot style.
    fn default() -> Self {
        Self {
            vehicle: VehicleProfile::m100(),
            route: guidance::Triangle {
                leg_m: 300.0,
                altitude_m: 25.0,
                speed_mps: 10.0,
                hover_s: 20.0,
            }
            .route(),
            payload_g: 500.0,
            wind_mps: 3.0,
            wind_dir_deg: 270.0,
            seed: 1,
            autopilot: Autopilot::Ardupilot,
            mission: None,
            battery: BatteryStart::Full,
        }
    }
}

impl SimOptions {
    /// Range checks; the error names the option (`payload_g`, `waypoints[1].speed_mps`).
    pub fn validate(&self) -> anyhow::Result<()> {
        self.route.validate()?;
        if Frame::of(&self.vehicle) != Frame::Plane {
            Airframe::from_profile(&self.vehicle)?;
        }
        Battery::from_profile(&self.vehicle, self.battery)?;
        let v = &self.vehicle.vehicle;
        let empty_kg = self.vehicle.mass_kg(0.0);
        let max_g = crate::features::units::floor_ratio((v.mtow_kg - empty_kg) * 1000.0, 1.0)
            .unwrap_or(0.0)
            .max(0.0);
        guidance::in_range("payload_g", self.payload_g, 0.0, max_g, false).map_err(|e| {
            InvalidOption {
                reason: format!(
                    "{} ({}: {} kg MTOW − {:.3} kg empty)",
                    e.reason, self.vehicle.name, v.mtow_kg, empty_kg
                ),
                ..e
            }
        })?;
        guidance::in_range("wind_mps", self.wind_mps, 0.0, 15.0, false)?;
        if !self.wind_dir_deg.is_finite() {
            return Err(InvalidOption {
                key: "wind_dir_deg".into(),
                reason: format!("= {}: must be a number", self.wind_dir_deg),
            }
            .into());
        }
        Ok(())
    }

    /// Mean wind velocity (where the air moves TO), NED, m/s.
    fn wind_ned(&self) -> Vector3<f64> {
        let from = self.wind_dir_deg.to_radians();
        Vector3::new(
            -self.wind_mps * from.cos(),
            -self.wind_mps * from.sin(),
            0.0,
        )
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
    /// North and east of home, m.
    pub north_m: f64,
    pub east_m: f64,
    /// Height above home, m.
    pub height_m: f64,
    /// A VTOL's state (`Undefined` for others).
    pub vtol: crate::features::VtolState,
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
    /// Flight time from the first step to the last truth sample, s.
    pub fn duration_s(&self) -> f64 {
        self.truth.last().map_or(0.0, |s| s.t_s)
    }

    /// Energy drawn over the flight by the truth samples (10 Hz rectangles), Wh.
    pub fn energy_wh(&self) -> f64 {
        self.truth.iter().map(|s| s.power_w * 0.1 / 3600.0).sum()
    }
}

/// Start of every simulated flight: 2019-10-24 13:32:00 UTC (09:32 local at the data set's
/// site, the start of flight 276), so timestamps look like a real log.
pub const EPOCH_START_US: u64 = 1_571_923_920_000_000;

/// Home: the data set's site near Pittsburgh (flight 276 starts at 40.459060 N,
/// −79.782820 E, 268.7 m above sea level).
pub const HOME: Home = Home {
    lat_deg: 40.459_060,
    lon_deg: -79.782_820,
    alt_amsl_m: 268.7,
};

/// Disarmed on the ground the pack feeds a third of the avionics power (the flight
/// controller and radios; the data set's M100 reads about 0 A before take-off), so a
/// resting voltage can be read before the flight, as on a real vehicle.
const DISARMED_FRAC: f64 = 1.0 / 3.0;
/// Simulation step, s.
const DT: f64 = 0.01;
/// Horizontal and vertical acceleration limits of the velocity loop, m/s².
const A_MAX_H: f64 = 3.0;
const A_MAX_V: f64 = 2.0;
/// Lag of the achieved acceleration behind the commanded one, s.
const TAU_A: f64 = 0.25;
const YAW_RATE_MAX: f64 = 45.0 * PI / 180.0;

/// One draw of N(0, 1).
pub(crate) fn std_normal(rng: &mut StdRng) -> f64 {
    // Normal::new(0, 1) cannot fail.
    Normal::new(0.0, 1.0).map(|n| n.sample(rng)).unwrap_or(0.0)
}

/// The full vehicle state the telemetry is made from.
pub struct State {
    /// Position, NED m from home.
    pub pos: Vector3<f64>,
    /// Velocity, NED m/s.
    pub vel: Vector3<f64>,
    /// Acceleration, NED m/s².
    pub acc: Vector3<f64>,
    /// Heading, rad.
    pub yaw: f64,
    /// Body (FRD) → NED.
    pub rot: Rotation3<f64>,
    /// Body rates, rad/s.
    pub rates: Vector3<f64>,
    /// True wind, NED m/s (where the air moves to).
    pub wind: Vector3<f64>,
    /// Electrical power, W.
    pub power_w: f64,
    /// Terminal voltage, V.
    pub voltage_v: f64,
    /// Current, A.
    pub current_a: f64,
    /// Motors armed.
    pub armed: bool,
    /// Off the ground.
    pub in_air: bool,
    /// Throttle, %.
    pub throttle: f64,
    /// A VTOL's state (`Undefined` for others).
    pub vtol: crate::features::VtolState,
    /// True airspeed an airspeed sensor reads (planes), m/s; None: no sensor.
    pub airspeed_mps: Option<f64>,
}

/// A multirotor's velocity loop for one step: the acceleration `K_v·(v_des − v)`, clipped
/// ([`A_MAX_H`], [`A_MAX_V`]), lagged (τ [`TAU_A`]) and integrated; the ground is a floor;
/// the yaw follows the desired track (45°/s at most) when moving.
pub(crate) fn mc_velocity_step(st: &mut State, vd: Vector3<f64>) {
    let mut a_cmd = (vd - st.vel) * guidance::VELOCITY_GAIN_PER_S;
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
    let vh = (vd.x * vd.x + vd.y * vd.y).sqrt();
    if vh > 1.0 {
        let want = vd.y.atan2(vd.x);
        let err = wrap_pi(want - st.yaw);
        st.yaw = wrap_pi(st.yaw + err.clamp(-YAW_RATE_MAX * DT, YAW_RATE_MAX * DT));
    }
}

/// Set the attitude, the body rates from the change since the last step.
pub(crate) fn set_attitude(st: &mut State, rot: Rotation3<f64>) {
    let d_rot = st.rot.inverse() * rot;
    let m = d_rot.matrix();
    st.rates = Vector3::new(
        m[(2, 1)] - m[(1, 2)],
        m[(0, 2)] - m[(2, 0)],
        m[(1, 0)] - m[(0, 1)],
    ) / (2.0 * DT);
    st.rot = rot;
}

/// What one step leaves behind: the truth at 10 Hz and the telemetry.
pub(crate) struct Recorder {
    pub emitter: emit::Emitter,
    pub truth: Vec<TruthSample>,
    pub frame: Frame,
}

impl Recorder {
    pub fn new(opts: &SimOptions) -> Self {
        Self {
            emitter: emit::Emitter::new(opts),
            truth: Vec::new(),
            frame: Frame::of(&opts.vehicle),
        }
    }

    /// Record step `step` (10 ms each) of the flight.
    pub fn record(
        &mut self,
        step: u64,
        phase: Phase,
        st: &State,
        battery: &Battery,
        weather: &mut Weather,
        rng: &mut StdRng,
    ) {
        let t_ms = step * 10;
        let gps = weather.gps(rng);
        if t_ms.is_multiple_of(100) {
            self.truth.push(TruthSample {
                t_s: step as f64 * DT,
                phase,
                power_w: st.power_w,
                voltage_v: st.voltage_v,
                ground_speed_mps: (st.vel.x * st.vel.x + st.vel.y * st.vel.y).sqrt(),
                height_m: -st.pos.z,
                north_m: st.pos.x,
                east_m: st.pos.y,
                vtol: st.vtol,
            });
        }
        self.emitter.emit(
            &emit::Instant {
                t_ms,
                st,
                battery,
                gps_err: &gps,
                wind_est: &weather.wind_est,
                phase,
                frame: self.frame,
            },
            rng,
        );
    }

    pub fn finish(self) -> SimFlight {
        SimFlight {
            records: self.emitter.into_records(),
            truth: self.truth,
        }
    }
}

/// Fly `opts` and return every message and the ground truth. Pure computation. A profile
/// with a `[plane]` section flies as a plane or a quadplane ([`plane`]).
pub fn simulate(opts: &SimOptions) -> anyhow::Result<SimFlight> {
    opts.validate()?;
    if Frame::of(&opts.vehicle) != Frame::Multirotor {
        return plane::simulate(opts);
    }
    let frame = Airframe::from_profile(&opts.vehicle)?;
    let mut battery = Battery::from_profile(&opts.vehicle, opts.battery)?;
    let mut rng = StdRng::seed_from_u64(opts.seed);
    let mass = frame.mass_kg(opts.payload_g / 1000.0);
    let mut guide = Guidance::new(opts.route.clone());
    let mut weather = Weather::new(opts);
    let hover_p = frame
        .power(mass, Vector3::zeros(), Vector3::zeros())
        .electrical_w;

    let mut st = State::at_home(frame.avionics_w, battery.ocv_v());
    let mut rec = Recorder::new(opts);
    let mut step: u64 = 0;
    loop {
        st.wind = weather.wind(&mut rng);
        let cmd = guide.step(&st.pos, &st.vel, DT);
        if cmd.finished {
            break;
        }
        if cmd.touchdown {
            st.pos.z = 0.0;
        }
        let phase = cmd.phase;
        st.armed = phase.armed();
        st.in_air = phase.in_air();

        // Kinematics: lagged acceleration toward the commanded one.
        if let (true, Some(vd)) = (st.in_air, cmd.velocity_ned) {
            mc_velocity_step(&mut st, vd);
        } else {
            st.acc = Vector3::zeros();
            st.vel = Vector3::zeros();
        }

        // Attitude from the thrust direction (in the air) or level (on the ground).
        let v_air = st.vel - st.wind;
        let (rot, power) = if st.in_air {
            let t_vec = frame.thrust_ned(mass, v_air, st.acc);
            let p = frame.power(mass, v_air, st.acc);
            (attitude_from_thrust(&t_vec, st.yaw), p.electrical_w)
        } else {
            let p = match phase {
                Phase::Spinup | Phase::Landed => frame.idle_w,
                Phase::PreArm | Phase::Done => DISARMED_FRAC * frame.avionics_w,
                _ => frame.avionics_w,
            };
            (Rotation3::from_euler_angles(0.0, 0.0, st.yaw), p)
        };
        set_attitude(&mut st, rot);
        st.power_w = power;
        (st.voltage_v, st.current_a) = battery.step(power, DT);
        st.throttle = if st.in_air {
            (50.0 * (power / hover_p).sqrt()).clamp(0.0, 100.0)
        } else if st.armed {
            8.0
        } else {
            0.0
        };
        rec.record(step, phase, &st, &battery, &mut weather, &mut rng);
        step += 1;
        check_steps(step, opts)?;
    }
    Ok(rec.finish())
}

/// The longest flight simulated, steps.
const MAX_STEPS: u64 = (4.0 * 3600.0 / DT) as u64;

/// An error once a flight passes 4 hours.
pub(crate) fn check_steps(step: u64, opts: &SimOptions) -> anyhow::Result<()> {
    if step > MAX_STEPS {
        anyhow::bail!(
            "the simulated mission did not finish within 4 hours of flight ({} waypoints)",
            opts.route.waypoints.len()
        );
    }
    Ok(())
}

impl State {
    /// On the ground at home, level, disarmed, drawing `power_w` from a pack at `ocv_v`.
    pub fn at_home(power_w: f64, ocv_v: f64) -> Self {
        Self {
            pos: Vector3::zeros(),
            vel: Vector3::zeros(),
            acc: Vector3::zeros(),
            yaw: 0.0,
            rot: Rotation3::identity(),
            rates: Vector3::zeros(),
            wind: Vector3::zeros(),
            power_w,
            voltage_v: ocv_v,
            current_a: 0.0,
            armed: false,
            in_air: false,
            throttle: 0.0,
            vtol: crate::features::VtolState::Undefined,
            airspeed_mps: None,
        }
    }
}

/// Body-to-NED rotation whose body z axis (down, FRD) opposes the thrust and whose heading
/// is `yaw`.
pub(crate) fn attitude_from_thrust(t_ned: &Vector3<f64>, yaw: f64) -> Rotation3<f64> {
    let b3 = -t_ned.normalize();
    let heading = Vector3::new(yaw.cos(), yaw.sin(), 0.0);
    let b2 = b3.cross(&heading).normalize();
    let b1 = b2.cross(&b3);
    Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[b1, b2, b3]))
}
