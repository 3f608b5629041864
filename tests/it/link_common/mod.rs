//! Shared by the link-fault and link-security tests: run `dronewatt monitor` on a free
//! loopback port with `--json`, fly `tests/peers/vehicle.py` (pymavlink) at it with a plan of
//! phases, stop dronewatt with SIGTERM (its own shutdown path) and read what the operator
//! saw.
#![allow(dead_code)]

use crate::harness::{dronewatt, Monitor};
use std::process::Command;

use serde_json::Value;

/// What one run showed: dronewatt's JSON lines and the peer's own report.
pub struct Run {
    /// Every `estimate` line that carries model output (a real estimate, not the
    /// "nothing heard" report a silent link's alert rides on).
    pub estimates: Vec<Value>,
    /// Every `alert` line.
    pub alerts: Vec<Value>,
    /// The `summary` line.
    pub summary: Value,
    /// Every `estimate` line, real or not.
    pub estimate_lines: usize,
    /// Every `estimate` line itself (those with no model output too: a vehicle no model
    /// applies to).
    pub all_estimates: Vec<Value>,
    /// What `vehicle.py` printed.
    pub peer: Value,
    /// dronewatt's standard error.
    pub stderr: String,
}

impl Run {
    /// The `t` of every real estimate.
    pub fn times(&self) -> Vec<f64> {
        self.estimates
            .iter()
            .map(|e| e["t"].as_f64().unwrap())
            .collect()
    }
    /// A summary counter.
    pub fn count(&self, key: &str) -> u64 {
        self.summary[key]
            .as_u64()
            .unwrap_or_else(|| panic!("no {key} in the summary {}", self.summary))
    }
    /// The run made as many estimates as `seconds` of sending in `segments` make
    /// ([`expected_estimates`]).
    #[track_caller]
    pub fn assert_estimates(&self, seconds: f64, segments: usize) {
        assert!(
            expected_estimates(seconds, segments).contains(&self.estimates.len()),
            "{} estimates",
            self.estimates.len()
        );
    }
    /// dronewatt read every frame the peer sent.
    #[track_caller]
    pub fn assert_every_frame_read(&self) {
        assert_eq!(
            self.count("frames_ok"),
            self.peer["frames"].as_u64().unwrap(),
            "{}",
            self.summary
        );
    }
    /// Gaps between consecutive real estimates longer than `s`.
    pub fn holes_over(&self, s: f64) -> Vec<(f64, f64)> {
        self.times()
            .windows(2)
            .filter(|w| w[1] - w[0] > s)
            .map(|w| (w[0], w[1]))
            .collect()
    }
}

pub fn free_udp_port() -> u16 {
    std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

pub fn free_tcp_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Run the pymavlink peer `tests/peers/SCRIPT` with `args` to its end while `dw` (a
/// `dronewatt monitor` already listening, stderr piped) watches, then stop dronewatt with
/// SIGTERM (its own orderly shutdown). Both must succeed; returns the peer's JSON report and
/// dronewatt's stderr.
pub fn peer_then_stop(dw: Monitor, script: &str, args: &[&str]) -> (Value, String) {
    let peer = Command::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.venv-py/bin/python"))
        .arg(format!(
            "{}/tests/peers/{script}",
            env!("CARGO_MANIFEST_DIR")
        ))
        .args(args)
        .output()
        .expect("run .venv-py/bin/python (make setup creates it)");
    let (status, stderr) = dw.stop();
    assert!(
        peer.status.success(),
        "peer failed: {}",
        String::from_utf8_lossy(&peer.stderr)
    );
    assert!(status.success(), "dronewatt exited with {status}: {stderr}");
    let out = String::from_utf8_lossy(&peer.stdout);
    let peer: Value = serde_json::from_str(out.trim())
        .unwrap_or_else(|e| panic!("peer said {out:?}: {e}\ndronewatt: {stderr}"));
    (peer, stderr)
}

/// Monitor `udpin:` (or `tcpin:` with `tcp`) with `config`, fly `plan` with the extra peer
/// arguments, and collect the run.
pub fn fly(config: &str, tcp: bool, plan: &str, peer_args: &[&str]) -> Run {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("dw.toml");
    std::fs::write(&cfg, config).unwrap();
    let json = dir.path().join("out.jsonl");
    let port = if tcp {
        free_tcp_port()
    } else {
        free_udp_port()
    };
    let address = format!("{}:127.0.0.1:{port}", if tcp { "tcpin" } else { "udpin" });
    let dw = Monitor::listening(
        dronewatt()
            .args(["monitor", &address, "-q", "--config"])
            .arg(&cfg)
            .arg("--json")
            .arg(&json),
        port,
        tcp,
    );
    let to = format!("{}:127.0.0.1:{port}", if tcp { "tcp" } else { "udpout" });
    let args: Vec<&str> = ["--to", &to, "--plan", plan]
        .into_iter()
        .chain(peer_args.iter().copied())
        .collect();
    let (peer, stderr) = peer_then_stop(dw, "vehicle.py", &args);
    let text = std::fs::read_to_string(&json).unwrap();
    let (mut estimates, mut alerts, mut summary, mut estimate_lines) =
        (Vec::new(), Vec::new(), Value::Null, 0);
    let mut all_estimates = Vec::new();
    for line in text.lines() {
        let v: Value =
            serde_json::from_str(line).unwrap_or_else(|e| panic!("bad JSON line {line:?}: {e}"));
        match v["type"].as_str() {
            Some("estimate") => {
                estimate_lines += 1;
                if v["models"].as_object().is_some_and(|m| !m.is_empty()) {
                    estimates.push(v.clone());
                }
                all_estimates.push(v);
            }
            Some("alert") => alerts.push(v),
            Some("summary") => summary = v,
            _ => {}
        }
    }
    assert!(summary.is_object(), "no summary line; dronewatt: {stderr}");
    Run {
        estimates,
        alerts,
        summary,
        estimate_lines,
        all_estimates,
        peer,
        stderr,
    }
}

/// What every run must show: every report written and none missed, real estimates in
/// strictly increasing time, and every measured power on the flown profile (500 ± 40 W at
/// 22.2 V, rounded to the centiamp): nothing from another vehicle, nothing made up.
pub fn check_consistent(r: &Run) {
    assert_eq!(r.count("missed_reports"), 0, "{}", r.summary);
    assert_eq!(
        r.count("reports") as usize,
        r.estimate_lines,
        "every report is one estimate line"
    );
    let t = r.times();
    assert!(
        t.windows(2).all(|w| w[1] > w[0]),
        "estimate times must strictly increase"
    );
    for e in &r.estimates {
        if let Some(w) = e["measured_w"].as_f64() {
            assert!(
                (455.0..=545.0).contains(&w),
                "measured {w} W is not on the flown profile: {e}"
            );
        }
    }
}

/// Real estimates expected from `seconds` of telemetry in `segments` unbroken stretches at
/// 10 Hz with a 10-sample window: one per sample once the window is full.
pub fn expected_estimates(seconds: f64, segments: usize) -> std::ops::RangeInclusive<usize> {
    let full = (seconds * 10.0).round() as usize;
    let lo = full.saturating_sub(segments * 10 + 5 * segments);
    lo..=full + 2 * segments
}

/// The names of the models in an `estimate` line's `models` object.
pub fn models(e: &Value) -> Vec<String> {
    e["models"]
        .as_object()
        .map(|m| m.keys().cloned().collect())
        .unwrap_or_default()
}

/// What a flight of [`fly_small_pack_to_low`] showed.
pub struct LowFlight {
    /// dronewatt's JSON lines.
    pub lines: Vec<Value>,
    /// The peer's own report (its `statustexts` are what the ground station was told).
    pub peer: Value,
    /// dronewatt's stderr.
    pub stderr: String,
    /// When the measured voltage first read under `BATT_LOW_VOLT` (10.5 V), s.
    pub crossed_at: f64,
}

/// The first-flight tests' vehicle: pymavlink (`tests/peers/vehicle.py --pack`) flies a small
/// 3S pack (4 Wh: 360 mAh, 11.40 V at rest, 40 % of a LiPo) at 50 W ± 5 W along `plan`, so that
/// its loaded voltage crosses `BATT_LOW_VOLT` (10.5 V) about 12 s after take-off; it answers
/// the parameter reads (BATT_LOW_VOLT 10.5, BATT_CRT_VOLT 10.0, BATT_CAPACITY 360) and its
/// target is `dw`, a monitor listening on `port` and writing `--json` to `json`.
pub fn fly_small_pack_to_low(
    dw: Monitor,
    port: u16,
    plan: &str,
    json: &std::path::Path,
) -> LowFlight {
    let pack = r#"{"cells": 3, "wh": 4, "rest_v": 11.40, "r0": 0.12, "r1": 0.08, "tau_s": 10}"#;
    let to = format!("udpout:127.0.0.1:{port}");
    let (peer, stderr) = peer_then_stop(
        dw,
        "vehicle.py",
        &[
            "--to",
            &to,
            "--plan",
            plan,
            "--pack",
            pack,
            "--power-w",
            "50",
            "--power-swing-w",
            "5",
            "--params",
            r#"{"BATT_LOW_VOLT": 10.5, "BATT_CRT_VOLT": 10.0, "BATT_CAPACITY": 360}"#,
        ],
    );
    let lines = crate::harness::json_lines(json);
    let crossed_at = lines
        .iter()
        .filter(|l| l["type"] == "estimate")
        .find(|e| e["battery_v"].as_f64().is_some_and(|v| v < 10.5))
        .and_then(|e| e["t"].as_f64())
        .unwrap_or_else(|| panic!("the pack never sagged under 10.5 V: {stderr}"));
    LowFlight {
        lines,
        peer,
        stderr,
        crossed_at,
    }
}
