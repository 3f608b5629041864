//! `dronewatt learn --fine-tune`, smoke-sized: three short simulated 3S-quad logs, a few
//! optimiser steps. The lean `dronewatt` hands the command to `dronewatt-torch`, which
//! fine-tunes the LSTM from the paper network's weights (lstm-m100-h128) and writes `lstm/`
//! (safetensors + card) beside the profile, which refers to it; the model card scores it by log; and the lean
//! binary then runs the fine-tuned model (`lstm_ft`, read by its own safetensors reader)
//! from the profile.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn lean() -> PathBuf {
    let p = Path::new(env!("CARGO_BIN_EXE_dronewatt-torch")).with_file_name("dronewatt");
    assert!(
        p.is_file(),
        "{}: not built (cargo test --workspace builds it)",
        p.display()
    );
    p
}

fn ok(args: &[&str]) -> Output {
    let out = Command::new(lean())
        .args(args)
        .env("DRONEWATT_HOME", "off")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "dronewatt {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

#[test]
fn fine_tunes_the_lstm_and_the_lean_binary_runs_it() {
    let dir = tempfile::tempdir().unwrap();
    let mut logs = Vec::new();
    for seed in 1..=3 {
        let p = dir
            .path()
            .join(format!("q3-{seed}.tlog"))
            .to_string_lossy()
            .into_owned();
        let s = seed.to_string();
        ok(&[
            "simulate",
            "--vehicle",
            "quad-3s",
            "--payload-g",
            "0",
            "--leg-m",
            "60",
            "--hover-s",
            "5",
            "--seed",
            &s,
            "--out",
            &p,
        ]);
        logs.push(p);
    }
    let out = dir.path().join("learned");
    let mut args: Vec<&str> = vec!["learn"];
    args.extend(logs.iter().map(String::as_str));
    args.extend([
        "--holdout-every",
        "3",
        "--out",
        out.to_str().unwrap(),
        "--fine-tune",
        "--ft-epochs",
        "2",
        "--ft-max-steps",
        "3",
    ]);
    ok(&args);

    // Weights and their card (the M100 normalisation kept), referred to by the profile.
    let card = dronewatt::model::card::ModelCard::load(&out.join("lstm/card.toml")).unwrap();
    assert_eq!(card.name, "lstm_ft");
    assert!(out.join("lstm/model.safetensors").is_file());
    let shipped = dronewatt::model::card::ModelCard::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("../config/models/lstm-m100-h128/card.toml"),
    )
    .unwrap();
    assert_eq!(
        (card.feature_mean.clone(), card.power_scale_w),
        (shipped.feature_mean, shipped.power_scale_w)
    );
    assert!(
        card.training.steps <= 3 && card.training.train_windows > 0,
        "{:?}",
        card.training
    );
    let profile = std::fs::read_to_string(out.join("profile.toml")).unwrap();
    assert!(profile.contains("lstm = \"lstm\""), "{profile}");
    // The model card scores it on the held-out log beside the physics models.
    let model_card = std::fs::read_to_string(out.join("model-card.md")).unwrap();
    assert!(
        model_card.contains("## LSTM fine-tuned") && model_card.contains("| lstm |"),
        "{model_card}"
    );

    // The lean binary runs it from the profile.
    let json = dir.path().join("r.jsonl");
    ok(&[
        "replay",
        "--speed",
        "max",
        "-q",
        "--data-dir",
        "off",
        "--vehicle",
        out.join("profile.toml").to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
        &logs[2],
    ]);
    let text = std::fs::read_to_string(&json).unwrap();
    let est: Vec<&str> = text
        .lines()
        .filter(|l| l.starts_with("{\"type\":\"estimate\""))
        .collect();
    assert!(!est.is_empty());
    // Every estimate carries a number from the fine-tuned model, none from the shipped one.
    let number_after = |l: &str, key: &str| {
        l.split(key)
            .nth(1)
            .and_then(|r| r.split([',', '}']).next())
            .and_then(|v| v.parse::<f64>().ok())
    };
    assert!(
        est.iter().all(
            |l| number_after(l, "\"lstm_ft\":").is_some_and(f64::is_finite)
                && !l.contains("\"lstm\":")
        ),
        "{}",
        est[0]
    );
}
