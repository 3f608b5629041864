//! End to end against an independent ground station: pymavlink
//! (`tests/peers/gcs_flight.py`) streams a synthetic flight to `dronewatt monitor
//! udpin:127.0.0.1:PORT` and listens on the same socket. With no `[sinks.mavlink]` table at
//! all dronewatt must answer on that link: NAMED_VALUE_FLOAT estimates, exactly one
//! STATUSTEXT warning when the remaining energy crosses the configured threshold (one, not
//! a storm), none on a flight that stays above it.

use crate::harness::{monitor_udp, Monitor};
use crate::link_common::{self, free_udp_port};

/// Stream 15 s at ~500 W to dronewatt with a `capacity_wh` battery and a 1.5 Wh warning.
fn fly(capacity_wh: f64) -> serde_json::Value {
    let config = format!(
        "[energy]\ncapacity_wh = {capacity_wh}\n\n[[alerts]]\nname = \"energy_low\"\nkind = \"remaining_below\"\n\
         below_wh = 1.5\nclear_wh = 1.7\nmessage = \"Battery low\"\n"
    );
    fly_with(&config, &["--seconds", "15"])
}

/// Stream a flight (peer arguments `peer_args`) to `dronewatt monitor` with this config.
fn fly_with(config: &str, peer_args: &[&str]) -> serde_json::Value {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("gcs.toml");
    std::fs::write(&cfg, config).unwrap();
    let port = free_udp_port();
    let dw = Monitor::listening(monitor_udp(port).arg("--config").arg(&cfg), port, false);
    let port_s = port.to_string();
    let args: Vec<&str> = ["--port", &port_s, "--power-w", "500"]
        .into_iter()
        .chain(peer_args.iter().copied())
        .collect();
    // Then SIGTERM: the pipeline's own shutdown path.
    link_common::peer_then_stop(dw, "gcs_flight.py", &args).0
}

fn check_estimates(heard: &serde_json::Value) {
    let values = heard["values"].as_object().unwrap();
    for name in ["dw_meas_w", "dw_used_wh", "dw_rem_wh", "dw_tte_s"] {
        assert!(
            values
                .get(name)
                .is_some_and(|v| v.as_array().unwrap().len() >= 10),
            "no {name} in {heard}"
        );
    }
    let meas: Vec<f64> = values["dw_meas_w"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|v| v.as_f64())
        .collect();
    assert!(
        meas.iter().all(|w| (440.0..=560.0).contains(w)),
        "measured power off the profile: {meas:?}"
    );
    // Our own ids alongside nothing that claims to be the autopilot (component 1).
    assert!(
        heard["senders"]
            .as_array()
            .unwrap()
            .contains(&serde_json::json!([1, 191])),
        "{heard}"
    );
    assert!(
        !heard["senders"]
            .as_array()
            .unwrap()
            .contains(&serde_json::json!([1, 1])),
        "{heard}"
    );
    assert!(heard["heartbeats"].as_u64().unwrap() >= 5, "{heard}");
    eprintln!(
        "SYS_STATUS → dw_meas_w delay over the link: p50 {} ms, p99 {} ms ({} samples)",
        heard["delay_p50_ms"], heard["delay_p99_ms"], heard["delays"]
    );
}

#[test]
fn monitor_warns_once_when_energy_runs_low() {
    // 3 Wh at ~500 W: 1.5 Wh remain after ~11 s of the 15 s flight.
    let heard = fly(3.0);
    check_estimates(&heard);
    let texts = heard["statustexts"].as_array().unwrap();
    assert_eq!(texts.len(), 1, "exactly one warning: {texts:?}");
    assert_eq!(texts[0]["severity"], 4, "MAV_SEVERITY_WARNING");
    assert!(
        texts[0]["text"]
            .as_str()
            .unwrap()
            .starts_with("Battery low 1."),
        "{texts:?}"
    );
    let at = texts[0]["t"].as_f64().unwrap();
    assert!(
        (9.0..=14.0).contains(&at),
        "warned at {at} s of the flight, expected ~11 s"
    );
}

#[test]
fn monitor_stays_quiet_above_the_threshold() {
    let heard = fly(100.0);
    check_estimates(&heard);
    assert_eq!(heard["statustexts"], serde_json::json!([]));
}

#[test]
fn monitor_warns_when_the_link_goes_silent() {
    // 6 s of telemetry, then nothing while the peer listens on for 6 s: with no estimate
    // at all, the telemetry_lost rule must still fire (once) after its 2 s.
    let config = "[[alerts]]\nname = \"lost\"\nkind = \"telemetry_lost\"\nfor_s = 2\nseverity = \"critical\"\n\
                  message = \"Telemetry lost\"\n";
    let heard = fly_with(config, &["--seconds", "6", "--listen-after-s", "6"]);
    let texts = heard["statustexts"].as_array().unwrap();
    assert_eq!(texts.len(), 1, "exactly one alert: {texts:?}");
    assert_eq!(texts[0]["severity"], 2, "MAV_SEVERITY_CRITICAL");
    assert!(
        texts[0]["text"]
            .as_str()
            .unwrap()
            .starts_with("Telemetry lost"),
        "{texts:?}"
    );
}
