//! A flat-out replay batches its windows through the models (issue 47, build 4): up to 256
//! windows a batch, the LSTM ensemble's members on two threads from 32. The `--json` it
//! writes must be byte for byte what the unbatched path writes, every window run alone
//! (`DRONEWATT_MAX_BATCH=1`, the test's knob), the summary's wall-clock fields aside:
//!
//! - a simulated ArduCopter flight (the performance chapter's benchmark flight, shorter);
//! - a two-vehicle fleet on one link (batches that mix vehicles, each adapting on its own).
//!
//! Lines are compared vehicle by vehicle (two vehicles' lines interleave as their chains
//! run, batched or not). Each run's own count of batches (the inference stage's debug line) shows the two paths
//! really differ: one batch a window unbatched, far fewer batched.

use crate::harness::{output, replay_max, without_wall_clock, RunExt};
use serde_json::Value;
use std::path::Path;

/// `simulate` ARGS `--out LOG`.
fn simulate(log: &Path, args: &[&str]) {
    let mut a = vec!["simulate", "--out", log.to_str().expect("utf-8 path")];
    a.extend_from_slice(args);
    let o = output(&a);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// `replay LOG --speed max -q --json -` with batches of at most `max` windows (`None`: the
/// default): the JSON lines without the summary's wall-clock fields, and the run's
/// (batches, windows) as the inference stage counted them.
fn replay(log: &Path, max: Option<usize>) -> (String, (u64, u64)) {
    let mut c = replay_max(log, &["--data-dir", "off"]);
    c.env(
        "RUST_LOG",
        "dronewatt=info,dronewatt::pipeline::inference=debug,warn",
    );
    if let Some(m) = max {
        c.env("DRONEWATT_MAX_BATCH", m.to_string());
    }
    let out = c.ok();
    let stderr = String::from_utf8_lossy(&out.stderr);
    let counts = stderr
        .lines()
        .find(|l| l.contains("the run's batches"))
        .map(|l| (field(l, "batches="), field(l, "windows=")))
        .unwrap_or_else(|| panic!("no batch count in stderr: {stderr}"));
    (
        without_wall_clock(&String::from_utf8_lossy(&out.stdout)),
        counts,
    )
}

/// The number after `key` in a tracing line.
fn field(line: &str, key: &str) -> u64 {
    let at = line.find(key).unwrap_or_else(|| panic!("{key} in {line}")) + key.len();
    line[at..]
        .split(|c: char| !c.is_ascii_digit())
        .next()
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("a number after {key} in {line}"))
}

/// The lines vehicle by vehicle (by their `system_id`; lines without one, such as the
/// summary, under ""), each vehicle's in the order written: how two vehicles' lines
/// interleave is their chains' timing, batched or not, and no part of the output's promise.
fn per_vehicle(text: &str) -> String {
    let mut by: std::collections::BTreeMap<String, Vec<&str>> = Default::default();
    for l in text.lines() {
        let v: Value = serde_json::from_str(l).expect("a JSON line");
        by.entry(v["system_id"].to_string()).or_default().push(l);
    }
    by.into_values().flatten().collect::<Vec<_>>().join("\n")
}

/// Batched and unbatched replays of `log`: the same bytes, and really batched.
fn same_batched_and_alone(log: &Path, min_windows: u64) {
    let (batched, (nb, wb)) = replay(log, None);
    let (alone, (na, wa)) = replay(log, Some(1));
    let (batched, alone) = (per_vehicle(&batched), per_vehicle(&alone));
    assert_eq!(wb, wa, "the same windows either way");
    assert!(wb >= min_windows, "{wb} windows");
    assert_eq!(na, wa, "unbatched: one batch a window");
    assert!(nb * 10 <= wb, "batched: {nb} batches for {wb} windows");
    let lstm = batched.lines().filter(|l| l.contains("\"lstm\":")).count();
    assert!(lstm as u64 >= wb, "{lstm} lines with the LSTM's estimate");
    if batched != alone {
        let (k, (b, a)) = batched
            .lines()
            .zip(alone.lines())
            .enumerate()
            .find(|(_, (b, a))| b != a)
            .unwrap_or((0, ("(lengths differ)", "")));
        panic!("line {k} differs:\nbatched {b}\nalone   {a}");
    }
}

#[test]
fn a_flat_out_replay_batched_writes_the_bytes_of_one_window_at_a_time() {
    let dir = tempfile::tempdir().expect("tempdir");
    let log = dir.path().join("ac.tlog");
    // The benchmark flight's kind (docs/src/performance.md), about 80 s.
    simulate(
        &log,
        &[
            "--autopilot",
            "ardupilot",
            "--leg-m",
            "150",
            "--hover-s",
            "10",
        ],
    );
    same_batched_and_alone(&log, 500);
}

#[test]
fn a_fleet_replay_batched_writes_the_bytes_of_one_window_at_a_time() {
    let dir = tempfile::tempdir().expect("tempdir");
    let log = dir.path().join("fleet.tlog");
    simulate(
        &log,
        &[
            "--vehicles",
            "2",
            "--seed",
            "5",
            "--leg-m",
            "60",
            "--hover-s",
            "3",
        ],
    );
    same_batched_and_alone(&log, 300);
}
