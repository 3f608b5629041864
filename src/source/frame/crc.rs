//! The MAVLink checksum and each message's `crc_extra`.

use std::sync::OnceLock;

use mavlink::Message;

use crate::MavMessage;

/// The MAVLink checksum (CRC-16/MCRF4XX, "X.25") over `data` then the message's
/// `crc_extra`. Public so tests and tools can build frames by hand.
#[inline]
pub fn crc16(data: &[u8], extra: u8) -> u16 {
    #[inline(always)]
    fn acc(crc: u16, b: u8) -> u16 {
        let mut t = b ^ (crc as u8);
        t ^= t << 4;
        let t = t as u16;
        (crc >> 8) ^ (t << 8) ^ (t << 3) ^ (t >> 4)
    }
    let mut crc = 0xFFFF;
    for &b in data {
        crc = acc(crc, b);
    }
    acc(crc, extra)
}

/// `crc_extra` of every message id below 65536 that the dialect knows (bit 8 set = known).
/// Built once: `MavMessage::extra_crc` answers 0 for an unknown id, which a known message
/// may also have, so knowing is asked of `default_message_from_id`.
fn id_table() -> &'static [u16] {
    static TABLE: OnceLock<Vec<u16>> = OnceLock::new();
    TABLE.get_or_init(|| {
        (0..=u16::MAX as u32)
            .map(|id| match MavMessage::default_message_from_id(id) {
                Some(_) => 0x100 | MavMessage::extra_crc(id) as u16,
                None => 0,
            })
            .collect()
    })
}

/// The `crc_extra` of `id`, or `None` when this dialect does not know the message.
#[inline]
pub(crate) fn crc_extra(id: u32) -> Option<u8> {
    match id_table().get(id as usize) {
        Some(&e) if e & 0x100 != 0 => Some(e as u8),
        Some(_) => None,
        None => MavMessage::default_message_from_id(id).map(|_| MavMessage::extra_crc(id)),
    }
}
