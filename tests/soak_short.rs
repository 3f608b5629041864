//! The soak's CI version: `scripts/soak.sh 0.75` (45 s of wall time at ×100, the demo
//! flight looped with a continuous clock) must pass its own checks — zero missed reports,
//! counters consistent, RSS without a gross leak (35 %: see below) — and its figures must
//! say so.
//! The long run (`scripts/soak.sh 30`) is the same script; its figures are in the README.

use std::process::Command;

#[test]
fn a_short_soak_keeps_memory_flat_and_loses_no_report() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(root.join("scripts/soak.sh"))
        .arg("0.75")
        .env("DRONEWATT", env!("CARGO_BIN_EXE_dronewatt"))
        .env("SOAK_OUT", dir.path())
        .env("SOAK_SAMPLE_S", "2")
        // 45 s cannot tell a leak from the bounded queues reaching their high-water mark
        // when the machine is busy (seen: +16 % with the whole suite running beside it,
        // +2 % alone): here only a gross leak fails; the 5 % rule is the long run's.
        .env("SOAK_MAX_GROWTH_PCT", "35")
        // ... and the queues may still be deepening at the end: judge from the plain warm-up.
        .env("SOAK_MIN_JUDGED_FRAC", "0")
        .output()
        .expect("run scripts/soak.sh");
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "soak failed: {said}");
    let f: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("soak.json")).unwrap())
            .unwrap();
    let n = |k: &str| f[k].as_f64().unwrap_or_else(|| panic!("no {k} in {f}"));
    assert_eq!(n("missed_reports"), 0.0, "{f}");
    assert!(n("rss_growth_pct") <= 35.0, "{f}");
    assert_eq!(n("estimate_lines"), n("reports"), "{f}");
    assert_eq!(n("reports"), n("windows"), "{f}");
    assert_eq!(
        (n("frames_bad"), n("junk_bytes"), n("clock_jumps")),
        (0.0, 0.0, 0.0),
        "{f}"
    );
    // Well over an hour of flight in 45 s even on a busy machine: the loop really ran fast.
    assert!(n("flight_s_replayed") > 1800.0, "{f}");
    // The queues' high-water mark is reported, and no queue is deeper than its bound.
    assert!((1.0..=1024.0).contains(&n("queue_peak")), "{f}");
    eprintln!("{said}");
}
