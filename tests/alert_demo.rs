//! The demo `make run` plays: replay/demo.tlog with config/demo.toml raises its
//! remaining-energy warning once, at the first estimate whose remaining energy is under
//! 40 % of the demo's 40 Wh pack — late in the flight, in the hover over home.

use std::process::Command;

#[test]
fn demo_warns_once_when_the_pack_crosses_40_percent() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    // The demo's config without the dashboard, so the test needs no free port 8787.
    let demo = std::fs::read_to_string(root.join("config/demo.toml")).unwrap();
    assert!(demo.contains("capacity_wh = 40") && demo.contains("below_pct = 40"), "the demo config changed: update this test");
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("demo.toml");
    std::fs::write(&cfg, demo.replace("enabled = true", "enabled = false")).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_dronewatt"))
        .args(["replay", "--speed", "max", "-q", "--json", "-", "--config"])
        .arg(&cfg)
        .arg(root.join("replay/demo.tlog"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let lines: Vec<serde_json::Value> =
        String::from_utf8_lossy(&out.stdout).lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    let alerts: Vec<&serde_json::Value> = lines.iter().filter(|l| l["type"] == "alert").collect();
    assert_eq!(alerts.len(), 1, "{alerts:?}");
    assert_eq!((alerts[0]["rule"].as_str(), alerts[0]["severity"].as_str()), (Some("energy_low"), Some("warning")));
    let t = alerts[0]["t"].as_f64().unwrap();
    let est: Vec<(f64, f64)> = lines
        .iter()
        .filter(|l| l["type"] == "estimate")
        .map(|l| (l["t"].as_f64().unwrap(), l["remaining_wh"].as_f64().unwrap()))
        .collect();
    let first_below = est.iter().find(|(_, wh)| *wh < 16.0).expect("the pack never went under 40 %");
    assert_eq!(first_below.0, t, "the warning must come with the first estimate under 40 %");
    let end = est.last().unwrap().0;
    assert!(t > 0.75 * end && t < end - 20.0, "late in the flight but before landing: {t} of {end} s");
}
