//! `dronewatt` does not load libtorch (issue 14, "start fast"): its executable names none
//! of libtorch's libraries, and a TorchScript model or training is handed to
//! `dronewatt-torch` with a message saying so when that binary is not there.

use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_dronewatt");

#[test]
fn the_executable_needs_no_libtorch() {
    let out = Command::new("ldd").arg(BIN).output().expect("run ldd");
    assert!(
        out.status.success(),
        "ldd failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let libs = String::from_utf8_lossy(&out.stdout);
    assert!(
        libs.contains("libc.so"),
        "ldd listed no libraries at all:\n{libs}"
    );
    for torch in ["libtorch", "libc10", "libgomp"] {
        assert!(!libs.contains(torch), "dronewatt links {torch}:\n{libs}");
    }
}

/// Without `dronewatt-torch` beside it, `dronewatt-lab train` fails with one clear line
/// naming what to build, and no panic.
#[test]
fn training_without_the_torch_binary_says_what_to_build() {
    let dir = tempfile::tempdir().expect("temp dir");
    let lone = dir.path().join("dronewatt-lab");
    std::fs::copy(crate::harness::bin("dronewatt-lab"), &lone).expect("copy the binary");
    let out = Command::new(&lone)
        .args(["train", "--epochs", "1"])
        .output()
        .expect("run dronewatt-lab train");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("training the LSTM needs libtorch") && err.contains("dronewatt-torch"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
}
