//! The redundant-link merge at a fast sender's rate, over real UDP: a recorded ArduCopter
//! log (`dronewatt simulate`'s tlog, ~44 frames/s at 1×) sent by a light pymavlink sender
//! (`tests/peers/merge_send.py`: the log's own bytes and sequence numbers) at 20× (~900
//! frames/s, a sequence wrap every 0.29 s) and at 100× (~4,400 frames/s, a wrap every
//! 58 ms) to `dronewatt monitor udpin:P1 udpin:P2`:
//!
//! - on one of the two links (the case that lost 31 % of its frames as "duplicates" when the
//!   merge keyed on the sequence alone within 1 s), and
//! - on both links, each losing 30 % independently.
//!
//! The frames decoded must be exactly the union of what arrived, with no false duplicate.
//! What arrived is counted, not assumed: the sender's ledger says what it sent on each link,
//! and the kernel's own drop counter of each of the monitor's sockets (`/proc/net/udp`, the
//! `drops` column) says what never reached dronewatt. With no datagram dropped (the usual
//! case on loopback) the assertion is exact: merged frames = frames sent on at least one
//! link, duplicates = frames sent on both. Should the kernel drop some (a loaded machine at
//! 100×), each link must still account for every datagram it was handed (frames = sent −
//! dropped), and the merge's counts are held to the bounds the drops leave.

use std::path::{Path, PathBuf};

use serde_json::Value;

use crate::harness::{dronewatt, json_lines, Monitor, RunExt};
use crate::link_common;

/// A simulated ArduCopter flight (~124 s, ~5,500 frames, one sender) in `dir`.
fn recorded_log(dir: &Path) -> PathBuf {
    let log = dir.join("copter.tlog");
    dronewatt()
        .args([
            "simulate",
            "--leg-m",
            "200",
            "--hover-s",
            "5",
            "--seed",
            "3",
        ])
        .arg("--out")
        .arg(&log)
        .ok();
    log
}

/// The kernel's count of datagrams it dropped for the socket bound to 127.0.0.1:`port`
/// (its receive queue full), from `/proc/net/udp`.
fn kernel_drops(port: u16) -> u64 {
    let table = std::fs::read_to_string("/proc/net/udp").expect("read /proc/net/udp");
    let local = format!("0100007F:{port:04X}");
    table
        .lines()
        .skip(1)
        .map(|l| l.split_whitespace().collect::<Vec<_>>())
        .find(|f| f.get(1) == Some(&local.as_str()))
        .and_then(|f| f.last().and_then(|d| d.parse().ok()))
        .unwrap_or_else(|| panic!("no socket on {local} in /proc/net/udp"))
}

/// What one run showed.
struct Merge {
    /// The sender's ledger.
    peer: Value,
    /// dronewatt's summary line.
    summary: Value,
    /// Datagrams the kernel dropped on each link's socket.
    drops: [u64; 2],
    stderr: String,
}

/// Monitor two links and send the log at `speed` with `loss` ("L1,L2") on them.
fn merge(speed: &str, loss: &str) -> Merge {
    let dir = tempfile::tempdir().unwrap();
    let log = recorded_log(dir.path());
    let json = dir.path().join("out.jsonl");
    let ports = [link_common::free_udp_port(), link_common::free_udp_port()];
    let mut dw = Monitor::spawn(
        dronewatt()
            .arg("monitor")
            .args(ports.map(|p| format!("udpin:127.0.0.1:{p}")))
            .arg("-q")
            .arg("--json")
            .arg(&json),
    );
    for p in ports {
        dw.wait_listening(p, false);
    }
    let out =
        std::process::Command::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.venv-py/bin/python"))
            .arg(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/tests/peers/merge_send.py"
            ))
            .arg("--log")
            .arg(&log)
            .args(["--ports", &format!("{},{}", ports[0], ports[1])])
            .args(["--speed", speed, "--loss", loss, "--seed", "7"])
            .output()
            .expect("run .venv-py/bin/python (make setup creates it)");
    assert!(
        out.status.success(),
        "sender failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let peer: Value = serde_json::from_slice(&out.stdout).expect("the sender's ledger");
    // Let the monitor drain its sockets, then read the kernel's drop counters while they
    // are still open.
    std::thread::sleep(std::time::Duration::from_millis(1500));
    let drops = ports.map(kernel_drops);
    let (status, stderr) = dw.stop();
    assert!(status.success(), "dronewatt exited with {status}: {stderr}");
    let summary = json_lines(&json)
        .into_iter()
        .find(|l| l["type"] == "summary")
        .unwrap_or_else(|| panic!("no summary line: {stderr}"));
    Merge {
        peer,
        summary,
        drops,
        stderr,
    }
}

/// Check one run: every datagram accounted for, the merged stream exactly the union of
/// what arrived, no false duplicate.
fn check(m: &Merge, min_fps: f64) {
    let ctx = format!(
        "ledger: {}\nkernel drops: {:?}\nsummary: {}\ndronewatt: {}",
        m.peer, m.drops, m.summary, m.stderr
    );
    let n = |v: &Value, k: &str| v[k].as_u64().unwrap_or_else(|| panic!("{k}: {ctx}"));
    assert_eq!(n(&m.peer, "repeats"), 0, "copies inside the log: {ctx}");
    assert!(
        m.peer["fps"].as_f64().unwrap_or(0.0) >= min_fps,
        "the sender fell behind its pace: {ctx}"
    );
    let (union, both) = (n(&m.peer, "union"), n(&m.peer, "both"));
    let links = m.summary["links"]
        .as_array()
        .unwrap_or_else(|| panic!("no links: {ctx}"));
    assert_eq!(links.len(), 2, "{ctx}");
    // Each link decoded every datagram the kernel handed it, one frame each.
    let mut arrived = 0;
    for (i, l) in links.iter().enumerate() {
        let sent = m.peer["sent"][i].as_u64().unwrap();
        assert_eq!(n(l, "frames"), sent - m.drops[i], "link {i}: {ctx}");
        arrived += n(l, "frames");
    }
    assert_eq!(n(&m.summary, "frames_bad"), 0, "{ctx}");
    let (ok, dups) = (n(&m.summary, "frames_ok"), n(&m.summary, "duplicates"));
    // Every frame that arrived is handed on or counted a copy, never both, never neither.
    assert_eq!(ok + dups, arrived, "{ctx}");
    let dropped = m.drops[0] + m.drops[1];
    if dropped == 0 {
        // Exact: the union of what arrived, each once; copies only of frames sent on both.
        assert_eq!(
            ok, union,
            "merged frames ≠ the union of what arrived: {ctx}"
        );
        assert_eq!(dups, both, "false duplicates: {ctx}");
    } else {
        eprintln!("the kernel dropped {dropped} datagrams: bounds instead of equalities\n{ctx}");
        assert!(ok <= union && ok + dropped >= union, "{ctx}");
        assert!(dups <= both && dups + dropped >= both, "{ctx}");
    }
}

#[test]
fn a_fast_log_on_one_of_two_links_loses_no_frame_at_20x() {
    let m = merge("20", "0,1");
    assert_eq!(m.peer["sent"][1], 0);
    check(&m, 700.0);
    assert_eq!(m.summary["duplicates"], 0, "{}", m.summary);
}

#[test]
fn a_fast_log_on_one_of_two_links_loses_no_frame_at_100x() {
    let m = merge("100", "0,1");
    check(&m, 3_000.0);
    assert_eq!(m.summary["duplicates"], 0, "{}", m.summary);
}

#[test]
fn a_fast_log_on_two_lossy_links_merges_to_the_union_at_20x() {
    let m = merge("20", "0.3,0.3");
    check(&m, 700.0);
}

#[test]
fn a_fast_log_on_two_lossy_links_merges_to_the_union_at_100x() {
    let m = merge("100", "0.3,0.3");
    check(&m, 3_000.0);
}
