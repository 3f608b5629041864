//! `dronewatt learn` → `dronewatt replay --vehicle` round trip on a vehicle that is not the
//! M100: the simulator flies four X500 logs (different seeds and winds); `learn` fits the
//! physics models on two, scores them on the third (held out whole) and writes a profile
//! and a model card; a replay of the fourth log, never seen, with the learned profile is far
//! closer to the measured power than with the published M100 parameters. `learn` also picks
//! the forecast model on the held-out log and keeps the profile in the vehicle store, so a
//! replay of the vehicle with that store and no `--vehicle` runs the learned profile and
//! forecasts from its pick.

use crate::harness::{output, replay_json, run, simulate_x500};
use std::path::Path;

/// Each physics model's MAPE over the in-flight windows (measured > 100 W) of a replay, %.
fn physics_mape(tlog: &Path, vehicle: Option<&Path>) -> Vec<(String, f64)> {
    let args = match vehicle {
        Some(v) => vec!["--vehicle", v.to_str().unwrap()],
        None => vec![],
    };
    let lines = replay_json(tlog, &args);
    let est: Vec<&serde_json::Value> = lines
        .iter()
        .filter(|l| l["type"] == "estimate" && l["measured_w"].as_f64().is_some_and(|m| m > 100.0))
        .collect();
    assert!(est.len() > 500, "{} in-flight estimates", est.len());
    let names: Vec<String> = est[0]["models"]
        .as_object()
        .unwrap()
        .keys()
        .filter(|n| *n != "lstm")
        .cloned()
        .collect();
    names
        .into_iter()
        .map(|n| {
            let mape = est
                .iter()
                .map(|e| {
                    (e["models"][&n].as_f64().unwrap() - e["measured_w"].as_f64().unwrap()).abs()
                        / e["measured_w"].as_f64().unwrap()
                })
                .sum::<f64>();
            (n, 100.0 * mape / est.len() as f64)
        })
        .collect()
}

#[test]
fn learned_profile_beats_the_published_one_on_an_unseen_log() {
    let dir = tempfile::tempdir().unwrap();
    let logs = dir.path().join("logs");
    std::fs::create_dir_all(&logs).unwrap();
    for seed in 1..=3 {
        simulate_x500(&logs.join(format!("x500-{seed}.tlog")), seed, &[]);
    }
    let unseen = dir.path().join("x500-4.tlog");
    simulate_x500(&unseen, 4, &[]);
    let out_dir = dir.path().join("learned");
    let store = dir.path().join("store");
    let out = run(&[
        "learn",
        logs.to_str().unwrap(),
        "--holdout-every",
        "3",
        "--out",
        out_dir.to_str().unwrap(),
        "--data-dir",
        store.to_str().unwrap(),
    ]);
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(
        said.contains("held out:") && said.contains("x500-3.tlog"),
        "{said}"
    );
    let card = std::fs::read_to_string(out_dir.join("model-card.md")).unwrap();
    assert!(
        card.contains("held out (score)")
            && card.contains("| training |")
            && card.contains("not fine-tuned"),
        "{card}"
    );
    let profile = out_dir.join("profile.toml");
    let text = std::fs::read_to_string(&profile).unwrap();
    assert!(text.contains("[calibration]"));
    // The forecast model picked on the held-out log, in the profile and the card.
    let table: toml::Table = toml::from_str(&text).unwrap();
    let pick = table["forecast"]["model"].as_str().unwrap().to_string();
    assert!(pick.ends_with("_cal") || pick == "lstm", "{pick}");
    assert!(
        card.contains("## Forecast model") && card.contains(&pick),
        "{card}"
    );
    // The store keeps it for the logs' vehicle, and says so.
    let listing =
        String::from_utf8_lossy(&run(&["vehicles", "--data-dir", store.to_str().unwrap()]).stdout)
            .into_owned();
    assert!(
        listing.contains("learned profile") && listing.contains(&pick),
        "{listing}"
    );

    let published = physics_mape(&unseen, None);
    let learned = physics_mape(&unseen, Some(&profile));
    assert!(
        learned.iter().all(|(n, _)| n.ends_with("_cal")),
        "{learned:?}"
    );
    let mean = |v: &[(String, f64)]| v.iter().map(|(_, m)| m).sum::<f64>() / v.len() as f64;
    let best = |v: &[(String, f64)]| v.iter().map(|(_, m)| *m).fold(f64::INFINITY, f64::min);
    assert!(
        mean(&learned) < 0.6 * mean(&published),
        "learned {learned:?}\npublished {published:?}"
    );
    assert!(best(&learned) < 10.0, "{learned:?}");

    // The next run of the vehicle with the store (no --vehicle): the learned profile's
    // models, the forecast on its pick, from the first window.
    let json = dir.path().join("from-store.jsonl");
    run(&[
        "replay",
        "--speed",
        "max",
        "-q",
        "--data-dir",
        store.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
        unseen.to_str().unwrap(),
    ]);
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&json)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let est: Vec<&serde_json::Value> = lines.iter().filter(|l| l["type"] == "estimate").collect();
    let first = est
        .iter()
        .find(|e| e["forecast_model"].is_string())
        .unwrap();
    assert!(
        first["models"]
            .as_object()
            .unwrap()
            .keys()
            .any(|n| n.ends_with("_cal")),
        "{first}"
    );
    assert_eq!(
        first["forecast_model"].as_str(),
        Some(pick.as_str()),
        "{first}"
    );
    assert!(
        first["forecast_why"]
            .as_str()
            .unwrap()
            .contains("learned for this vehicle"),
        "{first}"
    );
}

#[test]
fn learn_refuses_logs_it_cannot_read_and_a_single_log() {
    let dir = tempfile::tempdir().unwrap();
    let txt = dir.path().join("notes.txt");
    std::fs::write(&txt, b"not read").unwrap();
    let out = output(&["learn", txt.to_str().unwrap()]);
    assert!(!out.status.success());
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(
        said.contains("notes.txt")
            && said.contains(".tlog, ArduPilot DataFlash .bin and PX4 ULog .ulg"),
        "{said}"
    );
    let one = dir.path().join("one.tlog");
    simulate_x500(&one, 1, &[]);
    // A .bin that is not DataFlash, a .ulg that is not ULog: an error naming the file and
    // what is wrong with it.
    for (name, why) in [
        ("00000012.BIN", "not an ArduPilot DataFlash log"),
        ("log_3.ulg", "not a readable PX4 ULog"),
    ] {
        let bad = dir.path().join(name);
        std::fs::write(&bad, b"not a log").unwrap();
        let out = output(&[
            "learn",
            bad.to_str().unwrap(),
            one.to_str().unwrap(),
            "--out",
            dir.path().join("o").to_str().unwrap(),
            "--data-dir",
            "off",
        ]);
        assert!(!out.status.success());
        let said = String::from_utf8_lossy(&out.stderr);
        assert!(said.contains(name) && said.contains(why), "{said}");
    }
    let out = output(&[
        "learn",
        one.to_str().unwrap(),
        "--out",
        dir.path().join("o").to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("at least 2"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
