//! Training and the shipped weights on the real data set (`DRONEWATT_DATA`), through the
//! ingest path (`offline::data::load_flights`).

use dronewatt::model::card::ModelCard;
use dronewatt::model::lstm::{LstmModel, DEFAULT_MODEL_DIR};
use dronewatt::model::PowerModel;
use dronewatt::offline::data::load_flights;
use dronewatt::telemetry::{MissionConfig, TelemetryConfig};

/// A smoke-sized run (three flights, a few hundred steps, small network, target lag 2): the
/// loss falls, and the card (with its lag), weights and curves are written.
#[test]
fn smoke_training_loss_falls() {
    let out = tempfile::tempdir().unwrap();
    // Through `dronewatt-lab`, which hands training to `dronewatt-torch` beside it.
    let lean =
        std::path::Path::new(env!("CARGO_BIN_EXE_dronewatt-torch")).with_file_name("dronewatt-lab");
    assert!(
        lean.is_file(),
        "{}: not built (cargo test --workspace builds it)",
        lean.display()
    );
    let mut cmd = std::process::Command::new(&lean);
    cmd.args([
        "train",
        "--flights",
        "100,150,200",
        "--stride",
        "1",
        "--epochs",
        "8",
        "--patience",
        "8",
    ])
    .args([
        "--max-steps",
        "300",
        "--hidden",
        "32",
        "--batch",
        "64",
        "--lr",
        "3e-3",
        "--seed",
        "3",
        "--target-lag",
        "2",
    ]);
    let status = on_data(&mut cmd, out.path());
    assert!(status.success(), "dronewatt-lab train failed");
    let curve = std::fs::read_to_string(out.path().join("loss.csv")).unwrap();
    let losses: Vec<f64> = curve
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(2).unwrap().parse().unwrap())
        .collect();
    assert!(losses.len() >= 3, "{curve}");
    assert!(
        losses.last().unwrap() < &(losses[0] * 0.7),
        "training loss did not fall: {losses:?}"
    );
    let card = ModelCard::load(&out.path().join("card.toml")).unwrap();
    assert_eq!(
        card.training.train_flights.len() + card.training.validation_flights.len(),
        3
    );
    assert_eq!(
        card.target_lag, 2,
        "the card records the target lag the model was trained for"
    );
    assert!(
        out.path().join("loss.png").is_file() && out.path().join("model.safetensors").is_file()
    );
}

/// The committed weights, loaded as the binary loads them, score flight 276 (never
/// trained on) within 35 W MAE.
#[test]
fn shipped_weights_flight_276() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(DEFAULT_MODEL_DIR);
    let cfg = TelemetryConfig::default();
    let mut model = LstmModel::load(&dir, &cfg).unwrap();
    assert!(!model.card().training.train_flights.contains(&276));
    assert!(!model.card().training.validation_flights.contains(&276));
    let flights = [flight(276, &cfg)];
    // Each estimate is for the sample the card's target lag before the window's newest.
    let lag = model.card().target_lag;
    let windows: Vec<_> = flights[0]
        .windows
        .iter()
        .filter(|w| w.back(lag).measured_w.is_some())
        .cloned()
        .collect();
    assert!(windows.len() > 1000);
    let mut out = Vec::new();
    model.predict(&windows, &mut out);
    let mae = windows
        .iter()
        .zip(&out)
        .map(|(w, p)| (p.power_w - w.back(lag).measured_w.unwrap()).abs() as f64)
        .sum::<f64>()
        / windows.len() as f64;
    assert!(mae <= 35.0, "flight 276 MAE {mae:.1} W");
}

/// The hand-written forward, one window at a time (the live case) and as one batch of
/// every window (a replay flat out), gives libtorch's estimates and bands on the shipped
/// weights over flight 276.
#[test]
fn live_forward_matches_libtorch_on_shipped_weights() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(DEFAULT_MODEL_DIR);
    let cfg = TelemetryConfig::default();
    let mut model = LstmModel::load(&dir, &cfg).unwrap();
    assert!(model.on_kernel());
    let mut torch =
        LstmModel::load_with(&dir, &cfg, Some(dronewatt_torch::load_on_libtorch)).unwrap();
    assert!(!torch.on_kernel());
    let flights = [flight(276, &cfg)];
    let windows: Vec<_> = flights[0].windows.iter().step_by(7).cloned().collect();
    assert!(windows.len() > 100);
    let mut batched = Vec::new();
    torch.predict(&windows, &mut batched);
    let mut all = Vec::new();
    model.predict(&windows, &mut all);
    assert_eq!(all.len(), batched.len());
    for (got, want) in all.iter().zip(&batched) {
        assert!(
            (got.power_w - want.power_w).abs() < 0.05,
            "batched: {} W vs libtorch {} W",
            got.power_w,
            want.power_w
        );
        let (gb, wb) = (got.band_w.unwrap(), want.band_w.unwrap());
        assert!(
            (gb.0 - wb.0).abs() < 0.05 && (gb.1 - wb.1).abs() < 0.05,
            "batched band {gb:?} vs {wb:?}"
        );
    }
    let mut one = Vec::new();
    for (w, want) in windows.iter().zip(&batched) {
        model.predict(std::slice::from_ref(w), &mut one);
        let got = &one[0];
        assert!(
            (got.power_w - want.power_w).abs() < 0.05,
            "t = {}: {} W vs libtorch {} W",
            w.last().t_s,
            got.power_w,
            want.power_w
        );
        let (gb, wb) = (got.band_w.unwrap(), want.band_w.unwrap());
        assert!(
            (gb.0 - wb.0).abs() < 0.05 && (gb.1 - wb.1).abs() < 0.05,
            "band {gb:?} vs {wb:?}"
        );
    }
}

/// `train --cv 2 --init-seed 3,4` on four flights, a few steps a fit: every fold's two-member
/// ensemble scores its held-out flights through the live chain, `cv.csv` carries the
/// held-out MAE, in-flight MAPE, energy error and band coverage (mean, median, per fold), all
/// finite, and the final run writes an ensemble card the binary loads, its band calibrated
/// from the cross-validation it just wrote (`--band-from-cv`). CPU only.
#[test]
fn smoke_cross_validation_scores_held_out_folds() {
    let out = tempfile::tempdir().unwrap();
    let cv_csv = out.path().join("cv.csv");
    let cv_arg = cv_csv.to_str().unwrap();
    let status = smoke_train(
        out.path(),
        &[
            "--cv",
            "2",
            "--init-seed",
            "3,4",
            "--target-lag",
            "2",
            "--band-from-cv",
            cv_arg,
            "--cv-predictions",
        ],
    );
    assert!(status.success(), "dronewatt-lab train --cv 2 failed");
    let csv = std::fs::read_to_string(out.path().join("cv.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let row: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(header.len(), row.len(), "{csv}");
    let cell = |name: &str| row[header.iter().position(|h| *h == name).unwrap()];
    for name in [
        "avg_mae_w",
        "median_mae_w",
        "avg_rmse_w",
        "avg_mape_in_flight_pct",
        "median_mape_in_flight_pct",
        "avg_energy_error_pct",
        "median_energy_error_pct",
        "avg_band_coverage_pct",
        "cv_band_widen_w",
    ] {
        let v: f64 = cell(name).parse().unwrap();
        assert!(v.is_finite() && v >= 0.0, "{name} = {v}\n{csv}");
    }
    for name in [
        "fold_mae_w",
        "fold_mape_in_flight_pct",
        "fold_energy_error_pct",
        "fold_inner_val_mae_w",
        "fold_band_coverage_pct",
        "fold_band_q_w",
    ] {
        let v: Vec<f64> = cell(name).split(';').map(|x| x.parse().unwrap()).collect();
        assert_eq!(v.len(), 2, "{name}: one value per fold\n{csv}");
        assert!(v.iter().all(|x| x.is_finite()), "{name}: {v:?}\n{csv}");
    }
    // Two folds of two flights: each held out once, never both in one fold.
    let held: Vec<&str> = cell("fold_held_out").split(';').collect();
    assert_eq!(held.len(), 2, "{csv}");
    assert!(
        !out.path().join(".cv-fold").exists(),
        "the fold scratch folder is removed"
    );
    assert_eq!(cell("init_seeds"), "3;4", "{csv}");
    assert_eq!(
        cell("target_lag"),
        "2",
        "the row says the lag it was trained at\n{csv}"
    );
    // `--cv-predictions`: each fold's held-out windows, whose MAE is the fold's in cv.csv.
    let fold_mae: Vec<f64> = cell("fold_mae_w")
        .split(';')
        .map(|x| x.parse().unwrap())
        .collect();
    for (k, want) in fold_mae.iter().enumerate() {
        let dump = std::fs::read_to_string(out.path().join(format!("cv-predictions-{k}.csv")))
            .unwrap_or_else(|e| panic!("cv-predictions-{k}.csv: {e}"));
        let mut rows = dump.lines();
        assert_eq!(
            rows.next(),
            Some("flight,fold,t_s,measured_w,pred_w,low_w,high_w")
        );
        let errs: Vec<f64> = rows
            .map(|l| {
                let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
                assert_eq!(v[1], k as f64, "{l}");
                (v[4] - v[3]).abs()
            })
            .collect();
        let mae = errs.iter().sum::<f64>() / errs.len() as f64;
        assert!(
            (mae - want).abs() < 0.01,
            "fold {k}: the dump's MAE {mae} against cv.csv's {want}"
        );
    }
    let card = ModelCard::load(&out.path().join("card.toml")).unwrap();
    // The band is the cross-validation's: the folds' mean signed widening, floored at 0.
    let q: Vec<f64> = cell("fold_band_q_w")
        .split(';')
        .map(|x| x.parse().unwrap())
        .collect();
    let widen = (q.iter().sum::<f64>() / q.len() as f64).max(0.0);
    assert_eq!(
        card.band_calibration,
        dronewatt::model::card::BandCalibration::Cv
    );
    assert!(
        (f64::from(card.band_widen_w) - widen).abs() < 1e-3
            && (widen - cell("cv_band_widen_w").parse::<f64>().unwrap()).abs() < 1e-3,
        "card {} W, folds {q:?}\n{csv}",
        card.band_widen_w
    );
    assert_eq!(card.weights, "member-3.safetensors");
    assert_eq!(card.members, ["member-4.safetensors"]);
    assert_eq!(card.training.init_seed, None, "member 3 is --seed's own");
    let cfg = TelemetryConfig::default();
    let mut model = LstmModel::load(out.path(), &cfg).unwrap();
    let flights = [flight(100, &cfg)];
    let mut est = Vec::new();
    model.predict(&flights[0].windows[..50], &mut est);
    assert!(est.iter().all(|p| p.power_w.is_finite()), "{est:?}");
    let metrics = card.validation_metrics.expect("validation flights scored");
    assert!(metrics.mae_w.is_finite());

    // A member is the network its init seed trains alone (same split, same seed, one
    // thread): the model card's one-command retrain and a member-by-member one agree.
    let alone = tempfile::tempdir().unwrap();
    let status = smoke_train(alone.path(), &["--init-seed", "4", "--target-lag", "2"]);
    assert!(status.success(), "dronewatt-lab train --init-seed 4 failed");
    let windows = &flights[0].windows[..50];
    let mut member = LstmModel::load(&out.path().join("member-4.safetensors"), &cfg).unwrap();
    let mut single = LstmModel::load(alone.path(), &cfg).unwrap();
    let (mut a, mut b) = (Vec::new(), Vec::new());
    member.predict(windows, &mut a);
    single.predict(windows, &mut b);
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(
            x.power_w, y.power_w,
            "member 4 differs from seed 4 trained alone"
        );
    }
}

/// `--relative-loss` and `--plateau-decay` are recorded in the card (so `--ensemble` can
/// refuse a member trained otherwise), the relative loss changes what the network learns,
/// and an out-of-range value is refused, naming the flag. CPU only.
#[test]
fn smoke_loss_options_are_recorded_and_act() {
    let (plain, weighted) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    assert!(smoke_train(plain.path(), &[]).success());
    let flags = ["--relative-loss", "1", "--plateau-decay", "0.5"];
    assert!(smoke_train(weighted.path(), &flags).success());
    let card = ModelCard::load(&weighted.path().join("card.toml")).unwrap();
    assert_eq!(card.training.relative_loss, 1.0);
    assert_eq!(card.training.plateau_decay, Some(0.5));
    let card = ModelCard::load(&plain.path().join("card.toml")).unwrap();
    assert_eq!(card.training.relative_loss, 0.0);
    assert_eq!(
        card.training.plateau_decay, None,
        "a constant rate is not written"
    );

    let cfg = TelemetryConfig::default();
    let flights = [flight(100, &cfg)];
    let windows = &flights[0].windows[..50];
    let (mut a, mut b) = (Vec::new(), Vec::new());
    LstmModel::load(plain.path(), &cfg)
        .unwrap()
        .predict(windows, &mut a);
    LstmModel::load(weighted.path(), &cfg)
        .unwrap()
        .predict(windows, &mut b);
    assert!(
        a.iter().zip(&b).any(|(x, y)| x.power_w != y.power_w),
        "the relative loss trained the same network as the absolute one"
    );

    let bad = tempfile::tempdir().unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_dronewatt-torch"))
        .args(["train", "--relative-loss", "2", "--data"])
        .arg(dronewatt::default_data_path())
        .arg("--out")
        .arg(bad.path())
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--relative-loss 2"), "{err}");
}

/// `train --readout instant`: the card says so, and the CPU kernel that serves the weights
/// in `dronewatt` reads the states libtorch trained them on (the same outputs as the network
/// in tch), not the final ones.
#[test]
fn smoke_instant_readout_is_recorded_and_served_as_trained() {
    use dronewatt::features::N_FEATURES;
    use dronewatt::model::card::Readout;
    use dronewatt::model::lstm::{push_inputs, ExternalNet};
    let out = tempfile::tempdir().unwrap();
    let flags = ["--readout", "instant", "--target-lag", "3"];
    assert!(smoke_train(out.path(), &flags).success());
    let card = ModelCard::load(&out.path().join("card.toml")).unwrap();
    assert_eq!(card.readout, Readout::Instant);
    assert_eq!(card.readout_step(), Some(card.window - 4));

    let cfg = TelemetryConfig::default();
    let flights = [flight(150, &cfg)];
    let windows = &flights[0].windows[100..160];
    let mut served = Vec::new();
    LstmModel::load(out.path(), &cfg)
        .unwrap()
        .predict(windows, &mut served);
    let mut x = Vec::new();
    for w in windows {
        push_inputs(w, card.feature_set, card.window, &mut x);
    }
    for (i, v) in x.iter_mut().enumerate() {
        let f = i % N_FEATURES;
        *v = (*v - card.feature_mean[f]) / card.feature_std[f];
    }
    let weights = out.path().join(&card.weights);
    let mut tch_net = dronewatt_torch::TorchNet::load(&weights, &card, tch::Device::Cpu).unwrap();
    let (y, cols) = tch_net.forward(&x, windows.len(), card.window).unwrap();
    for (i, p) in served.iter().enumerate() {
        let want = y[i * cols] * card.power_scale_w;
        assert!(
            (p.power_w - want).abs() < 1e-2,
            "window {i}: served {} W, libtorch {want} W",
            p.power_w
        );
    }

    // The same weights read with the final states are another model.
    let text = std::fs::read_to_string(out.path().join("card.toml")).unwrap();
    let final_card = text.replace("readout = \"instant\"\n", "");
    assert_ne!(text, final_card, "the card writes its readout");
    std::fs::write(out.path().join("card.toml"), final_card).unwrap();
    let mut other = Vec::new();
    LstmModel::load(out.path(), &cfg)
        .unwrap()
        .predict(windows, &mut other);
    assert!(
        served
            .iter()
            .zip(&other)
            .any(|(a, b)| (a.power_w - b.power_w).abs() > 1e-3),
        "the readout changed nothing"
    );
}

/// `dronewatt-torch train` on four flights with a tiny network and a few steps a fit, CPU
/// only, into `out`, with `extra` flags.
/// `train --export-csv`, the LightGBM scripts' windows: every training flight carries its
/// fold of `cv_folds` and every test flight -1; the lagged copies are the earlier samples'
/// features; the physics columns are each model's estimate of the window in watts (published
/// Tseng within a third of the measured power in flight, as its ~16 % MAPE says).
#[test]
fn export_csv_carries_folds_lags_and_physics_estimates() {
    let out = tempfile::tempdir().unwrap();
    let csv = out.path().join("windows.csv");
    let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_dronewatt-torch"));
    cmd.args(["train", "--flights", "100,150,200,276", "--cv", "3"])
        .args(["--seed", "7", "--target-lag", "3", "--export-csv"])
        .arg(&csv);
    let status = on_data(&mut cmd, out.path());
    assert!(
        status.success(),
        "dronewatt-torch train --export-csv failed"
    );
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .unwrap_or_else(|| panic!("no column {name} in {header:?}"))
    };
    let phys: Vec<&str> = header
        .iter()
        .copied()
        .filter(|h| h.starts_with("phys_"))
        .collect();
    assert_eq!(
        phys,
        [
            "phys_dandrea_w",
            "phys_dandrea_headwind_w",
            "phys_dorling_w",
            "phys_stolaroff_w",
            "phys_kirschstein_w",
            "phys_tseng_w",
            "phys_tseng_solo_w"
        ]
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| {
            l.split(',')
                .enumerate()
                .map(|(i, v)| if i == 1 { 0.0 } else { v.parse().unwrap() })
                .collect()
        })
        .collect();
    let (flight, fold, measured) = (col("flight"), col("fold"), col("measured_w"));
    let mut folds = std::collections::BTreeMap::new();
    for r in &rows {
        folds.insert(r[flight] as u32, r[fold] as i64);
    }
    // The test flights are always exported, each in no fold.
    for (f, k) in &folds {
        let test = dronewatt::offline::data::TEST_FLIGHTS.contains(f);
        assert!(test == (*k == -1), "flight {f} fold {k}");
        assert!(
            test || [100, 150, 200].contains(f),
            "flight {f} not asked for"
        );
    }
    assert!(folds.contains_key(&276), "{folds:?}");
    let mut train_folds: Vec<i64> = [100, 150, 200].iter().map(|f| folds[f]).collect();
    train_folds.sort_unstable();
    assert_eq!(
        train_folds,
        [0, 1, 2],
        "three training flights, three folds"
    );
    // A lagged copy is the same flight's sample that many steps back.
    let (speed, speed_lag1) = (col("speed"), col("speed_lag1"));
    let pairs = rows
        .windows(2)
        .filter(|p| {
            p[0][flight] == p[1][flight] && (p[1][col("t_s")] - p[0][col("t_s")] - 0.1).abs() < 1e-3
        })
        .filter(|p| (p[1][speed_lag1] - p[0][speed]).abs() < 1e-4)
        .count();
    assert!(
        pairs > rows.len() * 9 / 10,
        "{pairs} of {} rows",
        rows.len()
    );
    let tseng = col("phys_tseng_w");
    let mut rel: Vec<f64> = rows
        .iter()
        .filter(|r| r[measured] >= 100.0)
        .map(|r| (r[tseng] - r[measured]).abs() / r[measured])
        .collect();
    assert!(rel.len() > 1000, "{} in-flight rows", rel.len());
    rel.sort_by(f64::total_cmp);
    let median = rel[rel.len() / 2];
    assert!(
        median < 0.33,
        "published Tseng's median relative error {median}"
    );
    for p in &phys {
        let c = col(p);
        assert!(rows.iter().all(|r| r[c].is_finite() && r[c] >= 0.0), "{p}");
    }
}

fn smoke_train(out: &std::path::Path, extra: &[&str]) -> std::process::ExitStatus {
    let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_dronewatt-torch"));
    cmd.args([
        "train",
        "--flights",
        "100,150,200,201",
        "--stride",
        "8",
        "--epochs",
        "2",
    ])
    .args([
        "--patience",
        "2",
        "--max-steps",
        "20",
        "--hidden",
        "8",
        "--batch",
        "64",
    ])
    .args(["--seed", "3", "--val-frac", "0.5", "--threads", "1"])
    .args(extra)
    .env("CUDA_VISIBLE_DEVICES", "");
    on_data(&mut cmd, out)
}

/// Run `cmd` on the data set (`DRONEWATT_DATA`), writing into `out`.
fn on_data(cmd: &mut std::process::Command, out: &std::path::Path) -> std::process::ExitStatus {
    cmd.arg("--data")
        .arg(dronewatt::default_data_path())
        .arg("--out")
        .arg(out)
        .status()
        .unwrap()
}

/// One flight of the data set (`DRONEWATT_DATA`), through the ingest path.
fn flight(n: u32, cfg: &TelemetryConfig) -> dronewatt::offline::data::FlightWindows {
    load_flights(
        &dronewatt::default_data_path(),
        Some(&[n]),
        cfg,
        &MissionConfig::default(),
    )
    .unwrap()
    .remove(0)
}
