//! A simulated ArduPilot flight as the autopilot's own DataFlash `.bin` log (what
//! `simulate --out FILE.bin` writes): the flight's MAVLink turned into the log messages
//! ArduPilot Copter writes, with their names, labels and format characters (ArduPilot 4.x),
//! `TimeUS` counted from the first record.
//!
//! | MAVLink | DataFlash |
//! |---|---|
//! | HEARTBEAT (on change) | `MODE` ModeNum, `ARM` ArmState |
//! | PARAM_VALUE | `PARM` Name, Value |
//! | ATTITUDE | `ATT` Roll, Pitch, Yaw (centidegrees) |
//! | RAW_IMU | `IMU` GyrX–Z (rad/s), AccX–Z (m/s²) |
//! | GLOBAL_POSITION_INT | `XKF1` VN, VE, VD (m/s), then `POS` Lat, Lng, Alt |
//! | GPS_RAW_INT | `GPS` Status, NSats, Lat, Lng, Alt, Spd, GCrs |
//! | WIND | `XKF2` VWN, VWE |
//! | BATTERY_STATUS | `BAT` Volt, Curr, CurrTot, EnrgTot, RemPct |
//! | NAMED_VALUE_FLOAT | `NVF` Name, Value (dronewatt's mission hints) |
//!
//! Only the ArduPilot style is written: PX4 logs ULog, not DataFlash.

use super::dataflash::{MsgDef, Value, Writer};
use crate::dialect as d;
use crate::features::units::G;
use crate::MavMessage;

const PARM: MsgDef = MsgDef {
    id: 64,
    name: "PARM",
    format: "QNf",
    labels: "TimeUS,Name,Value",
};
const MODE: MsgDef = MsgDef {
    id: 65,
    name: "MODE",
    format: "QMBB",
    labels: "TimeUS,Mode,ModeNum,Rsn",
};
const ARM: MsgDef = MsgDef {
    id: 66,
    name: "ARM",
    format: "QBIBB",
    labels: "TimeUS,ArmState,ArmChecks,Forced,Method",
};
const ATT: MsgDef = MsgDef {
    id: 67,
    name: "ATT",
    format: "QccccCCCCB",
    labels: "TimeUS,DesRoll,Roll,DesPitch,Pitch,DesYaw,Yaw,ErrRP,ErrYaw,AEKF",
};
const IMU: MsgDef = MsgDef {
    id: 68,
    name: "IMU",
    format: "QBffffffIIfBBHH",
    labels: "TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,EG,EA,T,GH,AH,GHz,AHz",
};
const XKF1: MsgDef = MsgDef {
    id: 69,
    name: "XKF1",
    format: "QBccCfffffffccce",
    labels: "TimeUS,C,Roll,Pitch,Yaw,VN,VE,VD,dPD,PN,PE,PD,GX,GY,GZ,OH",
};
const POS: MsgDef = MsgDef {
    id: 70,
    name: "POS",
    format: "QLLfff",
    labels: "TimeUS,Lat,Lng,Alt,RelHomeAlt,RelOriginAlt",
};
const GPS: MsgDef = MsgDef {
    id: 71,
    name: "GPS",
    format: "QBBIHBcLLeffffB",
    labels: "TimeUS,I,Status,GMS,GWk,NSats,HDop,Lat,Lng,Alt,Spd,GCrs,VZ,Yaw,U",
};
const XKF2: MsgDef = MsgDef {
    id: 72,
    name: "XKF2",
    format: "QBccccchhhhhhccB",
    labels: "TimeUS,C,AX,AY,AZ,VWN,VWE,MN,ME,MD,MX,MY,MZ,IDX,IDY,IS",
};
const BAT: MsgDef = MsgDef {
    id: 73,
    name: "BAT",
    format: "QBfffffcfBBB",
    labels: "TimeUS,Inst,Volt,VoltR,Curr,CurrTot,EnrgTot,Temp,Res,RemPct,H,SH",
};
const NVF: MsgDef = MsgDef {
    id: 74,
    name: "NVF",
    format: "QNf",
    labels: "TimeUS,Name,Value",
};

/// MAVLink `records` (µs since the Unix epoch, the message), in time order, as DataFlash `.bin`
/// bytes (module docs).
pub fn from_mavlink(records: &[(u64, &MavMessage)]) -> Vec<u8> {
    use Value::{Float as F, Int as I, Str as S};
    let mut w = Writer::new();
    let t0 = records.first().map_or(0, |r| r.0);
    let (mut mode, mut armed) = (None, None);
    let mut vz = 0.0;
    for &(t_us, msg) in records {
        let t = I((t_us - t0) as i64);
        match msg {
            MavMessage::HEARTBEAT(h) => {
                if mode != Some(h.custom_mode) {
                    mode = Some(h.custom_mode);
                    w.write(
                        &MODE,
                        &[t, I(h.custom_mode.into()), I(h.custom_mode.into()), I(0)],
                    );
                }
                let a = h
                    .base_mode
                    .contains(d::MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
                if armed != Some(a) {
                    armed = Some(a);
                    w.write(&ARM, &[t, I(a.into())]);
                }
            }
            MavMessage::PARAM_VALUE(p) => {
                let name = crate::source::messages::name_text(&p.param_id);
                w.write(&PARM, &[t, S(&name), F(p.param_value.into())]);
            }
            MavMessage::ATTITUDE(a) => {
                let deg = |x: f32| f64::from(x).to_degrees();
                w.write(
                    &ATT,
                    &[
                        t,
                        F(deg(a.roll)),
                        F(deg(a.roll)),
                        F(deg(a.pitch)),
                        F(deg(a.pitch)),
                        F(deg(a.yaw).rem_euclid(360.0)),
                        F(deg(a.yaw).rem_euclid(360.0)),
                    ],
                );
            }
            MavMessage::RAW_IMU(m) => {
                let rad = |x: i16| F(f64::from(x) * 1e-3);
                let acc = |x: i16| F(f64::from(x) * 1e-3 * G);
                w.write(
                    &IMU,
                    &[
                        t,
                        I(0),
                        rad(m.xgyro),
                        rad(m.ygyro),
                        rad(m.zgyro),
                        acc(m.xacc),
                        acc(m.yacc),
                        acc(m.zacc),
                        I(0),
                        I(0),
                        F(25.0),
                        I(1),
                        I(1),
                        I(400),
                        I(400),
                    ],
                );
            }
            MavMessage::GLOBAL_POSITION_INT(m) => {
                let v = |x: i16| F(f64::from(x) * 0.01);
                vz = f64::from(m.vz) * 0.01;
                w.write(
                    &XKF1,
                    &[t, I(0), F(0.0), F(0.0), F(0.0), v(m.vx), v(m.vy), v(m.vz)],
                );
                w.write(
                    &POS,
                    &[
                        t,
                        I(m.lat.into()),
                        I(m.lon.into()),
                        F(f64::from(m.alt) * 1e-3),
                        F(f64::from(m.relative_alt) * 1e-3),
                        F(f64::from(m.relative_alt) * 1e-3),
                    ],
                );
            }
            MavMessage::GPS_RAW_INT(m) => gps(&mut w, t, m, vz),
            MavMessage::WIND(m) => {
                // WIND's direction is where the wind comes from; XKF2's is its velocity.
                let (s, dir) = (f64::from(m.speed), f64::from(m.direction).to_radians());
                w.write(
                    &XKF2,
                    &[
                        t,
                        I(0),
                        F(0.0),
                        F(0.0),
                        F(0.0),
                        F(-s * dir.cos()),
                        F(-s * dir.sin()),
                    ],
                );
            }
            MavMessage::BATTERY_STATUS(b) if b.id == 0 => bat(&mut w, t, b),
            MavMessage::NAMED_VALUE_FLOAT(n) => {
                let name = crate::source::messages::name_text(&n.name);
                w.write(&NVF, &[t, S(&name), F(n.value.into())]);
            }
            _ => {}
        }
    }
    w.into_bytes()
}

/// GPS_RAW_INT as a GPS row (instance 0), with the last GLOBAL_POSITION_INT's vertical speed.
fn gps(w: &mut Writer, t: Value, m: &d::GPS_RAW_INT_DATA, vz: f64) {
    use Value::{Float as F, Int as I};
    let spd = if m.vel == u16::MAX {
        0.0
    } else {
        f64::from(m.vel) * 0.01
    };
    let crs = if m.cog == u16::MAX {
        0.0
    } else {
        f64::from(m.cog) * 0.01
    };
    let alt = f64::from(m.alt) * 1e-3;
    w.write(
        &GPS,
        &[
            t,
            I(0),
            I(m.fix_type as i64),
            I(0),
            I(0),
            I(m.satellites_visible.into()),
            F(0.8),
            I(m.lat.into()),
            I(m.lon.into()),
            F(alt),
            F(spd),
            F(crs),
            F(vz),
        ],
    );
}

/// BATTERY_STATUS (the first pack) as a BAT row (instance 0).
fn bat(w: &mut Writer, t: Value, b: &d::BATTERY_STATUS_DATA) {
    use Value::{Float as F, Int as I};
    let volt = if b.voltages[0] == u16::MAX {
        0.0
    } else {
        f64::from(b.voltages[0]) * 1e-3
    };
    let curr = f64::from(b.current_battery) * 0.01;
    w.write(
        &BAT,
        &[
            t,
            I(0),
            F(volt),
            F(volt),
            F(curr),
            F(b.current_consumed.into()),
            F(f64::from(b.energy_consumed) / 36.0),
            F(25.0),
            F(0.0),
            I(b.battery_remaining.into()),
            I(1),
            I(0),
        ],
    );
}
