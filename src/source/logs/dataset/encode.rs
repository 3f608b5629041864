//! A data-set flight encoded as MAVLink: each row as the messages an autopilot would send,
//! stamped on the flight's tlog clock (the mapping is in [`super`]'s docs).

use mavlink::{MavHeader, MavlinkVersion};

use super::{Flight, Row};
use crate::dialect::*;
use crate::features::frames;
use crate::features::units::{centidegrees, scaled, whole_degrees};
use crate::MavMessage;

/// Days from 1970-01-01 to a civil date (H. Hinnant's algorithm).
fn days_from_civil(y: i64, m: i64, d: i64) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let doy = (153 * (m + if m > 2 { -3 } else { 9 }) + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// The flight's tlog clock base, µs since the Unix epoch (see the module docs).
pub fn epoch_base_us(f: &Flight) -> u64 {
    let d: Vec<i64> = f.date.split('-').filter_map(|x| x.parse().ok()).collect();
    let t: Vec<i64> = f
        .time_day
        .split(':')
        .filter_map(|x| x.parse().ok())
        .collect();
    match (d.as_slice(), t.as_slice()) {
        ([y, m, dd], [hh, mm, ..])
            if (1..=12).contains(m)
                && (1..=31).contains(dd)
                && (1970..=9999).contains(y)
                && (0..24).contains(hh)
                && (0..60).contains(mm) =>
        {
            let s = days_from_civil(*y, *m, *dd) * 86_400 + hh * 3600 + mm * 60;
            (s.max(0) as u64) * 1_000_000
        }
        _ => 0,
    }
}

/// Encode one flight as tlog bytes (see the module docs for the mapping).
pub fn encode_flight(f: &Flight) -> Vec<u8> {
    let mut enc = Encoder {
        buf: Vec::with_capacity(f.rows.len() * 500),
        seq: 0,
        t_us: 0,
        boot_ms: 0,
    };
    let base = epoch_base_us(f);
    let mut last_hb: Option<f64> = None;
    let mut home: Option<[f64; 3]> = None;
    for r in &f.rows {
        // Saturating: a CSV may hold any finite time (found by fuzzing: 1e300 s overflowed).
        enc.t_us = base.saturating_add((r.time_s * 1e6).round().max(0.0) as u64);
        enc.boot_ms = (r.time_s * 1e3).round().max(0.0) as u32;
        if last_hb.is_none_or(|t| r.time_s - t >= 1.0) {
            last_hb = Some(r.time_s);
            enc.heartbeat();
            enc.named("cmd_speed", f.speed_m_s);
            enc.named("payload_g", f.payload_g);
            enc.named("cmd_alt", f.altitude_m);
        }
        if home.is_none() && (r.lat_deg != 0.0 || r.lon_deg != 0.0) {
            let h = [r.lat_deg, r.lon_deg, r.alt_m];
            home = Some(h);
            enc.send(MavMessage::HOME_POSITION(HOME_POSITION_DATA {
                latitude: deg_e7(h[0]),
                longitude: deg_e7(h[1]),
                altitude: mm(h[2]),
                q: [1.0, 0.0, 0.0, 0.0],
                time_usec: enc.t_us,
                ..Default::default()
            }));
        }
        enc.row(r, home);
    }
    enc.buf
}

fn deg_e7(x: f64) -> i32 {
    scaled(x, 1e7).unwrap_or(0)
}
fn mm(x: f64) -> i32 {
    scaled(x, 1e3).unwrap_or(0)
}
fn i16_scaled(x: f64, k: f64) -> i16 {
    scaled(x, k).unwrap_or(0)
}

struct Encoder {
    buf: Vec<u8>,
    seq: u8,
    t_us: u64,
    boot_ms: u32,
}

impl Encoder {
    fn send(&mut self, msg: MavMessage) {
        let h = MavHeader {
            system_id: 1,
            component_id: 1,
            sequence: self.seq,
        };
        self.seq = self.seq.wrapping_add(1);
        crate::source::logs::tlog::write_record(
            &mut self.buf,
            self.t_us,
            h,
            &msg,
            MavlinkVersion::V2,
        );
    }

    fn heartbeat(&mut self) {
        self.send(MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: 0,
            mavtype: MavType::MAV_TYPE_QUADROTOR,
            autopilot: MavAutopilot::MAV_AUTOPILOT_GENERIC,
            base_mode: MavModeFlag::empty(),
            system_status: MavState::MAV_STATE_ACTIVE,
            mavlink_version: 3,
        }));
    }

    fn named(&mut self, name: &str, value: f64) {
        self.send(MavMessage::NAMED_VALUE_FLOAT(NAMED_VALUE_FLOAT_DATA {
            time_boot_ms: self.boot_ms,
            value: value as f32,
            name: name.into(),
        }));
    }

    fn row(&mut self, r: &Row, home: Option<[f64; 3]>) {
        let t = self.boot_ms;
        let q = frames::ds_to_ned(r.q_wxyz());
        let [roll, pitch, yaw] = frames::euler_ned(q);
        let [p, qq, rr] = r.ang.map(|x| x as f32);
        self.send(MavMessage::ATTITUDE(ATTITUDE_DATA {
            time_boot_ms: t,
            roll: roll as f32,
            pitch: pitch as f32,
            yaw: yaw as f32,
            rollspeed: p,
            pitchspeed: qq,
            yawspeed: rr,
        }));
        self.send(MavMessage::ATTITUDE_QUATERNION(ATTITUDE_QUATERNION_DATA {
            time_boot_ms: t,
            q1: q[0] as f32,
            q2: q[1] as f32,
            q3: q[2] as f32,
            q4: q[3] as f32,
            rollspeed: p,
            pitchspeed: qq,
            yawspeed: rr,
            repr_offset_q: [0.0; 4],
        }));
        let a = r.acc.map(|x| x as f32);
        self.send(MavMessage::HIGHRES_IMU(HIGHRES_IMU_DATA {
            time_usec: self.t_us,
            xacc: a[0],
            yacc: a[1],
            zacc: a[2],
            xgyro: p,
            ygyro: qq,
            zgyro: rr,
            fields_updated: HighresImuUpdatedFlags::HIGHRES_IMU_UPDATED_XACC
                | HighresImuUpdatedFlags::HIGHRES_IMU_UPDATED_YACC
                | HighresImuUpdatedFlags::HIGHRES_IMU_UPDATED_ZACC
                | HighresImuUpdatedFlags::HIGHRES_IMU_UPDATED_XGYRO
                | HighresImuUpdatedFlags::HIGHRES_IMU_UPDATED_YGYRO
                | HighresImuUpdatedFlags::HIGHRES_IMU_UPDATED_ZGYRO,
            ..Default::default()
        }));
        let v = frames::body_to_ned_vel(r.vel, yaw);
        let (n, e) = home.map_or((0.0, 0.0), |h| {
            frames::ne_offset_m(h[0], h[1], r.lat_deg, r.lon_deg)
        });
        let home_alt = home.map_or(r.alt_m, |h| h[2]);
        self.send(MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
            time_boot_ms: t,
            x: n as f32,
            y: e as f32,
            z: -(r.alt_m - home_alt) as f32,
            vx: v[0] as f32,
            vy: v[1] as f32,
            vz: v[2] as f32,
        }));
        let hdg = yaw.to_degrees().rem_euclid(360.0);
        self.send(MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
            time_boot_ms: t,
            lat: deg_e7(r.lat_deg),
            lon: deg_e7(r.lon_deg),
            alt: mm(r.alt_m),
            relative_alt: mm(r.alt_m - home_alt),
            vx: i16_scaled(v[0], 100.0),
            vy: i16_scaled(v[1], 100.0),
            vz: i16_scaled(v[2], 100.0),
            hdg: centidegrees(hdg).unwrap_or(u16::MAX),
        }));
        let apparent = frames::wind_from_to_vec(r.wind_speed, r.wind_angle);
        let [ws, wd] = frames::wind_vec_to_from([apparent[0] + v[0], apparent[1] + v[1]]);
        self.send(MavMessage::WIND(WIND_DATA {
            direction: wd as f32,
            speed: ws as f32,
            speed_z: 0.0,
        }));
        self.send(MavMessage::VFR_HUD(VFR_HUD_DATA {
            airspeed: r.wind_speed as f32,
            groundspeed: v[0].hypot(v[1]) as f32,
            alt: r.alt_m as f32,
            climb: r.vel[2] as f32,
            heading: whole_degrees(hdg).unwrap_or(0),
            throttle: 0,
        }));
        let mv = scaled::<u16>(r.voltage_v.max(0.0), 1e3).map_or(0, |v| v.min(65_534));
        let ca = match i16_scaled(r.current_a, 100.0) {
            -1 => 0,
            c => c,
        };
        self.send(MavMessage::SYS_STATUS(SYS_STATUS_DATA {
            voltage_battery: mv,
            current_battery: ca,
            battery_remaining: -1,
            ..Default::default()
        }));
        let mut cells = [u16::MAX; 10];
        cells[0] = mv;
        self.send(MavMessage::BATTERY_STATUS(BATTERY_STATUS_DATA {
            current_consumed: -1,
            energy_consumed: -1,
            temperature: i16::MAX,
            voltages: cells,
            current_battery: ca,
            id: 0,
            battery_function: MavBatteryFunction::MAV_BATTERY_FUNCTION_ALL,
            mavtype: MavBatteryType::MAV_BATTERY_TYPE_LIPO,
            battery_remaining: -1,
            ..Default::default()
        }));
    }
}
