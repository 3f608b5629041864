//! The hand-made MAVLink streams the telemetry tests feed: an ArduPilot-style and a
//! PX4-style message mix at their real rates, around a flight whose answer is known.

use super::*;

pub(super) const LAT0: f64 = 40.459;
pub(super) const LON0: f64 = -79.78;
pub(super) const R: f64 = 6_371_000.0;

/// A vehicle in steady flight: NED velocity, heading, level attitude.
#[derive(Clone, Copy)]
pub(super) struct Flight {
    pub(super) v_ned: [f64; 3],
    pub(super) heading_deg: f64,
}

impl Flight {
    pub(super) fn lat_lon_alt(&self, t: f64) -> (f64, f64, f64) {
        let lat = LAT0 + (self.v_ned[0] * t / R).to_degrees();
        let lon = LON0 + (self.v_ned[1] * t / (R * LAT0.to_radians().cos())).to_degrees();
        (lat, lon, 300.0 - self.v_ned[2] * t)
    }
}

pub(super) struct Mix {
    pub(super) msgs: Vec<(f64, u32, MavMessage)>,
}

impl Mix {
    pub(super) fn new() -> Self {
        Self { msgs: Vec::new() }
    }
    /// `f(t)` every `1/hz` s over `[from, to)`.
    pub(super) fn every(&mut self, hz: f64, from: f64, to: f64, f: impl Fn(f64) -> MavMessage) {
        let n = ((to - from) * hz).ceil() as usize;
        for k in 0..n {
            let t = from + k as f64 / hz;
            if t < to {
                self.msgs.push((t, 1, f(t)));
            }
        }
    }
    pub(super) fn at(&mut self, t: f64, sys: u32, m: MavMessage) {
        self.msgs.push((t, sys, m));
    }
    /// Run through a fresh stage; returns the stage and every window.
    pub(super) fn run(
        mut self,
        cfg: &TelemetryConfig,
        mission: &MissionConfig,
    ) -> (Telemetry, Vec<Window>) {
        self.msgs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut tel = Telemetry::new(cfg, mission);
        let mut out = Vec::new();
        for (i, (t, sys, msg)) in self.msgs.into_iter().enumerate() {
            let header = mavlink::MavHeader {
                system_id: sys,
                component_id: 1,
                sequence: i as u8,
            };
            tel.push(&TimedMessage::new(1000.0 + t, header, msg), &mut out);
        }
        tel.finish(&mut out);
        (tel, out)
    }
}

pub(super) fn heartbeat(ap: MavAutopilot) -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot: ap,
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
        ..Default::default()
    })
}

pub(super) fn gpi(f: Flight, t: f64) -> MavMessage {
    let (lat, lon, alt) = f.lat_lon_alt(t);
    MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
        lat: (lat * 1e7).round() as i32,
        lon: (lon * 1e7).round() as i32,
        alt: (alt * 1e3).round() as i32,
        vx: (f.v_ned[0] * 100.0) as i16,
        vy: (f.v_ned[1] * 100.0) as i16,
        vz: (f.v_ned[2] * 100.0) as i16,
        hdg: (f.heading_deg * 100.0) as u16,
        ..Default::default()
    })
}

pub(super) fn battery(v: f64, a: f64) -> [MavMessage; 2] {
    let mut cells = [u16::MAX; 10];
    cells[0] = (v * 1e3) as u16;
    [
        MavMessage::SYS_STATUS(SYS_STATUS_DATA {
            voltage_battery: (v * 1e3) as u16,
            current_battery: (a * 100.0) as i16,
            battery_remaining: -1,
            ..Default::default()
        }),
        MavMessage::BATTERY_STATUS(BATTERY_STATUS_DATA {
            voltages: cells,
            current_battery: (a * 100.0) as i16,
            battery_remaining: -1,
            ..Default::default()
        }),
    ]
}

/// ArduPilot's default streams: ATTITUDE (Euler), RAW_IMU (mG, mrad/s), GLOBAL_POSITION_INT
/// (cm/s velocity), WIND, VFR_HUD, SYS_STATUS, BATTERY_STATUS. No ATTITUDE_QUATERNION, no
/// HIGHRES_IMU (and here no LOCAL_POSITION_NED: no EKF origin).
pub(super) fn ardupilot(f: Flight, until: f64) -> Mix {
    let mut m = Mix::new();
    m.every(1.0, 0.0, until, |_| {
        heartbeat(MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA)
    });
    let yaw = f.heading_deg.to_radians() as f32;
    m.every(10.0, 0.0, until, |_| {
        MavMessage::ATTITUDE(ATTITUDE_DATA {
            yaw,
            ..Default::default()
        })
    });
    m.every(10.0, 0.02, until, |_| {
        MavMessage::RAW_IMU(RAW_IMU_DATA {
            zacc: -1000,
            ..Default::default()
        })
    });
    m.every(5.0, 0.04, until, |t| gpi(f, t));
    // True wind: 3 m/s from the west.
    m.every(3.0, 0.06, until, |_| {
        MavMessage::WIND(WIND_DATA {
            direction: 270.0,
            speed: 3.0,
            speed_z: 0.0,
        })
    });
    m.every(4.0, 0.08, until, |_| {
        MavMessage::VFR_HUD(VFR_HUD_DATA {
            airspeed: 8.5,
            heading: f.heading_deg as i16,
            ..Default::default()
        })
    });
    m.every(2.0, 0.1, until, |_| battery(23.0, 20.0)[0].clone());
    m.every(2.0, 0.1, until, |_| battery(23.0, 20.0)[1].clone());
    m
}

pub(super) fn quat_yaw(yaw_deg: f64) -> [f32; 4] {
    let h = yaw_deg.to_radians() / 2.0;
    [h.cos() as f32, 0.0, 0.0, h.sin() as f32]
}

/// PX4's default streams: ATTITUDE_QUATERNION, HIGHRES_IMU (m/s²), LOCAL_POSITION_NED,
/// GLOBAL_POSITION_INT, VFR_HUD, BATTERY_STATUS, SYS_STATUS, HOME_POSITION; no WIND.
pub(super) fn px4(f: Flight, from: f64, until: f64) -> Mix {
    let mut m = Mix::new();
    m.every(1.0, from, until, |_| {
        heartbeat(MavAutopilot::MAV_AUTOPILOT_PX4)
    });
    let q = quat_yaw(f.heading_deg);
    m.every(50.0, from + 0.001, until, |_| {
        MavMessage::ATTITUDE_QUATERNION(ATTITUDE_QUATERNION_DATA {
            q1: q[0],
            q2: q[1],
            q3: q[2],
            q4: q[3],
            ..Default::default()
        })
    });
    m.every(50.0, from + 0.002, until, |_| {
        MavMessage::HIGHRES_IMU(HIGHRES_IMU_DATA {
            zacc: -9.81,
            fields_updated: HighresImuUpdatedFlags::all(),
            ..Default::default()
        })
    });
    let v = f.v_ned.map(|x| x as f32);
    m.every(30.0, from + 0.003, until, |_| {
        MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
            vx: v[0],
            vy: v[1],
            vz: v[2],
            ..Default::default()
        })
    });
    m.every(10.0, from + 0.004, until, |t| gpi(f, t));
    m.every(4.0, from + 0.005, until, |_| {
        MavMessage::VFR_HUD(VFR_HUD_DATA {
            airspeed: 5.0,
            heading: f.heading_deg as i16,
            ..Default::default()
        })
    });
    m.every(1.0, from + 0.006, until, |_| battery(22.0, 10.0)[1].clone());
    m.every(1.0, from + 0.007, until, |_| battery(22.0, 10.0)[0].clone());
    m.at(
        from + 0.5,
        1,
        MavMessage::HOME_POSITION(HOME_POSITION_DATA {
            latitude: (LAT0 * 1e7) as i32,
            longitude: (LON0 * 1e7) as i32,
            altitude: 300_000,
            ..Default::default()
        }),
    );
    m
}

pub(super) fn source(tel: &Telemetry, signal: &str) -> Option<&'static str> {
    tel.health()
        .into_iter()
        .find(|h| h.signal == signal)
        .and_then(|h| h.source)
}

pub(super) fn close(a: f32, b: f64, tol: f64) -> bool {
    (a as f64 - b).abs() <= tol
}
