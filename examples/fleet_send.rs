//! A light recorded-fleet sender for the load benchmark (`scripts/fleet-load.sh` with
//! `SENDER=1`): the frames of several `.tlog`s, each to its own UDP address, at their
//! recorded pace (real time), from one thread, so that the traffic of thousands of vehicles
//! costs the machine little beside the monitor measured (a simulator per link computes
//! its whole fleet's flight first, and shares the cores).
//!
//! ```text
//! cargo run --example fleet_send -- TLOG=127.0.0.1:PORT [TLOG=HOST:PORT …]
//! ```
//!
//! Each log's first stamp is its start; a frame is sent when its stamp, from that start, is
//! due on the wall clock (up to [`EARLY`] early, rather than a sleep per datagram). Prints
//! `sending` once every log is read, and at the end (the longest log over) the frames sent.

use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

/// How early a frame may go rather than sleeping for it.
const EARLY: Duration = Duration::from_micros(300);

/// One log, and where its frames go.
struct Link {
    data: Vec<u8>,
    pos: usize,
    to: SocketAddr,
    first_us: u64,
    name: String,
}

impl Link {
    /// The next record: its stamp (µs) and its frame's byte range; None at the end (or at
    /// bytes that are no MAVLink frame: said, and the log ends there).
    fn peek(&self) -> Option<(u64, std::ops::Range<usize>)> {
        let d = &self.data;
        let p = self.pos;
        let stamp: [u8; 8] = d.get(p..p + 8)?.try_into().ok()?;
        let f = p + 8;
        let (magic, len) = (*d.get(f)?, usize::from(*d.get(f + 1)?));
        let size = match magic {
            0xFD => 12 + len + if d.get(f + 2)? & 1 == 1 { 13 } else { 0 },
            0xFE => 8 + len,
            _ => {
                eprintln!(
                    "{}: no MAVLink frame at byte {f}: the log ends here",
                    self.name
                );
                return None;
            }
        };
        (f + size <= d.len()).then(|| (u64::from_be_bytes(stamp), f..f + size))
    }
}

fn main() -> Result<(), String> {
    let mut links = Vec::new();
    for arg in std::env::args().skip(1) {
        let (path, addr) = arg
            .split_once('=')
            .ok_or_else(|| format!("{arg}: expected TLOG=HOST:PORT"))?;
        let data = std::fs::read(path).map_err(|e| format!("{path}: {e}"))?;
        let to = addr
            .parse()
            .map_err(|e| format!("{addr}: not a HOST:PORT ({e})"))?;
        let mut l = Link {
            data,
            pos: 0,
            to,
            first_us: 0,
            name: path.to_string(),
        };
        l.first_us = l.peek().map_or(0, |(t, _)| t);
        links.push(l);
    }
    if links.is_empty() {
        return Err("usage: fleet_send TLOG=HOST:PORT [TLOG=HOST:PORT …]".into());
    }
    let sock = UdpSocket::bind("127.0.0.1:0").map_err(|e| format!("bind: {e}"))?;
    eprintln!("sending {} logs", links.len());
    let start = Instant::now();
    let mut sent = 0u64;
    loop {
        // The link whose next frame is due first.
        let next = links
            .iter()
            .enumerate()
            .filter_map(|(i, l)| l.peek().map(|(t, r)| (t.saturating_sub(l.first_us), i, r)))
            .min_by_key(|(due, ..)| *due);
        let Some((due_us, i, range)) = next else {
            break;
        };
        let due = start + Duration::from_micros(due_us);
        let now = Instant::now();
        if due > now + EARLY {
            std::thread::sleep(due - now);
        }
        let l = &mut links[i];
        // A refused datagram (nothing listening yet) is the receiver's loss, as on a radio.
        let _ = sock.send_to(&l.data[range.clone()], l.to);
        l.pos = range.end;
        sent += 1;
    }
    eprintln!(
        "sent {sent} frames in {:.1} s",
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
