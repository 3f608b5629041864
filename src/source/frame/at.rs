//! One position of the input: the frame that starts there, if any (v1, v2, signed v2), with
//! its CRC and payload checked. The decoder's hot path.

use mavlink::{MavHeader, MavlinkVersion, Message};

use super::*;
use crate::MavMessage;

/// What the bytes at one position turned out to be. (`Good` is large: boxing its message
/// would allocate once a frame on the decoder's hot path, for a value that lives a moment.)
#[allow(clippy::large_enum_variant)]
pub(super) enum At {
    /// A frame of `len` bytes whose CRC checked and whose payload decoded.
    Good {
        len: usize,
        header: MavHeader,
        version: MavlinkVersion,
        msg: MavMessage,
    },
    /// A frame layout of `len` bytes with an unknown message id.
    Unknown { len: usize, header: MavHeader },
    /// A frame layout of `len` bytes with a bad CRC or a payload that did not decode.
    Bad { len: usize },
    /// Not a frame start (wrong start byte, impossible flags).
    NotFrame,
    /// Could be a frame, but the input ends first.
    NeedMore,
}

/// Decode the frame that starts at `b[0]`.
#[inline]
pub(super) fn decode_at(b: &[u8]) -> At {
    let (version, hdr, id, incompat) = match b.first() {
        Some(&STX_V1) => {
            if b.len() < V1_HEADER {
                return At::NeedMore;
            }
            (MavlinkVersion::V1, V1_HEADER, b[5] as u32, 0)
        }
        Some(&STX_V2) => {
            if b.len() < 3 {
                return At::NeedMore;
            }
            // Any incompatibility flag but signing means we cannot read the frame:
            // treat it as a false start byte.
            if b[2] & !IFLAG_SIGNED != 0 {
                return At::NotFrame;
            }
            if b.len() < V2_HEADER {
                return At::NeedMore;
            }
            (
                MavlinkVersion::V2,
                V2_HEADER,
                u32::from_le_bytes([b[7], b[8], b[9], 0]),
                b[2],
            )
        }
        _ => return At::NotFrame,
    };
    let payload_len = b[1] as usize;
    let sig = if incompat & IFLAG_SIGNED != 0 {
        SIGNATURE_LEN
    } else {
        0
    };
    let len = hdr + payload_len + 2 + sig;
    if b.len() < len {
        return At::NeedMore;
    }
    let (sequence, system_id, component_id) = match version {
        MavlinkVersion::V1 => (b[2], b[3], b[4]),
        MavlinkVersion::V2 => (b[4], b[5], b[6]),
    };
    let header = MavHeader {
        system_id: system_id as u32,
        component_id,
        sequence,
    };
    let Some(extra) = crc_extra(id) else {
        return At::Unknown { len, header };
    };
    let crc_at = hdr + payload_len;
    let sent = u16::from_le_bytes([b[crc_at], b[crc_at + 1]]);
    if crc16(&b[1..crc_at], extra) != sent {
        return At::Bad { len };
    }
    match MavMessage::parse(version, id, &b[hdr..crc_at]) {
        Ok(msg) => At::Good {
            len,
            header,
            version,
            msg,
        },
        Err(_) => match lenient::unknown_type_heartbeat(version, id, &b[hdr..crc_at]) {
            Some(msg) => At::Good {
                len,
                header,
                version,
                msg,
            },
            None => At::Bad { len },
        },
    }
}

/// The length of the frame starting at `b[0]` if it is one that checks out (CRC and
/// payload), else `None`. The fuzz properties use it to tell a frame that garbage happens
/// to hold from one the decoder missed.
pub fn good_frame_len(b: &[u8]) -> Option<usize> {
    match decode_at(b) {
        At::Good { len, .. } => Some(len),
        _ => None,
    }
}
