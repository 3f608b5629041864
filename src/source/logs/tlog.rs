//! `.tlog` files (QGroundControl / MAVProxy telemetry logs): each frame is preceded by an
//! 8-byte big-endian timestamp in microseconds since the Unix epoch.
//!
//! Reading goes through [`crate::source::frame::FrameDecoder`] in [`Tlog`](crate::source::frame::Framing::Tlog)
//! framing (corruption is resynchronised and counted there) and the stamps through a
//! [`crate::source::frame::timed::Clock`]: `t_s` is seconds since the *first record*, never decreasing,
//! and a zero, backwards or absurd stamp is a counted clock jump that leaves `t_s` where it
//! was, so it cannot poison replay pacing.

use mavlink::{MavHeader, MavlinkVersion};

use crate::MavMessage;

/// Append one message to `buf` as a tlog record: the µs timestamp, then the encoded frame.
pub fn write_record(
    buf: &mut Vec<u8>,
    t_us: u64,
    header: MavHeader,
    msg: &MavMessage,
    version: MavlinkVersion,
) {
    buf.extend_from_slice(&t_us.to_be_bytes());
    // Writing into a Vec cannot fail.
    let _ = mavlink::write_versioned_msg(buf, version, header, msg);
}

/// Decode a whole in-memory tlog flat out (no pacing): every good message in order, bad
/// frames, unknown ids and gaps counted in `stats`. `t_s` is seconds since the first
/// record's stamp (see the module docs for how a broken stamp is handled). Offline work
/// uses it to walk data-set flights through the live ingest path.
pub fn decode_tlog(
    bytes: &[u8],
    stats: &crate::report::status::IngestStats,
) -> Vec<crate::source::TimedMessage> {
    let mut r = crate::source::frame::timed::TimedReader::tlog();
    r.push(bytes);
    r.finish();
    // Typical records are 30–60 bytes.
    let mut out = Vec::with_capacity(bytes.len() / 40);
    while let Some(m) = r.next_message(stats) {
        out.push(m);
    }
    out
}
