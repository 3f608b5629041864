//! `learn` on two copies of one log refuses, naming both files (a copy would be scored
//! against itself: the 0.0 % error of issue 45).

use crate::harness::{dronewatt, root, RunExt};

#[test]
fn learn_refuses_two_copies_of_one_log_naming_both() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (
        dir.path().join("monday.tlog"),
        dir.path().join("tuesday.tlog"),
    );
    std::fs::copy(root().join("replay/demo.tlog"), &a).unwrap();
    std::fs::copy(root().join("replay/demo.tlog"), &b).unwrap();
    let out = dronewatt()
        .arg("learn")
        .arg(&a)
        .arg(&b)
        .arg("--out")
        .arg(dir.path().join("out"))
        .out();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("monday.tlog") && err.contains("tuesday.tlog") && err.contains("same log"),
        "{err}"
    );
    assert!(!dir.path().join("out").exists(), "nothing written");
}
