//! Vehicle state, frame conversion, fixed-rate resampling and the feature vector the
//! models see.
//!
//! [`Telemetry`] is the live stage: MAVLink messages in, [`Window`]s out. It tracks the
//! vehicle state from whatever messages the autopilot sends, converts each signal to the
//! data set's frame and units at message time ([`frames`]), hands it to the fixed-rate
//! [`resample::Resampler`], and slides a ring of T samples over the result
//! ([`crate::telemetry::window::WindowRing`]). Training and evaluation walk the same stage over the
//! data set encoded as MAVLink ([`crate::offline::data`]), so live and offline features
//! cannot drift apart.
//!
//! ## Sources, best first
//!
//! | signal | features | sources (best first) |
//! |---|---|---|
//! | attitude | `orientation_*` | ATTITUDE_QUATERNION, ATTITUDE (Euler → quaternion) |
//! | angular rate | `angular_*` | ATTITUDE_QUATERNION, ATTITUDE, HIGHRES_IMU, SCALED_IMU (mrad/s), RAW_IMU (read as ArduPilot sends it: mrad/s) |
//! | acceleration | `linear_acceleration_*` | HIGHRES_IMU (m/s²), SCALED_IMU (mG), RAW_IMU (mG, ArduPilot's scaling) |
//! | velocity | `velocity_*` | LOCAL_POSITION_NED, ODOMETRY (child frame LOCAL_NED or BODY_FRD), GLOBAL_POSITION_INT (cm/s) |
//! | position | `position_*` | GLOBAL_POSITION_INT, GPS_RAW_INT |
//! | wind | `wind_speed`, `wind_angle` | WIND, WIND_COV (true wind minus ground velocity = what the anemometer reads), VFR_HUD (airspeed, with the heading as the angle) |
//! | power | `measured_w`, `voltage_v` | BATTERY_STATUS (battery id 0; cell voltages summed), SYS_STATUS (0 V: no voltage); [`crate::source::messages::power`] |
//! | mission | `speed`, `payload`, `altitude` | NAMED_VALUE_FLOAT `cmd_speed` (m/s), `payload_g` (g), `cmd_alt` (m) — the data-set encoder sends these — then `[mission]` config, then defaults 10 m/s, 0 g, 25 m |
//! | home | [`Sample::home`] | HOME_POSITION, else the first GPS fix (non-zero latitude/longitude) |
//! | vehicle class, air data | [`Sample::vehicle`], [`Sample::air`] | HEARTBEAT `type`, EXTENDED_SYS_STATE `vtol_state`, ArduPlane's Q modes, the profile's `[vehicle] class`; VFR_HUD airspeed, SYS_STATUS's airspeed sensor, WIND, SCALED_PRESSURE temperature ([`kind`]) |
//!
//! A worse source is used only while every better one is quiet (no update for
//! `stale_after_s`). ArduPilot's default streams (ATTITUDE, RAW_IMU/SCALED_IMU,
//! GLOBAL_POSITION_INT, LOCAL_POSITION_NED, WIND, VFR_HUD, SYS_STATUS, BATTERY_STATUS) and
//! PX4's (ATTITUDE_QUATERNION, HIGHRES_IMU, LOCAL_POSITION_NED, GLOBAL_POSITION_INT,
//! VFR_HUD, BATTERY_STATUS, no WIND) both fill every feature. [`Telemetry::health`] says
//! which source feeds each signal and what is stale (the terminal view shows it).
//!
//! Messages are taken from one vehicle: the system id of the first autopilot HEARTBEAT
//! (or of the first telemetry message, if that comes first); others are counted and
//! ignored. A non-finite value makes its whole update be dropped and counted
//! ([`Telemetry::nonfinite`]), never propagated; a position or home of (0, 0) or off the
//! globe is no fix, ignored and counted ([`Telemetry::no_fix`]). The time of a message is its
//! [`TimedMessage::t_s`] (the tlog stamp or the arrival time), rounded to the microsecond.
//!
//! Conversions that need another signal use its newest value at message time: body
//! velocities need the heading (a velocity before any attitude is dropped), the
//! anemometer reading needs the ground velocity. The data-set encoder sends the attitude
//! first and the velocity before the wind in every row, so each row converts back with
//! its own values. Resampling, staleness, gaps and latency: [`resample`].
//!
//! ## Frames, as verified on the data set
//!
//! See [`frames`] for the per-column conventions and the checks behind them.

pub mod kind;
pub mod rates;
pub mod resample;
pub mod window;

mod config;
pub use config::{MissionConfig, TelemetryConfig};

// The shared types live on the floor ([`crate::features`]); re-exported here because the
// telemetry stage is where they are made.
use crate::features::units::G;
use crate::features::{frames, idx, Sample};
use crate::report::status::SignalHealth;
use crate::source::TimedMessage;
use crate::telemetry::window::{Window, WindowRing};
use crate::MavMessage;
use resample::{Resampler, Signal, N_SIGNALS, SIGNALS};

/// The wind's last source: no air data heard, the air taken as still (the airspeed is the
/// ground velocity), until any WIND, WIND_COV or VFR_HUD comes, for good.
const STILL_AIR: usize = 3;

/// Source names per signal, best first (index = rank).
const SOURCES: [&[&str]; N_SIGNALS] = [
    &["WIND", "WIND_COV", "VFR_HUD", "still air (no air data)"],
    &["GLOBAL_POSITION_INT", "GPS_RAW_INT"],
    &["ATTITUDE_QUATERNION", "ATTITUDE"],
    &["LOCAL_POSITION_NED", "ODOMETRY", "GLOBAL_POSITION_INT"],
    &[
        "ATTITUDE_QUATERNION",
        "ATTITUDE",
        "HIGHRES_IMU",
        "SCALED_IMU",
        "RAW_IMU",
    ],
    &["HIGHRES_IMU", "SCALED_IMU", "RAW_IMU"],
    &["BATTERY_STATUS", "SYS_STATUS"],
];

/// The telemetry stage: messages in, windows out (see the module docs).
pub struct Telemetry {
    stale_us: i64,
    resampler: Resampler,
    ring: WindowRing,
    /// Per signal: (rank, time µs) of the source in use.
    active: [Option<(usize, i64)>; N_SIGNALS],
    sysid: Option<u32>,
    /// Latest raw attitude (FRD→NED) and ground velocity (NED), for conversions.
    q_ned: Option<frames::Quat>,
    vel_ned: Option<[f64; 3]>,
    /// Air data (WIND, WIND_COV or VFR_HUD) was heard: until it is, the air is taken as
    /// still ([`STILL_AIR`]).
    air_data: bool,
    /// Home was set (by HOME_POSITION or the first fix).
    home_known: bool,
    /// Mission: values from NAMED_VALUE_FLOAT, the config, and the defaults.
    mission_msg: [Option<f32>; 3],
    mission_cfg: [Option<f32>; 3],
    nonfinite: u64,
    no_fix: u64,
    foreign: u64,
    samples: Vec<Sample>,
    /// The autopilot's latest `battery_remaining`, %, if it reports one.
    battery_pct: Option<f32>,
    /// The vehicle's class and air data ([`kind`]).
    kind: kind::KindTracker,
    /// Time of the newest message taken, µs.
    now_us: i64,
    /// What the link's rates mean, said once ([`rates`]).
    rates: rates::RateWatch,
}

impl Telemetry {
    /// A stage for this rate, window and mission.
    pub fn new(cfg: &TelemetryConfig, mission: &MissionConfig) -> Self {
        let mut t = Self {
            stale_us: (cfg.stale_after_s * 1e6).round() as i64,
            resampler: Resampler::new(cfg.rate_hz, cfg.stale_after_s, cfg.max_gap_s),
            ring: WindowRing::new(cfg.window),
            active: [None; N_SIGNALS],
            sysid: None,
            q_ned: None,
            vel_ned: None,
            air_data: false,
            home_known: false,
            mission_msg: [None; 3],
            mission_cfg: [mission.speed_m_s, mission.payload_g, mission.altitude_m],
            nonfinite: 0,
            no_fix: 0,
            foreign: 0,
            samples: Vec::new(),
            battery_pct: None,
            kind: kind::KindTracker::new(None),
            now_us: 0,
            rates: rates::RateWatch::default(),
        };
        t.refresh_mission();
        t
    }

    /// The class the vehicle profile's `[vehicle] class` sets, which wins over the
    /// HEARTBEAT's type ([`kind`]); `None` leaves it to the vehicle.
    pub fn with_class(mut self, class: Option<crate::features::VehicleClass>) -> Self {
        self.kind = kind::KindTracker::new(class);
        self
    }

    /// The vehicle's kind as it stands (class, MAV_TYPE, VTOL state).
    pub fn vehicle_kind(&self) -> crate::features::VehicleKind {
        self.kind.kind()
    }

    /// Changes of class or VTOL state followed so far (after the first HEARTBEAT).
    pub fn class_switches(&self) -> u64 {
        self.kind.switches()
    }

    /// Feed one message; push any windows it completes onto `out`.
    pub fn push(&mut self, m: &TimedMessage, out: &mut Vec<Window>) {
        if !m.t_s.is_finite() || !self.hears_vehicle(m) {
            return;
        }
        let t_us = (m.t_s * 1e6).round() as i64;
        self.now_us = t_us;
        self.kind.ingest(t_us, self.stale_us, &m.msg);
        self.ingest(t_us, &m.msg);
        let active = self.active;
        self.rates.check(&self.resampler, t_us, |s| {
            active[s as usize].map(|(r, _)| SOURCES[s as usize][r])
        });
        if self.resampler.take_restart() {
            self.ring.clear();
        }
        let mut samples = std::mem::take(&mut self.samples);
        self.resampler.poll(&mut samples);
        self.windows_from(&mut samples, out);
        self.samples = samples;
    }

    /// The MAVLink system id of the vehicle this stage locked onto (its first autopilot
    /// HEARTBEAT, or the first sender of telemetry), `None` before one is heard.
    pub fn system_id(&self) -> Option<u8> {
        self.sysid.and_then(|s| u8::try_from(s).ok())
    }

    /// End of stream: flush what can still be emitted.
    pub fn finish(&mut self, out: &mut Vec<Window>) {
        let mut samples = std::mem::take(&mut self.samples);
        self.resampler.finish(&mut samples);
        self.windows_from(&mut samples, out);
        self.samples = samples;
    }

    /// Per signal: which message feeds it, its age and whether it is stale.
    pub fn health(&self) -> Vec<SignalHealth> {
        let mut v: Vec<SignalHealth> = SIGNALS
            .iter()
            .map(|&sig| SignalHealth {
                signal: sig.name(),
                features: sig.features().to_vec(),
                source: self.active[sig as usize].map(|(r, _)| SOURCES[sig as usize][r]),
                age_s: self.resampler.age_s(sig),
                stale: self.resampler.is_quiet(sig),
            })
            .collect();
        let src = if self.mission_msg.iter().any(Option::is_some) {
            "NAMED_VALUE_FLOAT"
        } else if self.mission_cfg.iter().any(Option::is_some) {
            "config"
        } else {
            "default"
        };
        v.push(SignalHealth {
            signal: "mission",
            features: vec![idx::SPEED, idx::PAYLOAD, idx::ALTITUDE],
            source: Some(src),
            age_s: None,
            stale: false,
        });
        v
    }

    /// Updates dropped because a field was NaN or infinite.
    pub fn nonfinite(&self) -> u64 {
        self.nonfinite
    }

    /// Positions (and homes) ignored because they were no fix: (0, 0), or off the globe.
    pub fn no_fix(&self) -> u64 {
        self.no_fix
    }

    /// Messages ignored because another system sent them.
    pub fn foreign(&self) -> u64 {
        self.foreign
    }

    /// Whole-stream gaps after which the window ring restarted.
    pub fn restarts(&self) -> u64 {
        self.resampler.restarts()
    }

    fn windows_from(&mut self, samples: &mut Vec<Sample>, out: &mut Vec<Window>) {
        let pct = self.battery_pct;
        let vehicle = self.kind.kind();
        let air = self.kind.air(self.now_us, self.stale_us);
        out.extend(samples.drain(..).filter_map(|mut s| {
            s.battery_remaining_pct = pct;
            s.vehicle = vehicle;
            s.air = air;
            self.ring.push(s)
        }));
    }

    fn hears_vehicle(&mut self, m: &TimedMessage) -> bool {
        let sys = m.header.system_id;
        match (self.sysid, &m.msg) {
            (Some(id), _) if id == sys => true,
            (Some(_), _) => {
                self.foreign += 1;
                false
            }
            (None, MavMessage::HEARTBEAT(h)) => {
                let autopilot = crate::source::messages::fleet::is_vehicle_heartbeat(h);
                if autopilot {
                    self.sysid = Some(sys);
                }
                autopilot
            }
            (None, MavMessage::PARAM_VALUE(_) | MavMessage::STATUSTEXT(_)) => false,
            (None, _) => {
                self.sysid = Some(sys);
                true
            }
        }
    }

    /// Record `v` for `sig` from source `rank` if no better source is live.
    fn offer(&mut self, sig: Signal, rank: usize, t_us: i64, v: &[f64]) {
        if v.iter().any(|x| !x.is_finite()) {
            self.nonfinite += 1;
            if self.nonfinite == 1 {
                tracing::warn!(
                    signal = sig.name(),
                    source = SOURCES[sig as usize][rank],
                    "non-finite telemetry value ignored (further ones are counted)"
                );
            }
            return;
        }
        if self.takes(sig, rank, t_us) {
            self.active[sig as usize] = Some((rank, t_us));
            self.resampler.update(sig, t_us, v);
        }
    }

    /// Whether an update from source `rank` is used: no better source is live.
    fn takes(&self, sig: Signal, rank: usize, t_us: i64) -> bool {
        let stale_us = (self.resampler.stale_limit_s(sig) * 1e6).round() as i64;
        match self.active[sig as usize] {
            None => true,
            Some((r, t)) => rank <= r || t_us - t > stale_us,
        }
    }

    fn refresh_mission(&mut self) {
        let d = [10.0, 0.0, 25.0];
        let m: Vec<f32> = (0..3)
            .map(|i| self.mission_msg[i].or(self.mission_cfg[i]).unwrap_or(d[i]))
            .collect();
        self.resampler.set_mission(m[0], m[1], m[2]);
    }

    fn attitude(&mut self, rank: usize, t_us: i64, q_ned: frames::Quat, rates: [f32; 3]) {
        if !(q_ned.iter().all(|x| x.is_finite()) && q_ned.iter().any(|&x| x != 0.0)) {
            self.nonfinite += 1;
        } else if self.takes(Signal::Attitude, rank, t_us) {
            self.q_ned = Some(q_ned);
            let q = frames::ned_to_ds(q_ned);
            self.offer(Signal::Attitude, rank, t_us, &q);
        }
        self.offer(Signal::Rates, rank, t_us, &rates.map(f64::from));
    }

    /// SCALED_IMU and RAW_IMU: rates in mrad/s and acceleration in mG, offered at
    /// `(rates rank, acceleration rank)`.
    fn milli_imu(
        &mut self,
        (rates, accel): (usize, usize),
        t_us: i64,
        gyro: [i16; 3],
        acc: [i16; 3],
    ) {
        self.offer(Signal::Rates, rates, t_us, &gyro.map(|x| x as f64 * 1e-3));
        self.offer(
            Signal::Accel,
            accel,
            t_us,
            &acc.map(|x| x as f64 * 1e-3 * G),
        );
    }

    fn velocity(&mut self, rank: usize, t_us: i64, v_ned: [f64; 3]) {
        if !v_ned.iter().all(|x| x.is_finite()) {
            self.nonfinite += 1;
            return;
        }
        if !self.takes(Signal::Velocity, rank, t_us) {
            return;
        }
        self.vel_ned = Some(v_ned);
        if !self.air_data {
            // No air data heard: the air is taken as still, the airspeed the ground
            // velocity (not 0: a member would fly every cruise at hover power).
            if self.active[Signal::Wind as usize].is_none() {
                tracing::info!("no air data (WIND, WIND_COV, VFR_HUD) heard yet: the air is taken as still, the airspeed as the ground speed");
            }
            let w = frames::apparent_wind([0.0, 0.0], [v_ned[0], v_ned[1]]);
            self.offer(Signal::Wind, STILL_AIR, t_us, &w);
        }
        // Body velocities need the heading: wait for the first attitude.
        if let Some(q) = self.q_ned {
            let v = frames::ned_to_body_vel(v_ned, frames::yaw_ned(q));
            self.offer(Signal::Velocity, rank, t_us, &v);
        }
    }

    fn true_wind(&mut self, rank: usize, t_us: i64, wind_ne: [f64; 2]) {
        if let Some(v) = self.vel_ned {
            self.kind.wind_airspeed(t_us, v, wind_ne);
            let w = frames::apparent_wind(wind_ne, [v[0], v[1]]);
            self.offer(Signal::Wind, rank, t_us, &w);
        }
    }

    /// Whether (lat, lon) in 1e-7 degrees is a fix: not (0, 0), which autopilots send
    /// before they have one, and on the globe. Counts and warns (once) when not.
    fn is_fix(&mut self, what: &'static str, lat_e7: i32, lon_e7: i32) -> bool {
        let fix =
            crate::features::frames::is_fix(f64::from(lat_e7) * 1e-7, f64::from(lon_e7) * 1e-7);
        if !fix {
            self.no_fix += 1;
            if self.no_fix == 1 {
                tracing::warn!(
                    message = what,
                    lat_e7,
                    lon_e7,
                    "position without a fix ignored (further ones are counted)"
                );
            }
        }
        fix
    }

    fn position(&mut self, rank: usize, t_us: i64, lat_e7: i32, lon_e7: i32, alt_mm: i32) {
        if !self.is_fix(SOURCES[Signal::Position as usize][rank], lat_e7, lon_e7) {
            return;
        }
        let p = [
            lon_e7 as f64 * 1e-7,
            lat_e7 as f64 * 1e-7,
            alt_mm as f64 * 1e-3,
        ];
        if !self.home_known {
            self.home_known = true;
            self.resampler.set_home([p[1], p[0], p[2]]);
        }
        self.offer(Signal::Position, rank, t_us, &p);
    }

    fn ingest(&mut self, t: i64, msg: &MavMessage) {
        match msg {
            MavMessage::ATTITUDE_QUATERNION(a) => {
                let q = [a.q1, a.q2, a.q3, a.q4].map(f64::from);
                self.attitude(0, t, q, [a.rollspeed, a.pitchspeed, a.yawspeed]);
            }
            MavMessage::ATTITUDE(a) => {
                let q = frames::quat_from_euler(a.roll as f64, a.pitch as f64, a.yaw as f64);
                self.attitude(1, t, q, [a.rollspeed, a.pitchspeed, a.yawspeed]);
            }
            MavMessage::HIGHRES_IMU(m) => self.highres_imu(t, m),
            MavMessage::SCALED_IMU(m) => self.milli_imu(
                (3, 1),
                t,
                [m.xgyro, m.ygyro, m.zgyro],
                [m.xacc, m.yacc, m.zacc],
            ),
            MavMessage::RAW_IMU(m) => self.milli_imu(
                (4, 2),
                t,
                [m.xgyro, m.ygyro, m.zgyro],
                [m.xacc, m.yacc, m.zacc],
            ),
            MavMessage::LOCAL_POSITION_NED(m) => {
                self.velocity(0, t, [m.vx, m.vy, m.vz].map(f64::from))
            }
            MavMessage::ODOMETRY(m) => self.odometry(t, m),
            MavMessage::GLOBAL_POSITION_INT(m) => {
                self.velocity(2, t, [m.vx, m.vy, m.vz].map(|x| x as f64 * 0.01));
                self.position(0, t, m.lat, m.lon, m.alt);
            }
            MavMessage::GPS_RAW_INT(m)
                if m.fix_type as u8 >= crate::dialect::GpsFixType::GPS_FIX_TYPE_3D_FIX as u8 =>
            {
                self.position(1, t, m.lat, m.lon, m.alt);
            }
            MavMessage::HOME_POSITION(h)
                if self.is_fix("HOME_POSITION", h.latitude, h.longitude) =>
            {
                self.home_known = true;
                self.resampler.set_home([
                    h.latitude as f64 * 1e-7,
                    h.longitude as f64 * 1e-7,
                    h.altitude as f64 * 1e-3,
                ]);
            }
            MavMessage::WIND(_) | MavMessage::WIND_COV(_) | MavMessage::VFR_HUD(_)
                if !self.air_data =>
            {
                // Air data from now on, for good: the still air's guess stops.
                self.air_data = true;
                self.ingest(t, msg);
            }
            MavMessage::WIND(w) => self.finite_wind(
                0,
                t,
                frames::wind_from_to_vec(w.speed as f64, w.direction as f64),
            ),
            MavMessage::WIND_COV(w) => self.finite_wind(1, t, [w.wind_x as f64, w.wind_y as f64]),
            MavMessage::VFR_HUD(h) => {
                let heading = (h.heading as f64).rem_euclid(360.0);
                self.offer(Signal::Wind, 2, t, &[h.airspeed as f64, heading]);
            }
            MavMessage::BATTERY_STATUS(b) if b.id == 0 => {
                self.battery_remaining(b.battery_remaining);
                self.power(t, msg);
            }
            MavMessage::SYS_STATUS(s) => {
                self.battery_remaining(s.battery_remaining);
                self.power(t, msg);
            }
            MavMessage::NAMED_VALUE_FLOAT(n) => self.named_value(n),
            _ => {}
        }
    }

    /// HIGHRES_IMU: its rates and its accelerations, each where its flags say it was updated
    /// (no flags: both).
    fn highres_imu(&mut self, t: i64, m: &crate::dialect::HIGHRES_IMU_DATA) {
        use crate::dialect::HighresImuUpdatedFlags as F;
        let f = m.fields_updated;
        let gyro = F::HIGHRES_IMU_UPDATED_XGYRO
            | F::HIGHRES_IMU_UPDATED_YGYRO
            | F::HIGHRES_IMU_UPDATED_ZGYRO;
        if f.is_empty() || f.contains(gyro) {
            self.offer(
                Signal::Rates,
                2,
                t,
                &[m.xgyro, m.ygyro, m.zgyro].map(f64::from),
            );
        }
        let acc =
            F::HIGHRES_IMU_UPDATED_XACC | F::HIGHRES_IMU_UPDATED_YACC | F::HIGHRES_IMU_UPDATED_ZACC;
        if f.is_empty() || f.contains(acc) {
            self.offer(
                Signal::Accel,
                0,
                t,
                &[m.xacc, m.yacc, m.zacc].map(f64::from),
            );
        }
    }

    /// ODOMETRY's velocity: in the local NED frame as it is, in the body frame rotated by
    /// its attitude (none given: not used).
    fn odometry(&mut self, t: i64, m: &crate::dialect::ODOMETRY_DATA) {
        use crate::dialect::MavFrame;
        let v = [m.vx, m.vy, m.vz].map(f64::from);
        let q = m.q.map(f64::from);
        match m.child_frame_id {
            MavFrame::MAV_FRAME_LOCAL_NED => self.velocity(1, t, v),
            MavFrame::MAV_FRAME_BODY_FRD if q.iter().any(|&x| x != 0.0) => {
                self.velocity(1, t, frames::rotate(q, v))
            }
            _ => {}
        }
    }

    /// A wind vector of rank `rank`, counted as non-finite instead where it is.
    fn finite_wind(&mut self, rank: usize, t: i64, v: [f64; 2]) {
        if v.iter().all(|x| x.is_finite()) {
            self.true_wind(rank, t, v);
        } else {
            self.nonfinite += 1;
        }
    }

    /// The data set's mission values sent as NAMED_VALUE_FLOAT (`cmd_speed`, `payload_g`,
    /// `cmd_alt`); any other name is not ours.
    fn named_value(&mut self, n: &crate::dialect::NAMED_VALUE_FLOAT_DATA) {
        let name = n.name.to_str().unwrap_or("").trim_end_matches('\0');
        let i = match name {
            "cmd_speed" => 0,
            "payload_g" => 1,
            "cmd_alt" => 2,
            _ => return,
        };
        if n.value.is_finite() {
            self.mission_msg[i] = Some(n.value);
            self.refresh_mission();
        } else {
            self.nonfinite += 1;
        }
    }

    /// MAVLink's `battery_remaining`: 0–100 %, −1 unknown.
    fn battery_remaining(&mut self, pct: i8) {
        if (0..=100).contains(&pct) {
            self.battery_pct = Some(f32::from(pct));
        }
    }

    /// The pack's power from BATTERY_STATUS (rank 0) or SYS_STATUS (rank 1), as
    /// [`crate::source::messages::power`] reads it.
    fn power(&mut self, t: i64, msg: &MavMessage) {
        if let Some(r) = crate::source::messages::power::power_reading(msg) {
            self.offer(
                Signal::Power,
                r.rank,
                t,
                &[r.voltage_v, r.current_a, r.power_w()],
            );
        }
    }
}
