//! Frames rust-mavlink refuses that still say something worth keeping.

use mavlink::{MavlinkVersion, Message};

use crate::MavMessage;

/// HEARTBEAT's `type` byte (payload offset 4, after `custom_mode`).
const HEARTBEAT_TYPE_AT: usize = 4;

/// A HEARTBEAT whose only fault is a `type` (MAV_TYPE) this dialect does not define (a
/// newer MAVLink's, or a private one): decoded with the type `MAV_TYPE_GENERIC`, which
/// the vehicle class reads as `other`, and the number said once in a warning. Dropping it
/// would hide the vehicle's kind and leave it taken for a multirotor.
pub(super) fn unknown_type_heartbeat(
    version: MavlinkVersion,
    id: u32,
    payload: &[u8],
) -> Option<MavMessage> {
    static SAID: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);
    let t = *payload.get(HEARTBEAT_TYPE_AT).filter(|_| id == 0)?;
    let mut p = payload.to_vec();
    p[HEARTBEAT_TYPE_AT] = 0;
    let msg = MavMessage::parse(version, id, &p).ok()?;
    if !SAID.swap(true, std::sync::atomic::Ordering::Relaxed) {
        tracing::warn!("HEARTBEAT with MAV_TYPE {t}, which MAVLink's common set does not define: vehicle class other (read as MAV_TYPE_GENERIC)");
    }
    Some(msg)
}
