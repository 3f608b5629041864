//! Useful with no config: the pilot's default alert rules (`alert::defaults`) run when no
//! `[[alerts]]` are configured, `check-config` with no file and `monitor --help` show them,
//! and a pack flown down to its low voltage with no config at all warns the ground station
//! (pymavlink, `tests/peers/vehicle.py --pack`) before the voltage gets there.

use crate::harness::{monitor_udp, run, Monitor};
use crate::link_common::{fly_small_pack_to_low, free_udp_port};

const DEFAULTS: [&str; 5] = [
    "low_voltage_before_home",
    "below_reserve",
    "voltage_forecast",
    "mission_margin",
    "telemetry_lost",
];

#[test]
fn check_config_with_no_file_and_help_show_the_default_rules() {
    let out = String::from_utf8(run(&["check-config"]).stdout).unwrap();
    assert!(
        out.contains("alerts: 5 rule(s) (the pilot's defaults"),
        "{out}"
    );
    let help = String::from_utf8(run(&["monitor", "--help"]).stdout).unwrap();
    for name in DEFAULTS {
        assert!(out.contains(&format!("name = \"{name}\"")), "{name}: {out}");
        assert!(help.contains(name), "{name}: {help}");
    }
    // The printed TOML is a config: checked, it sets up the same five rules (not the defaults'
    // marker: written down, they are the config's own).
    let dir = tempfile::tempdir().unwrap();
    let toml = out.split("# The default alert rules").nth(1).unwrap();
    let toml = toml.split_once('\n').unwrap().1;
    let cfg = dir.path().join("alerts.toml");
    std::fs::write(&cfg, toml.replace("below_pct = 20", "below_pct = 15")).unwrap();
    let mine = String::from_utf8(run(&["check-config", cfg.to_str().unwrap()]).stdout).unwrap();
    assert!(mine.contains("alerts: 5 rule(s)\n"), "{mine}");
}

#[test]
fn with_no_config_a_pack_flown_to_its_low_voltage_warns_before_the_crossing() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("out.jsonl");
    let port = free_udp_port();
    let dw = Monitor::listening(monitor_udp(port).arg("--json").arg(&json), port, false);
    // 3 s at rest, then 20 s at 50 W: the loaded voltage crosses the vehicle's BATT_LOW_VOLT
    // (10.5 V) about 12 s after take-off.
    let f = fly_small_pack_to_low(
        dw,
        port,
        r#"[{"send_s": 3, "ground": true}, {"send_s": 20}]"#,
        &json,
    );
    let (lines, peer, stderr, crossed_at) = (&f.lines, &f.peer, &f.stderr, f.crossed_at);
    let raised: Vec<_> = lines
        .iter()
        .filter(|l| l["type"] == "alert" && l["state"] == "raised")
        .filter(|l| DEFAULTS.contains(&l["rule"].as_str().unwrap_or("")))
        .collect();
    let first = raised
        .iter()
        .map(|a| a["t"].as_f64().unwrap())
        .fold(f64::INFINITY, f64::min);
    assert!(
        first < crossed_at,
        "first default alert at {first} s, the voltage crossed at {crossed_at} s: {raised:?}\n{stderr}"
    );
    let texts = peer["statustexts"].as_array().expect("statustexts");
    let said: Vec<&str> = raised
        .iter()
        .filter_map(|a| a["message"].as_str())
        .collect();
    assert!(
        texts
            .iter()
            .filter_map(|t| t.as_str())
            .any(|t| said.iter().any(|m| t.starts_with(&m[..m.len().min(20)]))),
        "no default alert reached the ground station: {texts:?} (raised {said:?})"
    );
}
