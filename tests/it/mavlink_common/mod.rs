//! Shared by the ingest/link/cli tests and the parse benchmark: a realistic autopilot
//! message mix, frame and tlog builders, and the pymavlink peer.
#![allow(dead_code)]

use dronewatt::dialect::*;
use dronewatt::MavMessage;
use mavlink::{MavHeader, MavlinkVersion};

/// One message as an autopilot would stream it: (µs since epoch, header, message).
pub type Rec = (u64, MavHeader, MavMessage);

/// Where the recording pretends to start: 2024-05-01 12:00:00 UTC, in µs.
pub const T0_US: u64 = 1_714_564_800_000_000;

/// `n` messages of an ArduPilot-like stream (system 1, component 1): every 100 ms tick
/// ATTITUDE, GLOBAL_POSITION_INT, LOCAL_POSITION_NED, SCALED_IMU, SERVO_OUTPUT_RAW; at
/// 5 Hz GPS_RAW_INT; 4 Hz VFR_HUD; 2 Hz SYS_STATUS; 1 Hz HEARTBEAT and BATTERY_STATUS.
/// Values move with time so no two frames are alike.
pub fn flight(n: usize) -> Vec<Rec> {
    let mut out = Vec::with_capacity(n);
    let mut seq = 0u8;
    let mut tick = 0u64;
    while out.len() < n {
        let t_ms = (tick * 100) as u32;
        let t = t_ms as f32 / 1000.0;
        let mut msgs = vec![
            MavMessage::ATTITUDE(ATTITUDE_DATA {
                time_boot_ms: t_ms,
                roll: 0.05 * (t * 0.7).sin(),
                pitch: -0.1 + 0.02 * (t * 0.3).cos(),
                yaw: (t * 0.05) % std::f32::consts::TAU,
                rollspeed: 0.01 * t.sin(),
                pitchspeed: 0.01 * t.cos(),
                yawspeed: 0.002,
            }),
            MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
                time_boot_ms: t_ms,
                lat: 404_433_000 + (tick as i32) * 7,
                lon: -799_436_000 + (tick as i32) * 5,
                alt: 300_000 + ((t * 0.2).sin() * 2000.0) as i32,
                relative_alt: 25_000,
                vx: 800,
                vy: -120,
                vz: (10.0 * t.sin()) as i16,
                hdg: ((tick * 3) % 36000) as u16,
            }),
            MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
                time_boot_ms: t_ms,
                x: 8.0 * t,
                y: -1.2 * t,
                z: -25.0,
                vx: 8.0,
                vy: -1.2,
                vz: 0.1 * t.cos(),
            }),
            MavMessage::SCALED_IMU(SCALED_IMU_DATA {
                time_boot_ms: t_ms,
                xacc: (30.0 * t.sin()) as i16,
                yacc: (20.0 * t.cos()) as i16,
                zacc: -1000,
                xgyro: 3,
                ygyro: -2,
                zgyro: 1,
                xmag: 200,
                ymag: -100,
                zmag: 400,
                temperature: 4000,
            }),
            MavMessage::SERVO_OUTPUT_RAW(SERVO_OUTPUT_RAW_DATA {
                time_usec: t_ms.wrapping_mul(1000),
                servo1_raw: 1500 + (tick % 50) as u16,
                servo2_raw: 1510,
                servo3_raw: 1490,
                servo4_raw: 1505,
                ..Default::default()
            }),
        ];
        if tick.is_multiple_of(2) {
            msgs.push(MavMessage::GPS_RAW_INT(GPS_RAW_INT_DATA {
                time_usec: T0_US + tick * 100_000,
                lat: 404_433_000 + (tick as i32) * 7,
                lon: -799_436_000 + (tick as i32) * 5,
                alt: 300_000,
                eph: 80,
                epv: 120,
                vel: 810,
                cog: 35_000,
                fix_type: GpsFixType::GPS_FIX_TYPE_3D_FIX,
                satellites_visible: 14,
                ..Default::default()
            }));
        }
        if tick.is_multiple_of(5) {
            msgs.push(MavMessage::VFR_HUD(VFR_HUD_DATA {
                airspeed: 8.3,
                groundspeed: 8.1,
                alt: 325.0,
                climb: 0.1 * t.sin(),
                heading: 350,
                throttle: 47,
            }));
        }
        if tick % 5 == 1 {
            msgs.push(MavMessage::SYS_STATUS(SYS_STATUS_DATA {
                load: 300,
                voltage_battery: 22_800 - (tick / 10) as u16,
                current_battery: 1050 + (tick % 30) as i16,
                battery_remaining: 80,
                ..Default::default()
            }));
        }
        if tick % 10 == 3 {
            msgs.push(MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                custom_mode: 10,
                mavtype: MavType::MAV_TYPE_QUADROTOR,
                autopilot: MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
                base_mode: MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
                    | MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED,
                system_status: MavState::MAV_STATE_ACTIVE,
                mavlink_version: 3,
            }));
        }
        if tick % 10 == 7 {
            let mut voltages = [u16::MAX; 10];
            voltages[..6].copy_from_slice(&[3800, 3801, 3799, 3802, 3800, 3798]);
            msgs.push(MavMessage::BATTERY_STATUS(BATTERY_STATUS_DATA {
                current_consumed: (tick * 3) as i32,
                energy_consumed: -1,
                temperature: 3100,
                voltages,
                current_battery: 1050,
                battery_remaining: 80,
                ..Default::default()
            }));
        }
        for (i, msg) in msgs.into_iter().enumerate() {
            if out.len() == n {
                break;
            }
            let header = MavHeader {
                system_id: 1,
                component_id: 1,
                sequence: seq,
            };
            seq = seq.wrapping_add(1);
            out.push((T0_US + tick * 100_000 + i as u64 * 400, header, msg));
        }
        tick += 1;
    }
    out
}

/// One encoded frame.
pub fn frame(header: MavHeader, msg: &MavMessage, version: MavlinkVersion) -> Vec<u8> {
    let mut b = Vec::new();
    mavlink::write_versioned_msg(&mut b, version, header, msg).expect("encode");
    b
}

/// Records as a tlog.
pub fn tlog(recs: &[Rec], version: MavlinkVersion) -> Vec<u8> {
    let mut b = Vec::new();
    for (t, h, m) in recs {
        dronewatt::source::logs::tlog::write_record(&mut b, *t, *h, m, version);
    }
    b
}

/// Records as a raw stream (frames back to back), and where each frame starts.
pub fn stream(recs: &[Rec], version: MavlinkVersion) -> (Vec<u8>, Vec<usize>) {
    let mut b = Vec::new();
    let mut starts = Vec::new();
    for (_, h, m) in recs {
        starts.push(b.len());
        mavlink::write_versioned_msg(&mut b, version, *h, m).expect("encode");
    }
    (b, starts)
}

/// A MAVLink 2 frame with a message id this dialect does not know (a valid layout).
pub fn unknown_v2(sequence: u8) -> Vec<u8> {
    let payload = [1u8, 2, 3, 4, 5];
    let mut b = vec![0xFD, payload.len() as u8, 0, 0, sequence, 1, 1];
    b.extend_from_slice(&60_001u32.to_le_bytes()[..3]);
    b.extend_from_slice(&payload);
    let crc = dronewatt::source::frame::crc16(&b[1..], 0);
    b.extend_from_slice(&crc.to_le_bytes());
    b
}

/// Sign a MAVLink 2 frame by hand: set the signed flag, recompute the CRC (it covers the
/// flags) and append a 13-byte signature (link id, 6-byte timestamp, 6-byte signature;
/// the decoder does not verify signatures, it must only frame them right).
pub fn sign_v2(frame: &[u8], msg: &MavMessage) -> Vec<u8> {
    use mavlink::Message;
    let mut b = frame.to_vec();
    b[2] |= 0x01;
    let crc_at = 10 + b[1] as usize;
    let crc =
        dronewatt::source::frame::crc16(&b[1..crc_at], MavMessage::extra_crc(msg.message_id()));
    b[crc_at..crc_at + 2].copy_from_slice(&crc.to_le_bytes());
    b.extend_from_slice(&[7, 1, 2, 3, 4, 5, 6, 0xFD, 0xFE, 9, 10, 11, 12]);
    b
}

/// The project's Python with pymavlink (`scripts/setup-python.sh`).
pub fn python() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(".venv-py/bin/python")
}

/// The pymavlink peer script.
pub fn peer() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/peers/mav_peer.py")
}

/// Run the pymavlink peer to completion; its stdout (one JSON object) parsed.
pub fn run_peer(args: &[&str]) -> serde_json::Value {
    let out = std::process::Command::new(python())
        .arg(peer())
        .args(args)
        .output()
        .expect("run the pymavlink peer");
    assert!(
        out.status.success(),
        "peer {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("peer prints one JSON object")
}

/// A free local port (bound then released: good enough for tests).
pub fn free_udp_port() -> u16 {
    std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// A free local TCP port.
pub fn free_tcp_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}
