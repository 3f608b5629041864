//! The `dronewatt` binary end to end: replay, monitor, errors, Ctrl-C.

use crate::harness::{json_lines, json_lines_of, quiet, replay_json, RunExt};
use crate::mavlink_common;

use std::io::Read;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use mavlink::MavlinkVersion::V2;
use mavlink_common::*;

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

/// `dronewatt replay PATH --speed max --json -` with warnings only on stderr, not yet run.
fn replay_max_speed(path: &std::path::Path) -> Command {
    let mut c = quiet();
    c.args([
        "replay",
        path.to_str().unwrap(),
        "--speed",
        "max",
        "--json",
        "-",
    ]);
    c
}

#[test]
fn replay_max_speed_ends_with_the_exact_summary_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("flight.tlog");
    std::fs::write(&path, damaged_tlog(400)).unwrap();
    let out = replay_max_speed(&path).ok();
    let lines = json_lines_of(&out.stdout);
    let summary = lines.last().expect("a summary line");
    assert_eq!(summary["type"], "summary");
    assert_eq!(summary["frames_ok"], 399);
    assert_eq!(summary["frames_bad"], 1);
    assert_eq!(summary["unknown"], 1);
    // The bad record is a sequence gap; the zero stamp a clock jump.
    assert_eq!(summary["gaps"], 2);
    assert_eq!(summary["clock_jumps"], 1);
    assert_eq!(summary["missed_reports"], 0);
    // One window per 100 ms of flight once the first is full: never zero, which would make
    // the line counts below hold hollowly (0 == 0).
    let windows = summary["windows"].as_u64().expect("windows is a number");
    assert!(
        windows > 0,
        "no windows from {} frames",
        summary["frames_ok"]
    );
    let count = |t: &str| lines.iter().filter(|l| l["type"] == t).count() as u64;
    assert_eq!(count("window"), windows);
    assert_eq!(count("estimate"), windows);
    // Flat out, the latency is the queueing; an estimate is counted once at most (those the
    // end of the log flushes, made by no arrival, not at all).
    let counted = summary["latency"]["count"]
        .as_u64()
        .expect("latency counted");
    assert!(counted > 0 && counted <= windows, "{summary}");
}

#[test]
fn replay_writes_json_to_a_file_and_reads_raw_streams() {
    let dir = tempfile::tempdir().unwrap();
    let raw = dir.path().join("capture.bin");
    let (bytes, _) = stream(&flight(250), V2);
    std::fs::write(&raw, bytes).unwrap();
    let json = dir.path().join("out.jsonl");
    let _out = quiet()
        .args([
            "replay",
            raw.to_str().unwrap(),
            "--speed",
            "max",
            "-q",
            "--json",
            json.to_str().unwrap(),
        ])
        .ok();
    let lines = json_lines(&json);
    let s = lines.last().unwrap();
    assert_eq!(
        (
            s["type"].as_str(),
            s["frames_ok"].as_u64(),
            s["frames_bad"].as_u64()
        ),
        (Some("summary"), Some(250), Some(0))
    );
}

#[test]
fn replay_at_a_speed_factor_honours_the_timestamps() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("twelve_seconds.tlog");
    let recs = flight(760); // ~12 s of flight
    let span_s = (recs.last().unwrap().0 - recs[0].0) as f64 * 1e-6;
    assert!(span_s > 11.0, "{span_s} s");
    std::fs::write(&path, tlog(&recs, V2)).unwrap();
    let start = Instant::now();
    let out = quiet()
        .args([
            "replay",
            path.to_str().unwrap(),
            "--speed",
            "4",
            "-q",
            "--json",
            "-",
        ])
        .out();
    let took = start.elapsed().as_secs_f64();
    assert!(out.status.success());
    // ×4 → about span/4 (3 s). Not faster than that, and clearly faster than ×2 (6 s), so a
    // replay that ignored the factor and ran at ×1 (12 s) fails; the slack above span/4 is
    // for process start on a busy machine.
    assert!(
        took >= span_s / 4.0 * 0.9,
        "took {took:.2} s for {span_s:.2} s at ×4"
    );
    assert!(
        took < span_s / 2.0,
        "took {took:.2} s for {span_s:.2} s at ×4: slower than ×2"
    );
    assert_eq!(json_lines_of(&out.stdout).last().unwrap()["frames_ok"], 760);
}

/// Runs `args`; asserts a non-zero exit and exactly one line on stderr containing `want`.
fn fails_with_one_line(args: &[&str], want: &[&str]) {
    let out = quiet().args(args).out();
    assert!(!out.status.success(), "{args:?} should fail");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.trim_end().lines().count(), 1, "one line, got: {err}");
    for w in want {
        assert!(err.contains(w), "'{w}' not in: {err}");
    }
    assert!(
        out.stdout.is_empty(),
        "nothing on stdout: {}",
        String::from_utf8_lossy(&out.stdout)
    );
}

#[test]
fn a_missing_file_is_one_clear_error_line() {
    fails_with_one_line(
        &["replay", "/nonexistent/flight.tlog", "--json", "-"],
        &["/nonexistent/flight.tlog"],
    );
}

#[test]
fn a_bad_address_is_one_clear_error_line() {
    for bad in ["udpin:14550", "bogus:1.2.3.4:5", "tcpout:localhost:port"] {
        fails_with_one_line(
            &["monitor", bad, "--json", "-"],
            &[bad, "udpin:HOST:PORT", "serial:DEVICE:BAUD"],
        );
    }
}

#[test]
fn ctrl_c_on_a_live_link_still_writes_the_summary() {
    let port = free_udp_port();
    let mut child = quiet()
        .env("RUST_LOG", "dronewatt=info")
        .args(["monitor", &format!("udpin:127.0.0.1:{port}"), "--json", "-"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Send only once it listens (its log says so): a fixed sleep loses the frames when a
    // loaded machine starts it slowly. The rest of its log drains on a thread.
    let stderr = std::io::BufReader::new(child.stderr.take().unwrap());
    let (said, listening) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in std::io::BufRead::lines(stderr).map_while(Result::ok) {
            if line.contains("listening on") {
                let _ = said.send(());
            }
        }
    });
    listening
        .recv_timeout(Duration::from_secs(30))
        .expect("monitor never said it was listening");
    let sock = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    for (_, h, m) in flight(25) {
        sock.send_to(&frame(h, &m, V2), ("127.0.0.1", port))
            .unwrap();
    }
    std::thread::sleep(Duration::from_millis(500));
    let ok = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
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
    child
        .stdout
        .take()
        .unwrap()
        .read_to_end(&mut stdout)
        .unwrap();
    assert!(status.success(), "exit {status:?}");
    let s = json_lines_of(&stdout).pop().unwrap();
    assert_eq!(
        (s["type"].as_str(), s["frames_ok"].as_u64()),
        (Some("summary"), Some(25))
    );
}

/// 200 kB of deterministic noise (xorshift), no MAVLink in it.
fn noise(n: usize) -> Vec<u8> {
    let mut x = 0x9E37_79B9_7F4A_7C15u64;
    (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x as u8
        })
        .collect()
}

#[test]
fn a_file_with_no_mavlink_says_so_and_names_the_format_it_expected() {
    let dir = tempfile::tempdir().unwrap();
    for (name, expected) in [
        ("noise.tlog", "an 8-byte big-endian microsecond timestamp"),
        ("noise.bin", "a raw MAVLink byte stream"),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, noise(200_000)).unwrap();
        let out = replay_max_speed(&path).out();
        // The summary still written (the counters are the evidence), then a failure: nothing
        // was replayed…
        assert!(
            !out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(String::from_utf8_lossy(&out.stderr).contains("nothing was replayed"));
        let summary = json_lines_of(&out.stdout).pop().expect("a summary line");
        assert_eq!(summary["frames_ok"], 0);
        // …and one line that says what is wrong and what was expected.
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("no MAVLink in this file: 200000 bytes"),
            "{name}: {err}"
        );
        assert!(err.contains(expected), "{name}: '{expected}' not in: {err}");
        assert!(
            err.contains(path.to_str().unwrap()),
            "{name}: the path not in: {err}"
        );
    }
}

#[test]
fn a_config_with_several_errors_names_every_one() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.toml");
    std::fs::write(
        &path,
        "[telemetry]\nrate_hz = 200.0\n[energy]\ncapacity_wh = -5.0\nreserve_pct = 120.0\n[sinks.web]\nbind = \"nowhere\"\n",
    )
    .unwrap();
    let out = quiet().args(["check-config", path.to_str().unwrap()]).out();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(path.to_str().unwrap()) && err.contains("4 errors"),
        "{err}"
    );
    for key in [
        "telemetry.rate_hz = 200",
        "energy.capacity_wh = -5",
        "energy.reserve_pct = 120",
        "sinks.web.bind = 'nowhere'",
    ] {
        assert!(err.contains(key), "'{key}' not in: {err}");
    }
}

#[test]
fn a_missing_data_set_names_the_path_and_the_environment_variable() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nowhere/flights.csv.gz");
    let out = crate::harness::lab()
        .env("RUST_LOG", "warn")
        .env("DRONEWATT_DATA", &missing)
        .args(["eval", "--flight", "276"])
        .out();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(missing.to_str().unwrap()),
        "the path not in: {err}"
    );
    assert!(err.contains("DRONEWATT_DATA"), "the variable not in: {err}");
}

/// A data-set flight whose pack rests at 22.95 V before take-off (flight 253, a TB48D at
/// 3.83 V a cell): the start state is that resting voltage, well under full, said so;
/// the voltage is modelled and forecast, and the pack is 6 cells of LiHV.
#[test]
fn a_half_used_pack_replays_well_under_full_from_its_resting_voltage() {
    let data = dronewatt::default_data_path();
    if !data.exists() {
        eprintln!("skipped: no data set at {}", data.display());
        return;
    }
    let lines = replay_json(&data, &["--flight", "253"]);
    let flying: Vec<_> = lines
        .iter()
        .filter(|l| l["type"] == "estimate" && l["measured_w"].as_f64().is_some_and(|w| w > 300.0))
        .collect();
    let take_off = flying.first().expect("the flight flies");
    assert_eq!(
        take_off["remaining_source"], "resting voltage",
        "{take_off}"
    );
    assert!(
        take_off["battery_rest_v"]
            .as_f64()
            .is_some_and(|v| (v - 22.95).abs() < 0.05),
        "{take_off}"
    );
    assert!(
        take_off["soc_pct"].as_f64().is_some_and(|s| s < 45.0),
        "{take_off}"
    );
    assert!(
        take_off["remaining_wh"]
            .as_f64()
            .is_some_and(|wh| wh < 0.4 * 129.96),
        "not a full pack: {take_off}"
    );
    assert_eq!(
        (
            take_off["cell_count"].as_u64(),
            take_off["chemistry"].as_str()
        ),
        (Some(6), Some("lihv"))
    );
    // In flight: the modelled voltage follows the measured one, and a forecast low is given.
    let mid = flying[flying.len() / 2];
    let (v, m) = (
        mid["battery_v"].as_f64().unwrap(),
        mid["battery_v_model"].as_f64().unwrap(),
    );
    assert!((v - m).abs() < 0.5, "measured {v} V, modelled {m} V");
    // The lowest forecast for the rest of the flight is under the voltage now and near the
    // lowest the flight then measured (the smooth forecast's sag deepened by the transients
    // it lacks, battery::forecast::dip): 20.15 V forecast, 20.42 V measured at 1 Hz.
    let k = flying.len() / 2;
    let measured_low = flying[k..]
        .iter()
        .filter_map(|l| l["battery_v"].as_f64())
        .fold(f64::INFINITY, f64::min);
    assert!(
        mid["v_min_forecast_v"]
            .as_f64()
            .is_some_and(|lo| (lo - measured_low).abs() < 0.4 && lo < v),
        "measured lowest {measured_low} V: {mid}"
    );
}
