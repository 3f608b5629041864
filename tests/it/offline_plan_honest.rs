//! `plan` says what it did: the plot's reserve line is on the pack as given (its margin is
//! the text's), and members the vehicle's profile says do not transfer are left out, said.

use crate::harness::{dronewatt, root, RunExt};

fn plan_json(args: &[&str]) -> serde_json::Value {
    let out = dronewatt()
        .current_dir("/")
        .arg("plan")
        .arg(root().join("replay/demo.plan"))
        .args(args)
        .args(["--json", "-"])
        .ok();
    serde_json::from_slice(&out.stdout).unwrap()
}

/// With `--battery-v` a part-charged pack: the usable energy the plot draws is what the pack
/// holds less the reserve, so its margin equals the text's (not a full pack's).
#[test]
fn the_plot_draws_the_reserve_on_the_pack_as_given() {
    let full = plan_json(&[]);
    let part = plan_json(&["--battery-v", "24.2"]);
    let f = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap_or(f64::NAN);
    let e50 = part["forecast"]["energy_p50_wh"].as_f64().unwrap();
    // the plot's line minus the P50 is the text's margin
    assert!(
        (f(&part, "usable_wh") - e50 - f(&part, "margin_p50_wh")).abs() < 1e-9,
        "{part}"
    );
    let full_usable = f(&full, "capacity_wh") * (1.0 - f(&full, "reserve_pct") / 100.0);
    assert!((f(&full, "usable_wh") - full_usable).abs() < 1e-9);
    assert!(
        f(&part, "usable_wh") < full_usable - 5.0,
        "a part-charged pack's line is below a full one's: {} vs {full_usable}",
        f(&part, "usable_wh")
    );
    // and the PNG is written with it
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("p.png");
    dronewatt()
        .current_dir("/")
        .arg("plan")
        .arg(root().join("replay/demo.plan"))
        .args(["--battery-v", "24.2", "--plot"])
        .arg(&png)
        .ok();
    assert!(std::fs::metadata(&png).is_ok_and(|m| m.len() > 10_000));
}

/// The X500's profile says Tseng's regressions do not transfer to it: its forecast leaves
/// them out and says so.
#[test]
fn plan_leaves_out_the_members_the_profile_says_do_not_transfer() {
    let out = dronewatt()
        .current_dir("/")
        .arg("plan")
        .arg(root().join("replay/demo.plan"))
        .args(["--vehicle", "x500", "--json", "-"])
        .ok();
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let model = v["forecast"]["model"].as_str().unwrap();
    assert!(!model.contains("tseng"), "{model}");
    assert!(
        model.contains("dorling") && model.contains("stolaroff"),
        "{model}"
    );
    let from = v["forecast_from"].as_str().unwrap();
    assert!(from.contains("do not transfer: tseng_solo"), "{from}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("tseng_solo left out"), "{err}");
}
