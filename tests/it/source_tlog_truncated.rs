//! A truncated `.tlog` (a download cut short, a card pulled mid-write) plays what it has,
//! says where it ends, and exits 0.

use crate::harness::{dronewatt, json_lines_of, root, RunExt};

/// The last log time (s) of the replay's estimate lines.
fn last_t(lines: &[serde_json::Value]) -> f64 {
    lines
        .iter()
        .filter_map(|l| l["t"].as_f64())
        .fold(0.0, f64::max)
}

#[test]
fn a_truncated_tlog_plays_what_it_has_and_says_where_it_ends() {
    let full = std::fs::read(root().join("replay/demo.tlog")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let cut = dir.path().join("cut.tlog");
    // 60 % of the file, a few bytes into a record
    std::fs::write(&cut, &full[..full.len() * 6 / 10]).unwrap();
    let run = |p: &std::path::Path| {
        dronewatt()
            .env("RUST_LOG", "warn")
            .args(["replay", "--speed", "max", "-q", "--json", "-"])
            .arg(p)
            .ok()
    };
    let out = run(&cut);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("truncated: the file ends inside a record"),
        "{err}"
    );
    assert!(err.contains("s of log time"), "{err}");
    // the whole file says nothing of the kind, and plays on past where the cut one ends
    let whole = run(&root().join("replay/demo.tlog"));
    assert!(!String::from_utf8_lossy(&whole.stderr).contains("truncated"));
    let (t_cut, t_full) = (
        last_t(&json_lines_of(&out.stdout)),
        last_t(&json_lines_of(&whole.stdout)),
    );
    assert!(
        t_cut > 0.3 * t_full && t_cut < 0.9 * t_full,
        "{t_cut} of {t_full}"
    );
}
