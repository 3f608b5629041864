//! Raw MAVLink byte streams (a serial capture, `socat` output, a `.bin` dump): frames with
//! no timestamps. Time comes from the messages themselves: `time_boot_ms`, through a
//! [`crate::source::frame::timed::Clock`] so a reboot or a wrap (49.7 days) is one counted clock jump
//! instead of a replay that waits forever or rushes (see [`crate::source::frame::timed::TimeBase`]).

use crate::MavMessage;

/// The autopilot's boot time in ms carried by `msg`, for the messages an autopilot streams
/// (attitude, position, IMU, pressure, RC, targets, named values, system time). `None`
/// for messages without one (HEARTBEAT, SYS_STATUS, BATTERY_STATUS, VFR_HUD …), which
/// then take the latest known time.
pub fn boot_time_ms(msg: &MavMessage) -> Option<u32> {
    use MavMessage as M;
    Some(match msg {
        M::ATTITUDE(d) => d.time_boot_ms,
        M::ATTITUDE_QUATERNION(d) => d.time_boot_ms,
        M::ATTITUDE_TARGET(d) => d.time_boot_ms,
        M::GLOBAL_POSITION_INT(d) => d.time_boot_ms,
        M::LOCAL_POSITION_NED(d) => d.time_boot_ms,
        M::POSITION_TARGET_GLOBAL_INT(d) => d.time_boot_ms,
        M::POSITION_TARGET_LOCAL_NED(d) => d.time_boot_ms,
        M::SCALED_IMU(d) => d.time_boot_ms,
        M::SCALED_IMU2(d) => d.time_boot_ms,
        M::SCALED_IMU3(d) => d.time_boot_ms,
        M::SCALED_PRESSURE(d) => d.time_boot_ms,
        M::SCALED_PRESSURE2(d) => d.time_boot_ms,
        M::SCALED_PRESSURE3(d) => d.time_boot_ms,
        M::RC_CHANNELS(d) => d.time_boot_ms,
        M::RC_CHANNELS_RAW(d) => d.time_boot_ms,
        M::RC_CHANNELS_SCALED(d) => d.time_boot_ms,
        M::SYSTEM_TIME(d) => d.time_boot_ms,
        M::NAMED_VALUE_FLOAT(d) => d.time_boot_ms,
        M::NAMED_VALUE_INT(d) => d.time_boot_ms,
        M::DISTANCE_SENSOR(d) => d.time_boot_ms,
        M::DEBUG(d) => d.time_boot_ms,
        _ => return None,
    })
}

/// Decode a whole in-memory raw stream flat out: every good message in order, timed by
/// `time_boot_ms` (seconds since the first one), with everything skipped counted.
pub fn decode_raw(
    bytes: &[u8],
    stats: &crate::report::status::IngestStats,
) -> Vec<crate::source::TimedMessage> {
    let mut r = crate::source::frame::timed::TimedReader::raw();
    r.push(bytes);
    r.finish();
    let mut out = Vec::new();
    while let Some(m) = r.next_message(stats) {
        out.push(m);
    }
    out
}
