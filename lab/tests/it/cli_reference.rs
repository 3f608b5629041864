//! The book's CLI reference is what clap defines: `dronewatt-lab cli-reference` prints
//! exactly the committed `docs/src/generated/cli.md`, and it lists the operator's commands
//! under `dronewatt` and the research ones under `dronewatt-lab` only.

use crate::harness::{lab, root, RunExt};

#[test]
fn the_committed_cli_reference_is_what_clap_defines() {
    let out = lab().arg("cli-reference").out();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let now = String::from_utf8(out.stdout).expect("UTF-8");
    let path = root().join("docs/src/generated/cli.md");
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        now == committed,
        "{} is stale: run `target/debug/dronewatt-lab cli-reference > docs/src/generated/cli.md`",
        path.display()
    );
    let (operator, research) = now.split_once("## `dronewatt-lab`").expect("both binaries");
    for c in [
        "monitor",
        "replay",
        "plan",
        "learn",
        "vehicles",
        "simulate",
        "check-config",
    ] {
        assert!(operator.contains(&format!("### `dronewatt {c}`")), "{c}");
    }
    for c in [
        "eval",
        "calibrate",
        "train",
        "sensitivity",
        "plan-eval",
        "battery-eval",
    ] {
        assert!(
            !operator.contains(&format!("### `dronewatt {c}`")),
            "{c} in the product"
        );
        assert!(
            research.contains(&format!("### `dronewatt-lab {c}`")),
            "{c}"
        );
    }
    assert!(operator.contains("`--speed <SPEED>`"), "{operator}");
}
