//! Recorded MAVLink: the formats dronewatt reads, each writer beside its reader.
//!
//! | module | format |
//! |---|---|
//! | [`tlog`] | `.tlog` (QGroundControl, MAVProxy): frames behind 8-byte µs stamps |
//! | [`raw`] | raw MAVLink byte streams, time from the messages |
//! | [`dataflash`], [`dataflash_writer`] | ArduPilot's DataFlash `.bin`, read; a MAVLink flight written as one |
//! | [`ulog`], [`ulog_writer`] | PX4's ULog `.ulg`, read; a MAVLink flight written as one |
//! | [`dataset`] | the M100 data set's CSV as the MAVLink an autopilot would send |

pub mod dataflash;
mod dataflash_records;
pub mod dataflash_writer;
pub mod dataset;
pub mod raw;
mod synth;
pub mod tlog;
pub mod ulog;
mod ulog_formats;
pub mod ulog_writer;

use anyhow::Context;

use crate::report::status::IngestStats;
use crate::source::TimedMessage;

/// Read a DataFlash `.bin` or ULog `.ulg` (by its name) whole into the MAVLink a tlog
/// gives. Errors name the file and what is wrong.
pub fn decode_autopilot_log(
    path: &std::path::Path,
    stats: &IngestStats,
) -> anyhow::Result<Vec<TimedMessage>> {
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    let name = path.display();
    if ulog::is_ulog(path) {
        let (msgs, fault) = ulog::read_ulog(&bytes, stats).with_context(|| format!("{name}"))?;
        if let Some(e) = fault {
            let secs = msgs.last().map_or(0.0, |m| m.t_s);
            tracing::warn!(
                "{name}: a corrupt or truncated PX4 ULog: {} messages ({secs:.1} s of log time) read up to the fault, the rest of the file skipped: {e}",
                msgs.len()
            );
        }
        Ok(msgs)
    } else {
        dataflash::decode_dataflash(&bytes, stats).with_context(|| format!("{name}"))
    }
}
