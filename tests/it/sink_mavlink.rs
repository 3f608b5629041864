//! The MAVLink sink against an independent ground station: pymavlink
//! (`tests/peers/gcs_listen.py`) listens on 127.0.0.1 and the sink sends to it with
//! `udpout:`, fed by the real energy tracker and alert engine over a synthetic flight.
//! The end-to-end version through `dronewatt monitor` is `tests/it/sink_mavlink_monitor.rs`.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::Arc;

use dronewatt::alert::AlertEngine;
use dronewatt::config::Config;
use dronewatt::energy::EnergyTracker;
use dronewatt::features::{Sample, N_FEATURES};
use dronewatt::pipeline::start_sinks;
use dronewatt::report::Report;
use dronewatt::report::{Estimate, ModelEstimate};
use dronewatt::sink::SinkSpec;

fn python() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(".venv-py/bin/python")
}

/// Fly 60 s at 10 Hz drawing ~500 W with a `capacity_wh` battery; return what the ground
/// station heard.
async fn fly(capacity_wh: f64) -> serde_json::Value {
    let mut peer = Command::new(python())
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/peers/gcs_listen.py"
        ))
        .args(["--idle-s", "1.5"])
        .stdout(Stdio::piped())
        .spawn()
        .expect("run .venv-py/bin/python (make setup creates it)");
    let mut out = BufReader::new(peer.stdout.take().unwrap());
    let mut line = String::new();
    out.read_line(&mut line).unwrap();
    let port: u16 = line.trim().strip_prefix("PORT ").unwrap().parse().unwrap();

    let cfg: Config = toml::from_str(&format!(
        r#"
        [energy]
        capacity_wh = {capacity_wh}
        [[alerts]]
        name = "energy_low"
        kind = "remaining_below"
        below_wh = 4
        clear_wh = 4.5
        message = "Battery low"
        [sinks.mavlink]
        address = "udpout:127.0.0.1:{port}"
        rate_hz = 50
        "#
    ))
    .unwrap();
    cfg.validate().unwrap();
    let cfg = Arc::new(cfg);
    let (mut fanout, sinks) = start_sinks(
        vec![SinkSpec::Mavlink(cfg.sinks.mavlink.clone())],
        &Default::default(),
    )
    .unwrap();
    let mut energy = EnergyTracker::new(&cfg.energy, cfg.mission.speed_m_s).unwrap();
    let mut alerts = AlertEngine::new(&cfg.alerts).unwrap();
    for i in 0..600 {
        let t_s = i as f64 * 0.1;
        let measured = 500.0 + 40.0 * ((i as f32) * 0.7).sin();
        let est = Estimate {
            arrived: None,
            t_s,
            sample: Sample {
                t_s,
                features: [0.0; N_FEATURES],
                measured_w: Some(measured),
                voltage_v: Some(22.0),
                home: None,
                stale_mask: 0,
                battery_remaining_pct: None,
                vehicle: Default::default(),
                air: Default::default(),
            },
            models: vec![ModelEstimate::new("lstm", 480.0, None)],
        };
        let state = energy.update(&est);
        let events = alerts.evaluate(&est, &state);
        fanout
            .send(Report {
                estimate: est,
                energy: state,
                alerts: events,
                vehicle: 1.into(),
            })
            .await;
        tokio::time::sleep(std::time::Duration::from_millis(2)).await;
    }
    drop(fanout);
    sinks.join().await.unwrap();
    let mut summary = String::new();
    out.read_line(&mut summary).unwrap();
    let _ = peer.wait();
    serde_json::from_str(&summary).unwrap_or_else(|e| panic!("peer said {summary:?}: {e}"))
}

fn check_estimates(heard: &serde_json::Value) {
    let values = heard["values"].as_object().unwrap();
    for name in [
        "dw_meas_w",
        "dw_pred_w",
        "dw_lstm_w",
        "dw_fcst_w",
        "dw_used_wh",
        "dw_rem_wh",
        "dw_rem_pct",
        "dw_tte_s",
    ] {
        assert!(
            values
                .get(name)
                .is_some_and(|v| v.as_array().unwrap().len() >= 5),
            "no {name} in {values:?}"
        );
    }
    assert!(values.keys().all(|k| k.len() <= 10));
    let meas: Vec<f64> = values["dw_meas_w"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert!(meas.iter().all(|w| (450.0..=550.0).contains(w)), "{meas:?}");
    let pred = values["dw_pred_w"].as_array().unwrap();
    assert!(pred.iter().all(|w| w.as_f64() == Some(480.0)), "{pred:?}");
    let rem: Vec<f64> = values["dw_rem_wh"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert!(
        rem.windows(2).all(|w| w[1] <= w[0]),
        "remaining energy must fall: {rem:?}"
    );
    // dronewatt's ids, never the autopilot's component 1.
    assert_eq!(heard["senders"], serde_json::json!([[1, 191]]));
    assert!(heard["heartbeats"].as_u64().unwrap() >= 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn one_warning_when_the_energy_threshold_is_crossed() {
    // 10 Wh at ~500 W for 60 s uses ~8.3 Wh: remaining crosses 4 Wh at about 43 s.
    let heard = fly(10.0).await;
    check_estimates(&heard);
    let texts = heard["statustexts"].as_array().unwrap();
    assert_eq!(texts.len(), 1, "{texts:?}");
    assert_eq!(texts[0]["severity"], 4, "MAV_SEVERITY_WARNING");
    let text = texts[0]["text"].as_str().unwrap();
    let wh: f64 = text
        .strip_prefix("Battery low ")
        .and_then(|v| v.strip_suffix("Wh"))
        .and_then(|v| v.parse().ok())
        .unwrap_or(f64::NAN);
    assert!((3.9..=4.0).contains(&wh), "{text}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn no_warning_when_the_flight_stays_above_it() {
    let heard = fly(100.0).await;
    check_estimates(&heard);
    assert_eq!(heard["statustexts"], serde_json::json!([]));
}
