//! The README's first command, as an operator runs it: `dronewatt monitor udpin:…` from `/`,
//! with no config, on a vehicle whose radio carries everything at 1 Hz (pymavlink,
//! `tests/peers/vehicle.py` with `rate_hz` 1) flying a small 3S pack down to its
//! `BATT_LOW_VOLT`: estimates through the flight, and a default alert before the crossing,
//! in `--json` and as a STATUSTEXT on the ground station.

use crate::harness::{monitor_udp, Monitor};
use crate::link_common::{fly_small_pack_to_low, free_udp_port};

#[test]
fn the_readme_first_command_from_slash_on_a_1_hz_vehicle_gives_estimates_and_alerts() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("out.jsonl");
    let port = free_udp_port();
    let dw = Monitor::listening(
        monitor_udp(port)
            .current_dir("/")
            .env("XDG_CACHE_HOME", dir.path().join("cache"))
            .arg("--json")
            .arg(&json),
        port,
        false,
    );
    // 5 s at rest, then 24 s at 50 W, every message at 1 Hz. (The resting voltage needs
    // 2 s of rest, three samples at 1 Hz: with 3 s at rest a sample late under load left
    // none, and the pack started load-compensated, read as full.)
    let f = fly_small_pack_to_low(
        dw,
        port,
        r#"[{"send_s": 5, "ground": true, "rate_hz": 1}, {"send_s": 24, "rate_hz": 1}]"#,
        &json,
    );
    let (lines, peer, stderr, crossed_at) = (&f.lines, &f.peer, &f.stderr, f.crossed_at);
    let est: Vec<f64> = lines
        .iter()
        .filter(|l| l["type"] == "estimate")
        .filter(|l| l["models"].as_object().is_some_and(|m| !m.is_empty()))
        .filter_map(|l| l["t"].as_f64())
        .collect();
    assert!(est.len() >= 15, "{} estimates at 1 Hz: {stderr}", est.len());
    let raised: Vec<_> = lines
        .iter()
        .filter(|l| l["type"] == "alert" && l["state"] == "raised")
        .collect();
    let first = raised
        .iter()
        .filter_map(|a| a["t"].as_f64())
        .fold(f64::INFINITY, f64::min);
    assert!(
        first < crossed_at,
        "first alert at {first} s, the voltage crossed at {crossed_at} s: {raised:?}\n{stderr}"
    );
    let texts = peer["statustexts"].as_array().expect("statustexts");
    assert!(
        !texts.is_empty(),
        "no alert reached the ground station (raised {raised:?})"
    );
}
