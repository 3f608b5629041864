//! The simulated vehicle's state → MAVLink messages at an autopilot's rates, with sensor
//! noise. What both autopilots send is here; what differs ([`Style`]) is in
//! [`super::ardupilot`] and [`super::px4`].
//!
//! | message | rate | noise |
//! |---|---|---|
//! | HEARTBEAT | 1 Hz, and at once on each phase or mode change | — |
//! | NAMED_VALUE_FLOAT `cmd_speed`, `payload_g`, `cmd_alt` | 1 Hz | — |
//! | PARAM_VALUE: battery capacity, cells or voltage thresholds, … ([`Style::parameters`]) | once, at start | — |
//! | SYS_STATUS, BATTERY_STATUS | 2 Hz | σ_V = 0.05 V; σ_I = 0.1 A + 7 % of the current |
//! | GLOBAL_POSITION_INT, GPS_RAW_INT | 5 Hz | Gauss–Markov position error; σ_v = 8/8/5 cm/s |
//! | attitude ([`Style::attitude`]) | 10 Hz | σ = 0.004/0.004/0.006 rad; rates 0.015/0.015/0.01 rad/s |
//! | IMU ([`Style::imu`]) | 10 Hz | vibration σ 0.03 (disarmed), 0.2 (idling), 0.3 m/s² (flying) |
//! | VFR_HUD | 4 Hz | σ_airspeed 0.1 m/s (a plane's: its airspeed sensor's true airspeed) |
//! | air data ([`Style::air_data`]) | the style's | — |
//! | HOME_POSITION | once armed, then every 5 s | — |
//!
//! σ_I matches the sample-to-sample scatter of the data set's V·I in steady cruise
//! (≈ 35–40 W) and its ±0.3 A offsets at rest. Every noise draw comes from the one seeded
//! RNG in a fixed order, so a seed gives the same bytes.

use crate::features::units::{centidegrees, scaled, whole_degrees};
use mavlink::MavHeader;
use nalgebra::Vector3;
use rand::rngs::StdRng;

use super::physics::Battery;
use super::{std_normal, Autopilot, Frame, SimOptions, SimRecord, State, EPOCH_START_US, HOME};
use crate::dialect as d;
use crate::features::units::G;
use crate::sim::guidance::{Phase, Route};
use crate::MavMessage;

/// The vehicle's side of a mission download: MISSION_COUNT, then every MISSION_ITEM_INT.
fn mission_download(m: &super::SimMission) -> Vec<MavMessage> {
    use num_traits::FromPrimitive;
    let count = u16::try_from(m.items.len()).unwrap_or(u16::MAX);
    let mut out = vec![MavMessage::MISSION_COUNT(d::MISSION_COUNT_DATA {
        count,
        target_system: 255,
        target_component: 190,
        ..Default::default()
    })];
    for it in &m.items {
        out.push(MavMessage::MISSION_ITEM_INT(d::MISSION_ITEM_INT_DATA {
            param1: it.params[0] as f32,
            param2: it.params[1] as f32,
            param3: it.params[2] as f32,
            param4: it.params[3] as f32,
            x: (it.lat_deg * 1e7).round() as i32,
            y: (it.lon_deg * 1e7).round() as i32,
            z: it.alt_m as f32,
            seq: it.seq,
            command: d::MavCmd::from_u32(it.command).unwrap_or_default(),
            target_system: 255,
            target_component: 190,
            frame: d::MavFrame::from_u32(it.frame).unwrap_or_default(),
            autocontinue: 1,
            ..Default::default()
        }));
    }
    out
}

/// Periodic emission schedule: period and phase offset, in ms of simulated time.
#[derive(Debug, Clone, Copy)]
pub struct Every {
    /// Period, ms.
    pub period_ms: u64,
    /// Offset of the first emission, ms.
    pub offset_ms: u64,
}

impl Every {
    /// Every `period_ms`, the first at `offset_ms`.
    pub const fn new(period_ms: u64, offset_ms: u64) -> Self {
        Self {
            period_ms,
            offset_ms,
        }
    }
    /// Whether a message on this schedule is due at `t_ms`.
    pub fn due(&self, t_ms: u64) -> bool {
        t_ms >= self.offset_ms && (t_ms - self.offset_ms).is_multiple_of(self.period_ms)
    }
}

/// One step's view of the vehicle, as the emitters read it.
pub struct Instant<'a> {
    /// Simulated time, ms since the start (also `time_boot_ms`).
    pub t_ms: u64,
    /// The vehicle.
    pub st: &'a State,
    /// The battery.
    pub battery: &'a Battery,
    /// GNSS position error, NED m.
    pub gps_err: &'a Vector3<f64>,
    /// The autopilot's wind estimate, NED m/s (where the air moves to).
    pub wind_est: &'a Vector3<f64>,
    /// Mission phase.
    pub phase: Phase,
    /// The airframe (HEARTBEAT type, modes, airspeed sensor).
    pub frame: Frame,
}

impl Instant<'_> {
    /// `time_boot_ms`.
    pub fn boot_ms(&self) -> u32 {
        self.t_ms as u32
    }
    /// Altitude above mean sea level, m (true, before GNSS error).
    pub fn alt_amsl_m(&self) -> f64 {
        HOME.alt_amsl_m - self.st.pos.z
    }
}

/// What one autopilot does its own way. Each method is called at its slot in the common
/// sequence, every step, and decides itself whether anything is due.
pub trait Style {
    /// HEARTBEAT's `custom_mode` in `now`'s phase, for its frame and VTOL state.
    fn custom_mode(&self, now: &Instant) -> u32;
    /// HEARTBEAT's `type` for a frame.
    fn mav_type(&self, frame: Frame) -> d::MavType;
    /// The battery and frame parameters a ground station reads at connection, as
    /// PARAM_VALUE payloads (index and count are filled in by the emitter).
    fn parameters(&self, opts: &SimOptions) -> Vec<d::PARAM_VALUE_DATA>;
    /// Landed and VTOL state (EXTENDED_SYS_STATE); before the battery messages.
    fn landed_state(&self, now: &Instant) -> Option<MavMessage>;
    /// Attitude messages, given the measured roll, pitch, yaw (rad) and body rates (rad/s),
    /// when the 10 Hz attitude slot is due. ATTITUDE (Euler) alone unless the style says
    /// otherwise (ArduPilot's way).
    fn attitude(
        &self,
        now: &Instant,
        rpy: (f64, f64, f64),
        rates: &Vector3<f64>,
        out: &mut Vec<MavMessage>,
    ) {
        out.push(attitude(now, rpy, rates));
    }
    /// The IMU message for a reading, when the 10 Hz IMU slot is due.
    fn imu(&self, now: &Instant, reading: &Imu) -> MavMessage;
    /// Wind or altitude messages at the style's own rate; last in each step but HOME_POSITION.
    fn air_data(&self, now: &Instant) -> Option<MavMessage>;
}

/// One IMU reading, as a style's [`Style::imu`] reports it.
pub struct Imu {
    /// Specific force, FRD, m/s².
    pub f: Vector3<f64>,
    /// Body rates, rad/s.
    pub w: Vector3<f64>,
    /// Magnetic field, body frame, gauss.
    pub mag: Vector3<f64>,
}

/// The style for an autopilot, and HEARTBEAT's `autopilot` for it.
pub fn style(autopilot: Autopilot) -> (Box<dyn Style>, d::MavAutopilot) {
    use d::MavAutopilot::{MAV_AUTOPILOT_ARDUPILOTMEGA, MAV_AUTOPILOT_PX4};
    match autopilot {
        Autopilot::Ardupilot => (
            Box::new(super::ardupilot::ArduPilot),
            MAV_AUTOPILOT_ARDUPILOTMEGA,
        ),
        Autopilot::Px4 => (Box::new(super::px4::Px4), MAV_AUTOPILOT_PX4),
    }
}

/// Turns the state into the autopilot's messages at its rates, with sensor noise.
pub struct Emitter {
    style: Box<dyn Style>,
    autopilot: d::MavAutopilot,
    route: Route,
    payload_g: f64,
    params: Vec<d::PARAM_VALUE_DATA>,
    seq: u8,
    records: Vec<SimRecord>,
    home_sent: bool,
    last_mode: Option<(Phase, u32)>,
    mission: Option<super::SimMission>,
    mission_logged: bool,
}

impl Emitter {
    /// An emitter for `opts`' autopilot style.
    pub fn new(opts: &SimOptions) -> Self {
        let (style, autopilot) = style(opts.autopilot);
        let mut params = style.parameters(opts);
        let count = params.len() as u16;
        for (i, p) in params.iter_mut().enumerate() {
            (p.param_index, p.param_count) = (i as u16, count);
        }
        Self {
            style,
            autopilot,
            route: opts.route.clone(),
            payload_g: opts.payload_g,
            params,
            seq: 0,
            records: Vec::new(),
            home_sent: false,
            last_mode: None,
            mission: opts.mission.clone(),
            mission_logged: false,
        }
    }

    /// Every message emitted so far.
    pub fn into_records(self) -> Vec<SimRecord> {
        self.records
    }

    fn push(&mut self, t_ms: u64, msg: MavMessage) {
        let header = MavHeader {
            system_id: 1,
            component_id: 1,
            sequence: self.seq,
        };
        self.seq = self.seq.wrapping_add(1);
        self.records.push(SimRecord {
            t_us: EPOCH_START_US + t_ms * 1000,
            header,
            msg,
        });
    }

    fn heartbeat(&self, now: &Instant) -> MavMessage {
        let (armed, phase) = (now.st.armed, now.phase);
        let mut base = d::MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
            | d::MavModeFlag::MAV_MODE_FLAG_STABILIZE_ENABLED;
        if armed {
            base |= d::MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
        }
        if !matches!(phase, Phase::PreArm | Phase::Done) {
            base |= d::MavModeFlag::MAV_MODE_FLAG_GUIDED_ENABLED
                | d::MavModeFlag::MAV_MODE_FLAG_AUTO_ENABLED;
        }
        MavMessage::HEARTBEAT(d::HEARTBEAT_DATA {
            custom_mode: self.style.custom_mode(now),
            mavtype: self.style.mav_type(now.frame),
            autopilot: self.autopilot,
            base_mode: base,
            system_status: if armed {
                d::MavState::MAV_STATE_ACTIVE
            } else {
                d::MavState::MAV_STATE_STANDBY
            },
            mavlink_version: 3,
        })
    }

    /// Emit whatever is due at `now`, drawing sensor noise from `rng` (always in the same
    /// order: the position's, the attitude's, then the IMU's and the airspeed's when due).
    pub fn emit(&mut self, now: &Instant, rng: &mut StdRng) {
        self.emit_state(now);
        // Battery: measured voltage and current carry sensor noise.
        if Every::new(500, 50).due(now.t_ms) {
            self.battery(now, rng);
        }
        let (vel_meas, alt, hdg_deg) = self.emit_position(now, rng);
        self.emit_attitude(now, rng);
        self.emit_air_and_home(now, rng, &vel_meas, alt, hdg_deg);
    }

    /// The heartbeat, the named values, the parameters and the mission, and the landed
    /// state: what carries no sensor noise.
    fn emit_state(&mut self, now: &Instant) {
        let (t_ms, phase) = (now.t_ms, now.phase);
        let boot_ms = now.boot_ms();
        // Heartbeat at 1 Hz, and at once when the mode or arming changes (so HOME_POSITION
        // never precedes the armed heartbeat).
        let mode = self.style.custom_mode(now);
        if self.last_mode != Some((phase, mode)) {
            self.last_mode = Some((phase, mode));
            self.push(t_ms, self.heartbeat(now));
        }
        if Every::new(1000, 0).due(t_ms) {
            self.push(t_ms, self.heartbeat(now));
            let (speed_mps, alt_m) = self.route.commanded(phase);
            for (name, value) in [
                ("cmd_speed", speed_mps),
                ("payload_g", self.payload_g),
                ("cmd_alt", alt_m),
            ] {
                self.push(
                    t_ms,
                    MavMessage::NAMED_VALUE_FLOAT(d::NAMED_VALUE_FLOAT_DATA {
                        time_boot_ms: boot_ms,
                        value: value as f32,
                        name: name.into(),
                    }),
                );
            }
        }
        // The parameters, once, right after the first heartbeat: what a ground station
        // logs when it reads the parameter list at connection.
        for p in std::mem::take(&mut self.params) {
            self.push(t_ms, MavMessage::PARAM_VALUE(p));
        }
        // The mission, once, as a ground station logs its download; then where it is, 1 Hz.
        if let Some(m) = self.mission.clone() {
            if !self.mission_logged {
                self.mission_logged = true;
                for msg in mission_download(&m) {
                    self.push(t_ms, msg);
                }
            }
            if Every::new(1000, 0).due(t_ms) {
                // total: the items after ArduPilot's home item; PX4 has none
                let home_item = usize::from(
                    m.items
                        .first()
                        .is_some_and(|i| i.command == 16 && i.frame == 0),
                );
                let total = u16::try_from(m.items.len() - home_item).unwrap_or(u16::MAX);
                self.push(
                    t_ms,
                    MavMessage::MISSION_CURRENT(d::MISSION_CURRENT_DATA {
                        seq: m.current_seq(phase),
                        total,
                        ..Default::default()
                    }),
                );
            }
        }
        if let Some(m) = self.style.landed_state(now) {
            self.push(t_ms, m);
        }
    }

    /// GLOBAL_POSITION_INT and GPS_RAW_INT when due; returns the measured velocity, the
    /// altitude (AMSL) and the heading, which the airspeed message reuses.
    fn emit_position(&mut self, now: &Instant, rng: &mut StdRng) -> (Vector3<f64>, f64, f64) {
        let (t_ms, st) = (now.t_ms, now.st);
        let boot_ms = now.boot_ms();
        let n = |rng: &mut StdRng, s: f64| s * std_normal(rng);
        let (_, _, yaw) = st.rot.euler_angles();
        // Position: GPS error (Gauss–Markov) on position, white noise on velocity.
        let (lat, lon, alt) = HOME.to_geodetic(&(st.pos + now.gps_err));
        let vel_meas = st.vel + Vector3::new(n(rng, 0.08), n(rng, 0.08), n(rng, 0.05));
        let hdg_deg = yaw.to_degrees().rem_euclid(360.0);
        if Every::new(200, 20).due(t_ms) {
            self.push(
                t_ms,
                MavMessage::GLOBAL_POSITION_INT(d::GLOBAL_POSITION_INT_DATA {
                    time_boot_ms: boot_ms,
                    lat: scaled(lat, 1e7).unwrap_or(0),
                    lon: scaled(lon, 1e7).unwrap_or(0),
                    alt: scaled(alt, 1000.0).unwrap_or(0),
                    relative_alt: scaled(alt - HOME.alt_amsl_m, 1000.0).unwrap_or(0),
                    vx: scaled(vel_meas.x, 100.0).unwrap_or(0),
                    vy: scaled(vel_meas.y, 100.0).unwrap_or(0),
                    vz: scaled(vel_meas.z, 100.0).unwrap_or(0),
                    hdg: centidegrees(hdg_deg).unwrap_or(u16::MAX),
                }),
            );
            let gs = (vel_meas.x.powi(2) + vel_meas.y.powi(2)).sqrt();
            self.push(
                t_ms,
                MavMessage::GPS_RAW_INT(d::GPS_RAW_INT_DATA {
                    time_usec: t_ms * 1000,
                    lat: scaled(lat, 1e7).unwrap_or(0),
                    lon: scaled(lon, 1e7).unwrap_or(0),
                    alt: scaled(alt, 1000.0).unwrap_or(0),
                    eph: 80,
                    epv: 120,
                    vel: scaled(gs, 100.0).unwrap_or(u16::MAX),
                    cog: centidegrees(vel_meas.y.atan2(vel_meas.x).to_degrees())
                        .unwrap_or(u16::MAX),
                    fix_type: d::GpsFixType::GPS_FIX_TYPE_3D_FIX,
                    satellites_visible: 14,
                    ..Default::default()
                }),
            );
        }
        (vel_meas, alt, hdg_deg)
    }

    /// The attitude, and the IMU (specific force, rates, field), when due.
    fn emit_attitude(&mut self, now: &Instant, rng: &mut StdRng) {
        let (t_ms, st) = (now.t_ms, now.st);
        let n = |rng: &mut StdRng, s: f64| s * std_normal(rng);
        let (roll, pitch, yaw) = st.rot.euler_angles();
        // Attitude.
        let att_noise = Vector3::new(n(rng, 0.004), n(rng, 0.004), n(rng, 0.006));
        let rate_meas = st.rates + Vector3::new(n(rng, 0.015), n(rng, 0.015), n(rng, 0.01));
        if Every::new(100, 30).due(t_ms) {
            let rpy = (
                roll + att_noise.x,
                pitch + att_noise.y,
                super::wrap_pi(yaw + att_noise.z),
            );
            let mut out = Vec::with_capacity(2);
            self.style.attitude(now, rpy, &rate_meas, &mut out);
            for m in out {
                self.push(t_ms, m);
            }
        }
        // IMU: specific force in the body frame (FRD), f = Rᵀ(a − g); ≈ (0, 0, −9.81) at
        // rest. Vibration noise grows when the props spin.
        if Every::new(100, 40).due(t_ms) {
            let vib = if st.in_air {
                0.3
            } else if st.armed {
                0.2
            } else {
                0.03
            };
            let f = st.rot.inverse() * (st.acc - Vector3::new(0.0, 0.0, G))
                + Vector3::new(n(rng, vib), n(rng, vib), n(rng, vib));
            // Earth field near Pittsburgh ≈ (0.19, −0.03, 0.47) gauss NED.
            let mag = st.rot.inverse() * Vector3::new(0.19, -0.03, 0.47);
            let m = self.style.imu(
                now,
                &Imu {
                    f,
                    w: rate_meas,
                    mag,
                },
            );
            self.push(t_ms, m);
        }
    }

    /// VFR_HUD and the autopilot's air data when due; HOME_POSITION once armed, then every 5 s.
    fn emit_air_and_home(
        &mut self,
        now: &Instant,
        rng: &mut StdRng,
        vel_meas: &Vector3<f64>,
        alt: f64,
        hdg_deg: f64,
    ) {
        let (t_ms, st) = (now.t_ms, now.st);
        let n = |rng: &mut StdRng, s: f64| s * std_normal(rng);
        if Every::new(250, 60).due(t_ms) {
            // A plane's airspeed sensor reads the true airspeed; a multirotor's autopilot
            // says its ground velocity less its wind estimate.
            let air = match (st.airspeed_mps, st.in_air) {
                (Some(a), _) => a,
                (None, true) => (st.vel - now.wind_est).norm(),
                (None, false) => 0.0,
            };
            self.push(
                t_ms,
                MavMessage::VFR_HUD(d::VFR_HUD_DATA {
                    airspeed: (air + n(rng, 0.1)).max(0.0) as f32,
                    groundspeed: (vel_meas.x.powi(2) + vel_meas.y.powi(2)).sqrt() as f32,
                    alt: alt as f32,
                    climb: (-vel_meas.z) as f32,
                    heading: whole_degrees(hdg_deg).unwrap_or(0),
                    throttle: st.throttle.round() as u16,
                }),
            );
        }
        if let Some(m) = self.style.air_data(now) {
            self.push(t_ms, m);
        }
        // Home: once when armed, then every 5 s.
        let home_due = st.armed && (!self.home_sent || Every::new(5000, 90).due(t_ms));
        if home_due {
            self.home_sent = true;
            let nan = f32::NAN;
            self.push(
                t_ms,
                MavMessage::HOME_POSITION(d::HOME_POSITION_DATA {
                    latitude: (HOME.lat_deg * 1e7).round() as i32,
                    longitude: (HOME.lon_deg * 1e7).round() as i32,
                    altitude: (HOME.alt_amsl_m * 1000.0).round() as i32,
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

    /// SYS_STATUS and BATTERY_STATUS with noisy voltage and current.
    fn battery(&mut self, now: &Instant, rng: &mut StdRng) {
        let (st, bat, t_ms) = (now.st, now.battery, now.t_ms);
        // 10 mV: a filtered voltage monitor, steady enough at rest for a resting voltage
        // to be read (the pack's own sag and recovery are the model's, not noise).
        let v_meas = (st.voltage_v + 0.01 * std_normal(rng)).max(0.0);
        // Never below 0: a small draw at rest must not read as charging, nor as MAVLink's -1
        // ("not measured").
        let i_meas = (st.current_a + (0.1 + 0.07 * st.current_a) * std_normal(rng)).max(0.0);
        let mv = (v_meas * 1000.0).round().clamp(0.0, 65534.0) as u16;
        let ca = (i_meas * 100.0).round().clamp(-32768.0, 32767.0) as i16;
        let remaining = (bat.soc * 100.0).round().clamp(0.0, 100.0) as i8;
        let mut sensors = d::MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_3D_GYRO
            | d::MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_3D_ACCEL
            | d::MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_3D_MAG
            | d::MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
            | d::MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_GPS
            | d::MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_BATTERY;
        if now.frame != Frame::Multirotor {
            // A plane's airspeed sensor: present, enabled, healthy.
            sensors |= d::MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_DIFFERENTIAL_PRESSURE;
        }
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
}

/// EXTENDED_SYS_STATE at `now`: the landed state from the phase, the VTOL state.
pub fn extended_sys_state(now: &Instant) -> MavMessage {
    use crate::features::VtolState as V;
    let landed = match now.phase {
        Phase::Climb => d::MavLandedState::MAV_LANDED_STATE_TAKEOFF,
        Phase::Descent => d::MavLandedState::MAV_LANDED_STATE_LANDING,
        _ if now.st.in_air => d::MavLandedState::MAV_LANDED_STATE_IN_AIR,
        _ => d::MavLandedState::MAV_LANDED_STATE_ON_GROUND,
    };
    let vtol_state = match now.st.vtol {
        V::Undefined => d::MavVtolState::MAV_VTOL_STATE_UNDEFINED,
        V::Mc => d::MavVtolState::MAV_VTOL_STATE_MC,
        V::Fw => d::MavVtolState::MAV_VTOL_STATE_FW,
        V::TransitionToFw => d::MavVtolState::MAV_VTOL_STATE_TRANSITION_TO_FW,
        V::TransitionToMc => d::MavVtolState::MAV_VTOL_STATE_TRANSITION_TO_MC,
    };
    MavMessage::EXTENDED_SYS_STATE(d::EXTENDED_SYS_STATE_DATA {
        vtol_state,
        landed_state: landed,
    })
}

/// A PARAM_VALUE payload (index and count left for the emitter).
/// ATTITUDE at `now`: Euler angles (rad) and body rates (rad/s), as both autopilots send it.
pub fn attitude(
    now: &Instant,
    (roll, pitch, yaw): (f64, f64, f64),
    rates: &Vector3<f64>,
) -> MavMessage {
    MavMessage::ATTITUDE(d::ATTITUDE_DATA {
        time_boot_ms: now.boot_ms(),
        roll: roll as f32,
        pitch: pitch as f32,
        yaw: yaw as f32,
        rollspeed: rates.x as f32,
        pitchspeed: rates.y as f32,
        yawspeed: rates.z as f32,
    })
}

pub fn param(name: &str, value: f32, kind: d::MavParamType) -> d::PARAM_VALUE_DATA {
    d::PARAM_VALUE_DATA {
        param_value: value,
        param_count: 0,
        param_index: 0,
        param_id: name.into(),
        param_type: kind,
    }
}

/// ISA static pressure at an altitude, Pa.
pub fn pressure_pa(alt_m: f64) -> f64 {
    101_325.0 * (1.0 - 2.25577e-5 * alt_m).powf(5.25588)
}
