//! `dronewatt check-config`: the shipped example configs pass and say what they set up; a
//! bad one fails with one line naming the file, the key and why, and a non-zero exit.

use crate::harness::{dronewatt, RunExt};

fn check(path: &std::path::Path) -> std::process::Output {
    dronewatt().arg("check-config").arg(path).out()
}

#[test]
fn shipped_configs_pass() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    for (file, rules) in [("config/dronewatt.toml", 10), ("config/demo.toml", 5)] {
        let out = check(&root.join(file));
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{file}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(
            text.contains(&format!("alerts: {rules} rule(s)")),
            "{file}:\n{text}"
        );
        assert!(
            text.contains("sinks.mavlink: ") && text.contains("component 191"),
            "{file}:\n{text}"
        );
    }
    let text =
        String::from_utf8_lossy(&check(&root.join("config/dronewatt.toml")).stdout).to_string();
    assert!(
        text.contains("mission_margin [critical]: mission-reserve margin < 0 Wh, clears ≥ 3 Wh"),
        "{text}"
    );
}

#[test]
fn a_bad_config_names_file_key_and_reason() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("mine.toml");
    std::fs::write(
        &p,
        "[[alerts]]\nname = \"low\"\nkind = \"remaining_below\"\nbelow_wh = 30\nclear_wh = 25\n",
    )
    .unwrap();
    let out = check(&p);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("mine.toml")
            && err.contains("alerts[0] (low).clear_wh = 25")
            && err.contains("must be ≥"),
        "{err}"
    );
}
