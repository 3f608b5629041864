//! The offline commands (`eval`, `train`, `calibrate`, `sensitivity`) read the user's
//! configuration file (`--config`) as `replay` and `monitor` do: its model set, its
//! telemetry and its energy settings change what they compute, and a bad file stops them
//! with the file and the key named. Through the binary, on the real data set.

use crate::harness::{lab as dronewatt, RunExt};
use std::path::Path;
use std::process::Output;

/// `dronewatt ARGS --config CONFIG --data DATA` from the project root.
fn offline(args: &[&str], config: &Path) -> Output {
    dronewatt()
        .args(args)
        .arg("--config")
        .arg(config)
        .arg("--data")
        .arg(dronewatt::default_data_path())
        .current_dir(crate::harness::root())
        .out()
}

/// `eval --json -` on one flight with this configuration: the "models" object.
fn eval_models(dir: &Path, name: &str, toml: &str, flight: &str) -> serde_json::Value {
    let cfg = dir.join(name);
    std::fs::write(&cfg, toml).unwrap();
    let out = offline(&["eval", "--flight", flight, "--json", "-"], &cfg);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text[text.find('{').unwrap()..]).unwrap();
    json["models"].clone()
}

#[test]
fn eval_runs_the_configured_models_and_energy_tracker() {
    let dir = tempfile::tempdir().unwrap();
    // The LSTM switched off: the physics models are scored, the LSTM is not.
    let models = eval_models(
        dir.path(),
        "no-lstm.toml",
        "[models.lstm]\nenabled = false\n",
        "277",
    );
    assert!(
        models.get("lstm").is_none() && models.get("tseng").is_some(),
        "{models}"
    );
    // Flight 277 has a telemetry gap of more than a second in flight. The energy tracker
    // caps a step at [energy] max_dt_s (default 1 s); lifting the cap integrates the whole
    // gap. Energy scores move with it, power scores do not: energy comes from the tracker.
    let capped = eval_models(dir.path(), "default.toml", "", "277");
    let uncapped = eval_models(
        dir.path(),
        "uncapped.toml",
        "[energy]\nmax_dt_s = 100\n",
        "277",
    );
    let f = |m: &serde_json::Value, key: &str| m["dandrea"][key].as_f64().unwrap();
    assert_eq!(f(&capped, "mae_w"), f(&uncapped, "mae_w"));
    assert!(
        (f(&capped, "energy_err_pct") - f(&uncapped, "energy_err_pct")).abs() > 0.01,
        "{capped} vs {uncapped}"
    );
}

#[test]
fn a_bad_config_stops_every_offline_command_naming_the_file_and_key() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "[telemetry]\nwindow_len = 10\n").unwrap();
    let out_dir = dir.path().join("out");
    let out_dir = out_dir.to_str().unwrap();
    let out_file = dir.path().join("cal.toml");
    let commands: [&[&str]; 4] = [
        &["eval", "--flight", "276"],
        &[
            "calibrate",
            "--flights",
            "100",
            "-o",
            out_file.to_str().unwrap(),
        ],
        &["sensitivity", "--flights", "276", "--out", out_dir],
        &["train", "--flights", "100,150", "--out", out_dir],
    ];
    for args in commands {
        let out = offline(args, &bad);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} accepted a bad config");
        assert!(
            err.contains("bad.toml") && err.contains("window_len"),
            "{args:?}: {err}"
        );
    }
    // A valid file whose window the shipped LSTM was not trained on: the model refuses it,
    // naming the key, so the telemetry settings do reach the models.
    let short = dir.path().join("short.toml");
    std::fs::write(&short, "[telemetry]\nwindow = 5\n").unwrap();
    let out = offline(
        &["sensitivity", "--flights", "276", "--out", out_dir],
        &short,
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("telemetry.window"),
        "{err}"
    );
}

#[test]
fn eval_says_what_the_pack_voltage_leaves_open_once_and_not_where_the_config_knows() {
    let dir = tempfile::tempdir().unwrap();
    let said = |name: &str, toml: &str| {
        let cfg = dir.path().join(name);
        std::fs::write(&cfg, toml).unwrap();
        let out = offline(&["eval", "--flight", "276", "--json", "-"], &cfg);
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{err}");
        err.lines().filter(|l| l.contains("fits 6 or 7")).count()
    };
    // Flight 276 rests at 23.4 V before take-off: 6 or 7 LiHV cells. The live tracker
    // says so once; the per-model bookkeeping trackers (15 models) say nothing more.
    assert_eq!(said("default.toml", ""), 1);
    // Told the cells, there is nothing left open to say.
    assert_eq!(said("six.toml", "[energy]\ncell_count = 6\n"), 0);
}
