//! The demo `make run` plays: replay/demo.tlog (an M100 delivery flown from
//! replay/demo.plan on a part-used pack) with config/demo.toml raises its alerts mid-flight,
//! in the hold at the drop point, not at the start: `mission_margin_below` once, with the
//! margin under its level, and cleared once the vehicle heads home; the remaining energy's
//! `remaining_below` after it. The voltage forecast's `voltage_forecast_below` (at the
//! vehicle's BATT_LOW_VOLT) fires once, before the measured voltage first goes under that
//! threshold, and does not flap.

use crate::harness::replay_json;

#[test]
fn demo_raises_its_mission_and_pack_alerts_mid_flight() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    // The demo's config without the dashboard, so the test needs no free port 8787.
    let demo = std::fs::read_to_string(root.join("config/demo.toml")).unwrap();
    assert!(
        demo.contains("kind = \"mission_margin_below\"\nbelow_wh = 2.5\n")
            && demo.contains("below_pct = 20"),
        "the demo config changed: update this test"
    );
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("demo.toml");
    let vehicles = format!(
        "calibrated_profile = \"{}/",
        root.join("config/vehicles").display()
    );
    std::fs::write(
        &cfg,
        demo.replace("enabled = true", "enabled = false")
            .replace("calibrated_profile = \"vehicles/", &vehicles),
    )
    .unwrap();
    let lines = replay_json(
        &root.join("replay/demo.tlog"),
        &["--config", cfg.to_str().unwrap()],
    );
    let est: Vec<&serde_json::Value> = lines.iter().filter(|l| l["type"] == "estimate").collect();
    let end = est.last().unwrap()["t"].as_f64().unwrap();
    let events = |rule: &str, state: &str| -> Vec<f64> {
        lines
            .iter()
            .filter(|l| l["type"] == "alert" && l["rule"] == rule && l["state"] == state)
            .map(|l| l["t"].as_f64().unwrap())
            .collect()
    };
    // The pack starts from its resting voltage, part-used.
    let flying = est
        .iter()
        .find(|e| e["t"].as_f64().unwrap() > 20.0)
        .unwrap();
    assert_eq!(flying["remaining_source"], "resting voltage", "{flying}");
    let soc = flying["soc_pct"].as_f64().unwrap();
    assert!((50.0..65.0).contains(&soc), "a part-used pack: {soc} %");
    let mut early: Vec<f64> = est
        .iter()
        .filter(|e| (10.0..60.0).contains(&e["t"].as_f64().unwrap()))
        .filter_map(|e| e["mission_margin_wh"].as_f64())
        .collect();
    early.sort_by(f64::total_cmp);
    assert!(
        early[early.len() / 2] > 2.0,
        "a margin over the alert's level at the start (median {})",
        early[early.len() / 2]
    );

    let raised = events("mission_margin", "raised");
    let cleared = events("mission_margin", "cleared");
    assert_eq!(raised.len(), 1, "mission_margin raised once: {raised:?}");
    let t = raised[0];
    assert!(
        t > 0.35 * end && t < 0.7 * end,
        "mid-flight: {t} of {end} s"
    );
    let at = est.iter().find(|e| e["t"].as_f64().unwrap() >= t).unwrap();
    assert!(
        at["mission_margin_wh"].as_f64().unwrap() < 2.5,
        "raised with the margin under 2.5 Wh: {at}"
    );
    assert!(
        cleared.len() == 1 && cleared[0] > t && cleared[0] < end - 30.0,
        "cleared on the way home: {cleared:?}"
    );
    // The forecast warns before the measured voltage crosses BATT_LOW_VOLT (21.0 V), once.
    let sag = events("sag_forecast", "raised");
    let crossed = est
        .iter()
        .find(|e| e["battery_v"].as_f64().is_some_and(|v| v < 21.0))
        .and_then(|e| e["t"].as_f64())
        .expect("the measured voltage goes under BATT_LOW_VOLT in the demo");
    assert!(
        sag.len() == 1 && sag[0] + 20.0 < crossed,
        "voltage_forecast_below once, well before the measured {crossed} s: {sag:?}"
    );
    assert!(events("sag_forecast", "cleared").is_empty(), "no flapping");
    let low = events("energy_low", "raised");
    assert!(
        low.len() == 1 && low[0] > t && low[0] < 0.7 * end,
        "remaining_below mid-flight: {low:?}"
    );
    assert!(
        events("home_margin", "raised").is_empty() && events("power_high", "raised").is_empty()
    );
}
