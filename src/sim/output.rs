//! Where a simulated flight goes: `.tlog` bytes (MAVLink 2 frames behind 8-byte µs
//! timestamps, [`crate::source::logs::tlog`]'s format) or a UDP stream paced like a live vehicle.

use std::io::Write;
use std::path::Path;

use anyhow::Context;
use mavlink::MavlinkVersion;

use super::{SimFlight, SimRecord};
use crate::source::Speed;

impl SimFlight {
    /// The flight as `.tlog` bytes.
    pub fn to_tlog(&self) -> Vec<u8> {
        let mut buf = Vec::with_capacity(self.records.len() * 48);
        for r in &self.records {
            crate::source::logs::tlog::write_record(
                &mut buf,
                r.t_us,
                r.header,
                &r.msg,
                MavlinkVersion::V2,
            );
        }
        buf
    }
}

/// Write `flight` as a `.tlog` at `path`; returns the bytes written. Errors name the file.
pub fn write_tlog(path: &Path, flight: &SimFlight) -> anyhow::Result<usize> {
    let bytes = flight.to_tlog();
    let mut f = std::fs::File::create(path)
        .with_context(|| format!("{}: cannot create the tlog", path.display()))?;
    f.write_all(&bytes)
        .with_context(|| format!("{}: cannot write the tlog", path.display()))?;
    Ok(bytes.len())
}

/// Write `flight`'s ground truth (10 Hz) as CSV at `path`: `t_s,phase,power_w,voltage_v,
/// ground_speed_mps,north_m,east_m,height_m,vtol`, the phase as `{:?}` (`Leg(2)`), the VTOL
/// state as the JSON lines say it (`transition_to_fw`). Errors name the file.
pub fn write_truth(path: &Path, flight: &SimFlight) -> anyhow::Result<()> {
    let mut out =
        String::from("t_s,phase,power_w,voltage_v,ground_speed_mps,north_m,east_m,height_m,vtol\n");
    for s in &flight.truth {
        out.push_str(&format!(
            "{:.2},{:?},{:.3},{:.3},{:.3},{:.2},{:.2},{:.2},{}\n",
            s.t_s,
            s.phase,
            s.power_w,
            s.voltage_v,
            s.ground_speed_mps,
            s.north_m,
            s.east_m,
            s.height_m,
            s.vtol.as_str()
        ));
    }
    std::fs::write(path, out)
        .with_context(|| format!("{}: cannot write the truth CSV", path.display()))
}

/// Write `flight` as an ArduPilot DataFlash `.bin` at `path` ([`crate::source::logs::dataflash_writer`]);
/// returns the bytes written. Errors name the file.
pub fn write_dataflash(path: &Path, flight: &SimFlight) -> anyhow::Result<usize> {
    let bytes = crate::source::logs::dataflash_writer::from_mavlink(&stamped(flight));
    std::fs::write(path, &bytes)
        .with_context(|| format!("{}: cannot write the DataFlash log", path.display()))?;
    Ok(bytes.len())
}

/// Write `flight` as a PX4 ULog `.ulg` at `path` ([`crate::source::logs::ulog_writer`]); returns the bytes
/// written. Errors name the file.
pub fn write_ulog(path: &Path, flight: &SimFlight) -> anyhow::Result<usize> {
    let bytes = crate::source::logs::ulog_writer::from_mavlink(&stamped(flight));
    std::fs::write(path, &bytes)
        .with_context(|| format!("{}: cannot write the ULog", path.display()))?;
    Ok(bytes.len())
}

/// The flight's messages with their µs stamps, as the log writers take them.
fn stamped(flight: &SimFlight) -> Vec<(u64, &crate::MavMessage)> {
    flight.records.iter().map(|r| (r.t_us, &r.msg)).collect()
}

/// Send `records` as MAVLink 2 frames, one datagram each, to `addr` (`HOST:PORT`), paced
/// by `speed` on the records' timestamps. Returns the number of frames sent.
pub async fn stream_udp(records: &[SimRecord], addr: &str, speed: Speed) -> anyhow::Result<u64> {
    let target = tokio::net::lookup_host(addr)
        .await
        .with_context(|| format!("--udp {addr}: cannot resolve (expected HOST:PORT)"))?
        .next()
        .with_context(|| format!("--udp {addr}: no address"))?;
    let bind = if target.is_ipv4() {
        "0.0.0.0:0"
    } else {
        "[::]:0"
    };
    let sock = tokio::net::UdpSocket::bind(bind)
        .await
        .context("cannot open a UDP socket")?;
    let start = tokio::time::Instant::now();
    let t0 = records.first().map(|r| r.t_us).unwrap_or(0);
    let mut sent = 0;
    let mut frame = Vec::with_capacity(300);
    for r in records {
        if let Speed::Factor(f) = speed {
            let due = start + std::time::Duration::from_secs_f64((r.t_us - t0) as f64 / 1e6 / f);
            tokio::time::sleep_until(due).await;
        }
        frame.clear();
        mavlink::write_versioned_msg(&mut frame, MavlinkVersion::V2, r.header, &r.msg)
            .context("cannot encode a MAVLink frame")?;
        match sock.send_to(&frame, target).await {
            Ok(_) => sent += 1,
            // Nobody listening yet (ICMP port unreachable): keep flying, as a drone would.
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => {}
            Err(e) => return Err(e).with_context(|| format!("--udp {addr}: send failed")),
        }
    }
    Ok(sent)
}
