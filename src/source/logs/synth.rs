//! What the readers of an autopilot's own log ([`super::dataflash`], [`super::ulog`]) share
//! in turning its records into the [`TimedMessage`]s a tlog gives: the log's clock (through
//! [`Clock`], jumps counted), a HEARTBEAT naming the vehicle at 1 Hz of log time, and the
//! messages' sequence.

use mavlink::MavHeader;

use crate::dialect as d;
use crate::report::status::IngestStats;
use crate::source::frame::timed::Clock;
use crate::source::TimedMessage;
use crate::MavMessage;

/// The synthesised stream's state.
#[derive(Default)]
pub(super) struct Synth {
    clock: Clock,
    t_s: f64,
    /// The log's time, ms, for the messages' `time_boot_ms`.
    pub boot_ms: u32,
    /// Whether any record had a time.
    pub timed: bool,
    pub autopilot: d::MavAutopilot,
    pub mavtype: d::MavType,
    /// The flight mode the log last said, as the HEARTBEAT's `custom_mode`.
    pub custom_mode: u32,
    pub armed: bool,
    next_heartbeat_s: Option<f64>,
    seq: u8,
}

impl Synth {
    pub fn new(autopilot: d::MavAutopilot, mavtype: d::MavType) -> Self {
        Self {
            autopilot,
            mavtype,
            ..Self::default()
        }
    }

    /// One message at the current log time.
    pub fn push(&mut self, msg: MavMessage, out: &mut Vec<TimedMessage>) {
        let header = MavHeader {
            system_id: 1,
            component_id: 1,
            sequence: self.seq,
        };
        self.seq = self.seq.wrapping_add(1);
        out.push(TimedMessage::new(self.t_s, header, msg));
    }

    /// A record stamped `us` (µs of log time): the clock moves (a jump is counted in
    /// `stats`), and the HEARTBEAT goes out when one is due.
    pub fn at(&mut self, us: u64, stats: &IngestStats, out: &mut Vec<TimedMessage>) {
        let (t, jump) = self.clock.map(us as f64 * 1e-6);
        if jump {
            IngestStats::add(&stats.gaps, 1);
            IngestStats::add(&stats.clock_jumps, 1);
        }
        self.t_s = t;
        self.boot_ms = (us / 1000) as u32;
        self.timed = true;
        if self.next_heartbeat_s.is_none_or(|n| t >= n) {
            self.announce(out);
        }
    }

    /// A HEARTBEAT now (the mode or arming changed), the next one a second later.
    pub fn announce(&mut self, out: &mut Vec<TimedMessage>) {
        self.next_heartbeat_s = Some(self.t_s + 1.0);
        self.push(self.heartbeat(), out);
    }

    /// The battery as a ground station hears it: SYS_STATUS and BATTERY_STATUS from the
    /// voltage (V), current (A, when known), remaining % and what was consumed (mAh, Wh).
    pub fn battery(
        &mut self,
        volt: f64,
        amps: Option<f64>,
        remaining: i8,
        consumed_mah: Option<f64>,
        consumed_wh: Option<f64>,
        out: &mut Vec<TimedMessage>,
    ) {
        let mv = (volt * 1000.0).round().clamp(0.0, 65534.0) as u16;
        let ca = amps.map_or(-1, |c| (c * 100.0).round().clamp(-32768.0, 32767.0) as i16);
        let s = d::SYS_STATUS_DATA {
            voltage_battery: mv,
            current_battery: ca,
            battery_remaining: remaining,
            ..Default::default()
        };
        self.push(MavMessage::SYS_STATUS(s), out);
        let mut voltages = [u16::MAX; 10];
        voltages[0] = mv;
        let b = d::BATTERY_STATUS_DATA {
            current_consumed: consumed_mah.map_or(-1, |x| x.round() as i32),
            // hJ: 1 Wh = 36 hJ.
            energy_consumed: consumed_wh.map_or(-1, |x| (x * 36.0).round() as i32),
            temperature: i16::MAX,
            voltages,
            current_battery: ca,
            id: 0,
            battery_remaining: remaining,
            ..Default::default()
        };
        self.push(MavMessage::BATTERY_STATUS(b), out);
    }

    /// A parameter as PARAM_VALUE (its value's bits as the type says, index unknown).
    pub fn param(
        &mut self,
        name: &str,
        value: f32,
        ty: d::MavParamType,
        out: &mut Vec<TimedMessage>,
    ) {
        let p = d::PARAM_VALUE_DATA {
            param_value: value,
            param_count: 0,
            param_index: u16::MAX,
            param_id: name.into(),
            param_type: ty,
        };
        self.push(MavMessage::PARAM_VALUE(p), out);
    }

    /// HIGHRES_IMU: specific force (m/s²) and rates (rad/s), body frame.
    pub fn imu(
        &mut self,
        time_usec: u64,
        acc: [f32; 3],
        gyro: [f32; 3],
        out: &mut Vec<TimedMessage>,
    ) {
        let ([xacc, yacc, zacc], [xgyro, ygyro, zgyro]) = (acc, gyro);
        let m = d::HIGHRES_IMU_DATA {
            time_usec,
            xacc,
            yacc,
            zacc,
            xgyro,
            ygyro,
            zgyro,
            ..Default::default()
        };
        self.push(MavMessage::HIGHRES_IMU(m), out);
    }

    /// LOCAL_POSITION_NED at the log's time: position (m) and velocity (m/s), NED.
    pub fn local_ned(&mut self, pos: [f32; 3], vel: [f32; 3], out: &mut Vec<TimedMessage>) {
        let ([x, y, z], [vx, vy, vz]) = (pos, vel);
        let m = d::LOCAL_POSITION_NED_DATA {
            time_boot_ms: self.boot_ms,
            x,
            y,
            z,
            vx,
            vy,
            vz,
        };
        self.push(MavMessage::LOCAL_POSITION_NED(m), out);
    }

    /// WIND_COV: the wind's north and east components, m/s (where it blows to).
    pub fn wind(&mut self, time_usec: u64, north: f64, east: f64, out: &mut Vec<TimedMessage>) {
        let m = d::WIND_COV_DATA {
            time_usec,
            wind_x: north as f32,
            wind_y: east as f32,
            ..Default::default()
        };
        self.push(MavMessage::WIND_COV(m), out);
    }

    fn heartbeat(&self) -> MavMessage {
        let mut base = d::MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
            | d::MavModeFlag::MAV_MODE_FLAG_STABILIZE_ENABLED;
        if self.armed {
            base |= d::MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
        }
        MavMessage::HEARTBEAT(d::HEARTBEAT_DATA {
            custom_mode: self.custom_mode,
            mavtype: self.mavtype,
            autopilot: self.autopilot,
            base_mode: base,
            system_status: if self.armed {
                d::MavState::MAV_STATE_ACTIVE
            } else {
                d::MavState::MAV_STATE_STANDBY
            },
            mavlink_version: 3,
        })
    }
}

/// What the tests of both readers check their output with.
#[cfg(test)]
pub(super) mod testutil {
    use super::*;

    /// `(t_s, voltage_battery, current_battery)` of every SYS_STATUS sent.
    pub fn sys_status(m: &[TimedMessage]) -> Vec<(f64, u16, i16)> {
        m.iter()
            .filter_map(|m| match &m.msg {
                MavMessage::SYS_STATUS(s) => Some((m.t_s, s.voltage_battery, s.current_battery)),
                _ => None,
            })
            .collect()
    }

    /// The vehicle type and autopilot of the first message, which must be the HEARTBEAT
    /// naming the vehicle.
    pub fn first_heartbeat(m: &[TimedMessage]) -> (d::MavType, d::MavAutopilot) {
        let MavMessage::HEARTBEAT(h) = &m[0].msg else {
            panic!("{:?}", m[0])
        };
        (h.mavtype, h.autopilot)
    }
}
