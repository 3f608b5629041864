//! The `dronewatt` binary end to end: replay, monitor, errors, Ctrl-C.

mod ingest_common;

use std::io::Read;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use ingest_common::*;
use mavlink::MavlinkVersion::V2;

fn dronewatt() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_dronewatt"));
    c.env("RUST_LOG", "warn");
    c
}

fn json_lines(stdout: &[u8]) -> Vec<serde_json::Value> {
    String::from_utf8_lossy(stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("not JSON ({e}): {l}")))
        .collect()
}

/// A tlog of `n` records with one flipped CRC, one unknown-id record and one zero stamp.
fn damaged_tlog(n: usize) -> Vec<u8> {
    let mut recs = flight(n);
    recs[n / 2].0 = 0;
    let mut bytes = tlog(&recs[..10], V2);
    let crc_hi = bytes.len() - 1;
    bytes[crc_hi] ^= 0x33; // record 9's CRC
    bytes.extend((T0_US + 950_000).to_be_bytes());
    bytes.extend(unknown_v2(recs[8].1.sequence)); // repeats 8's: record 10 then follows a gap
    bytes.extend(tlog(&recs[10..], V2));
    bytes
}

#[test]
fn replay_max_speed_ends_with_the_exact_summary_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("flight.tlog");
    std::fs::write(&path, damaged_tlog(400)).unwrap();
    let out = dronewatt().args(["replay", path.to_str().unwrap(), "--speed", "max", "--json", "-"]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let lines = json_lines(&out.stdout);
    let summary = lines.last().expect("a summary line");
    assert_eq!(summary["type"], "summary");
    assert_eq!(summary["frames_ok"], 399);
    assert_eq!(summary["frames_bad"], 1);
    assert_eq!(summary["unknown"], 1);
    // The bad record is a sequence gap; the zero stamp a clock jump.
    assert_eq!(summary["gaps"], 2);
    assert_eq!(summary["clock_jumps"], 1);
    assert_eq!(summary["missed_reports"], 0);
    // Until the features stage lands the telemetry stage builds no windows (0); after, one
    // per 100 ms of flight. Either way every window makes one window and one estimate line.
    let windows = summary["windows"].as_u64().expect("windows is a number");
    let count = |t: &str| lines.iter().filter(|l| l["type"] == t).count() as u64;
    assert_eq!(count("window"), windows);
    assert_eq!(count("estimate"), windows);
}

#[test]
fn replay_writes_json_to_a_file_and_reads_raw_streams() {
    let dir = tempfile::tempdir().unwrap();
    let raw = dir.path().join("capture.bin");
    let (bytes, _) = stream(&flight(250), V2);
    std::fs::write(&raw, bytes).unwrap();
    let json = dir.path().join("out.jsonl");
    let out = dronewatt()
        .args(["replay", raw.to_str().unwrap(), "--speed", "max", "-q", "--json", json.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let lines = json_lines(&std::fs::read(&json).unwrap());
    let s = lines.last().unwrap();
    assert_eq!((s["type"].as_str(), s["frames_ok"].as_u64(), s["frames_bad"].as_u64()), (Some("summary"), Some(250), Some(0)));
}

#[test]
fn replay_at_a_speed_factor_honours_the_timestamps() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("three_seconds.tlog");
    let recs = flight(190); // ~3.1 s of flight
    let span_s = (recs.last().unwrap().0 - recs[0].0) as f64 * 1e-6;
    std::fs::write(&path, tlog(&recs, V2)).unwrap();
    let start = Instant::now();
    let out = dronewatt().args(["replay", path.to_str().unwrap(), "--speed", "4", "-q", "--json", "-"]).output().unwrap();
    let took = start.elapsed().as_secs_f64();
    assert!(out.status.success());
    // ×4 → about span/4; loose bounds (process start, a busy CI machine).
    assert!(took >= span_s / 4.0 * 0.9, "took {took:.2} s for {span_s:.2} s at ×4");
    assert!(took < span_s / 4.0 + 8.0, "took {took:.2} s for {span_s:.2} s at ×4");
    assert_eq!(json_lines(&out.stdout).last().unwrap()["frames_ok"], 190);
}

/// Runs `args`; asserts a non-zero exit and exactly one line on stderr containing `want`.
fn fails_with_one_line(args: &[&str], want: &[&str]) {
    let out = dronewatt().args(args).output().unwrap();
    assert!(!out.status.success(), "{args:?} should fail");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.trim_end().lines().count(), 1, "one line, got: {err}");
    for w in want {
        assert!(err.contains(w), "'{w}' not in: {err}");
    }
    assert!(out.stdout.is_empty(), "nothing on stdout: {}", String::from_utf8_lossy(&out.stdout));
}

#[test]
fn a_missing_file_is_one_clear_error_line() {
    fails_with_one_line(&["replay", "/nonexistent/flight.tlog", "--json", "-"], &["/nonexistent/flight.tlog"]);
}

#[test]
fn a_bad_address_is_one_clear_error_line() {
    for bad in ["udpin:14550", "bogus:1.2.3.4:5", "tcpout:localhost:port"] {
        fails_with_one_line(&["monitor", bad, "--json", "-"], &[bad, "udpin:HOST:PORT", "serial:DEVICE:BAUD"]);
    }
}

#[test]
fn ctrl_c_on_a_live_link_still_writes_the_summary() {
    let port = free_udp_port();
    let mut child = dronewatt()
        .args(["monitor", &format!("udpin:127.0.0.1:{port}"), "--json", "-"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(800));
    let sock = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    for (_, h, m) in flight(25) {
        sock.send_to(&frame(h, &m, V2), ("127.0.0.1", port)).unwrap();
    }
    std::thread::sleep(Duration::from_millis(500));
    let ok = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(ok.success());
    let deadline = Instant::now() + Duration::from_secs(10);
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(Instant::now() < deadline, "no exit after Ctrl-C");
        std::thread::sleep(Duration::from_millis(50));
    };
    let mut stdout = Vec::new();
    child.stdout.take().unwrap().read_to_end(&mut stdout).unwrap();
    assert!(status.success(), "exit {status:?}");
    let s = json_lines(&stdout).pop().unwrap();
    assert_eq!((s["type"].as_str(), s["frames_ok"].as_u64()), (Some("summary"), Some(25)));
}
