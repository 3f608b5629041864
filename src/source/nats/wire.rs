//! One frame on the stream: what the gateway decoded and when it arrived, in 17 bytes
//! before the message's MAVLink 2 payload.
//!
//! ```text
//!  0  version (1)        4..8   message id (u32 LE)
//!  1  system id          8..16  arrival at the gateway, unix seconds (f64 LE)
//!  2  component id       16     network
//!  3  sequence           17..   the MAVLink 2 payload
//! ```
//!
//! A frame that is too short, of another version
//! or whose payload does not parse as its message is an error, never a panic.

use anyhow::{bail, Result};
use mavlink::Message;

use crate::MavMessage;

/// The layout's version byte.
pub const VERSION: u8 = 1;
const HEAD: usize = 17;

/// A frame off the stream.
#[derive(Debug, Clone)]
pub struct Frame {
    pub network: u8,
    pub header: mavlink::MavHeader,
    pub msg: MavMessage,
    /// When the gateway received it, unix seconds.
    pub arrived_unix_s: f64,
}

/// Encode one message heard at `arrived_unix_s` on `network`.
pub fn encode(
    network: u8,
    header: &mavlink::MavHeader,
    msg: &MavMessage,
    arrived_unix_s: f64,
) -> Vec<u8> {
    let mut payload = [0u8; 255];
    let n = msg.ser(mavlink::MavlinkVersion::V2, &mut payload).min(255);
    let mut out = Vec::with_capacity(HEAD + n);
    out.push(VERSION);
    out.push(u8::try_from(header.system_id).unwrap_or(u8::MAX));
    out.push(header.component_id);
    out.push(header.sequence);
    out.extend_from_slice(&msg.message_id().to_le_bytes());
    out.extend_from_slice(&arrived_unix_s.to_le_bytes());
    out.push(network);
    out.extend_from_slice(&payload[..n]);
    out
}

/// Decode one frame of the stream.
pub fn decode(b: &[u8]) -> Result<Frame> {
    if b.len() < HEAD {
        bail!(
            "frame of {} bytes: shorter than its {HEAD}-byte head",
            b.len()
        );
    }
    if b[0] != VERSION {
        bail!("frame layout version {}, not {VERSION}", b[0]);
    }
    let id = u32::from_le_bytes([b[4], b[5], b[6], b[7]]);
    let mut t = [0u8; 8];
    t.copy_from_slice(&b[8..16]);
    let arrived_unix_s = f64::from_le_bytes(t);
    let msg = MavMessage::parse(mavlink::MavlinkVersion::V2, id, &b[HEAD..])
        .map_err(|e| anyhow::anyhow!("message {id}: {e}"))?;
    Ok(Frame {
        network: b[16],
        header: mavlink::MavHeader {
            system_id: b[1].into(),
            component_id: b[2],
            sequence: b[3],
        },
        msg,
        arrived_unix_s,
    })
}

/// Unix seconds now.
pub fn unix_now_s() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dialect::SYS_STATUS_DATA;

    #[test]
    fn a_frame_comes_back_as_it_went_and_bad_ones_are_errors() {
        let msg = MavMessage::SYS_STATUS(SYS_STATUS_DATA {
            voltage_battery: 22_200,
            current_battery: 2_250,
            battery_remaining: 80,
            ..Default::default()
        });
        let h = mavlink::MavHeader {
            system_id: 7,
            component_id: 1,
            sequence: 200,
        };
        let b = encode(3, &h, &msg, 1.7e9 + 0.25);
        let f = decode(&b).unwrap();
        assert_eq!(
            (f.network, f.header.system_id, f.header.sequence),
            (3, 7, 200)
        );
        assert_eq!(f.arrived_unix_s, 1.7e9 + 0.25);
        assert_eq!(f.msg, msg);
        assert!(decode(&b[..5]).is_err());
        let mut other = b.clone();
        other[0] = 9;
        assert!(decode(&other)
            .unwrap_err()
            .to_string()
            .contains("version 9"));
    }
}
