//! The shipped model's trees on the CPU path (`src/model/trees.rs`) against LightGBM itself
//! (`tests/peers/lgbm_predict.py`, the `.venv-py` of `scripts/setup-python.sh`), on real
//! windows of the M100 data set (`DRONEWATT_DATA`) built by the ingest path, plus rows of
//! missing and far-out inputs; and the blend the card asks for, against the network alone.
//! `DRONEWATT_TREES_FLIGHTS=all` (or a comma-separated list) checks other flights.

use std::path::{Path, PathBuf};

use dronewatt::features::{idx, N_FEATURES};
use dronewatt::model::card::ModelCard;
use dronewatt::model::lstm::{push_inputs, tree_rows, LstmModel};
use dronewatt::model::trees::Trees;
use dronewatt::model::PowerModel;
use dronewatt::offline::data::{load_flights, FlightWindows};
use dronewatt::telemetry::{MissionConfig, TelemetryConfig};

fn shipped() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("config/models/lstm-m100")
}

/// Training flights of four routes: R4, R1, the A1 ground test and a hover (H).
fn flights(default: &[u32]) -> Vec<FlightWindows> {
    let data = dronewatt::default_data_path();
    assert!(
        data.exists(),
        "no data set at {} (set DRONEWATT_DATA)",
        data.display()
    );
    let want: Option<Vec<u32>> = match std::env::var("DRONEWATT_TREES_FLIGHTS").ok().as_deref() {
        Some("all") => None,
        Some(list) => Some(
            list.split(',')
                .map(|f| f.trim().parse().expect("a flight number"))
                .collect(),
        ),
        None => Some(default.to_vec()),
    };
    let cfg = TelemetryConfig::default();
    load_flights(&data, want.as_deref(), &cfg, &MissionConfig::default()).unwrap()
}

#[test]
fn shipped_trees_match_lightgbm_on_real_windows() {
    let dir = shipped();
    let card = ModelCard::load(&dir.join("card.toml")).unwrap();
    let blend = card.trees.clone().expect("the shipped card blends trees");
    let model = dir.join(&blend.file);
    let trees = Trees::parse(&std::fs::read_to_string(&model).unwrap()).unwrap();
    let n = trees.feature_names().len();
    assert_eq!(n, blend.lags.len() * N_FEATURES);

    let mut rows: Vec<Vec<f64>> = Vec::new();
    let mut buf = Vec::new();
    for f in flights(&[7, 23, 211, 221]) {
        for w in &f.windows {
            buf.clear();
            push_inputs(w, card.feature_set, card.window, &mut buf);
            rows.push(
                tree_rows(&buf, &blend.lags)
                    .flatten()
                    .map(|v| f64::from(*v))
                    .collect(),
            );
        }
    }
    let real = rows.len();
    assert!(real > 5000, "only {real} windows");
    // Nothing known, zeros (the missing value of some splits), and far outside the data.
    for v in [f64::NAN, 0.0, -0.0, 1e9, -1e9, 1e-40] {
        rows.push(vec![v; n]);
    }
    let tmp = tempfile::tempdir().unwrap();
    let csv = tmp.path().join("rows.csv");
    let mut text = trees.feature_names().join(",") + "\n";
    for r in &rows {
        let cells: Vec<String> = r.iter().map(|v| format!("{v:?}")).collect();
        text += &(cells.join(",") + "\n");
    }
    std::fs::write(&csv, text).unwrap();
    let stdout = crate::harness::peer("lgbm_predict.py", [model.as_os_str(), csv.as_os_str()]);
    let theirs: Vec<f64> = String::from_utf8_lossy(&stdout)
        .lines()
        .map(|l| l.parse().expect("a number"))
        .collect();
    assert_eq!(theirs.len(), rows.len());
    let mut worst = 0f64;
    for (i, (r, p)) in rows.iter().zip(&theirs).enumerate() {
        let ours = trees.predict(r);
        let d = (ours - p).abs();
        worst = worst.max(d);
        assert!(
            d <= 1e-9 * p.abs().max(1.0),
            "row {i}: dronewatt {ours} W, LightGBM {p} W"
        );
    }
    eprintln!(
        "{real} real windows and {} edge rows: largest difference {worst:e} W",
        rows.len() - real
    );
}

/// A copy of the shipped model folder in `to`, its card blending the trees or not.
fn copy_model(to: &Path, with_trees: bool) {
    let dir = shipped();
    let mut card = ModelCard::load(&dir.join("card.toml")).unwrap();
    let files = std::iter::once(card.weights.clone())
        .chain(card.members.clone())
        .chain(card.trees.as_ref().map(|t| t.file.clone()));
    for f in files {
        std::fs::copy(dir.join(&f), to.join(&f)).unwrap();
    }
    if !with_trees {
        card.trees = None;
    }
    card.save(&to.join("card.toml")).unwrap();
}

#[test]
fn the_blend_moves_the_networks_estimate_and_band_toward_the_trees_within_range_only() {
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    copy_model(a.path(), true);
    copy_model(b.path(), false);
    let cfg = TelemetryConfig::default();
    let mut blended = LstmModel::load(a.path(), &cfg).unwrap();
    let mut alone = LstmModel::load(b.path(), &cfg).unwrap();
    let card = blended.card().clone();
    let t = card.trees.clone().unwrap();
    let trees = Trees::parse(&std::fs::read_to_string(a.path().join(&t.file)).unwrap()).unwrap();

    let mut windows: Vec<_> = flights(&[7]).remove(0).windows;
    windows.truncate(600);
    // A payload a thousand times the training range's: the network alone there.
    let mut far = windows[300].clone();
    for s in &mut far.samples {
        s.features[idx::PAYLOAD] = 1e6;
    }
    windows.push(far);
    let mixed = blended.forward_w(&windows).unwrap();
    let net = alone.forward_w(&windows).unwrap();
    let mut buf = Vec::new();
    let (mut moved, mut alone_in) = (0, 0);
    for (i, ((m, n), w)) in mixed.iter().zip(&net).zip(&windows).enumerate() {
        if i == windows.len() - 1 {
            assert_eq!(m, n, "outside the training range the network runs alone");
            continue;
        }
        if !blended.in_training_range(w) {
            assert_eq!(
                m, n,
                "window {i}: outside the training range the network runs alone"
            );
            alone_in += 1;
            continue;
        }
        buf.clear();
        push_inputs(w, card.feature_set, card.window, &mut buf);
        let row: Vec<f64> = tree_rows(&buf, &t.lags)
            .flatten()
            .map(|v| f64::from(*v))
            .collect();
        let tree = trees.predict(&row) as f32;
        let w = t.weight_lstm as f32;
        let want = w * n[0] + (1.0 - w) * tree;
        let d = want - n[0];
        assert!(
            (m[0] - want).abs() < 1e-2,
            "window {i}: {} W, expected {want} W",
            m[0]
        );
        assert!(
            (m[1] - (n[1] + d)).abs() < 1e-2 && (m[2] - (n[2] + d)).abs() < 1e-2,
            "window {i}: the band moves with the estimate"
        );
        moved += (d.abs() > 0.1) as usize;
    }
    assert!(moved > 500, "the trees moved only {moved} of 600 estimates");
    eprintln!("flight 7's first 600 windows: the trees moved {moved}; {alone_in} outside the training range");
}

#[test]
fn trees_that_do_not_fit_the_cards_inputs_are_refused_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    copy_model(dir.path(), true);
    let card = ModelCard::load(&dir.path().join("card.toml")).unwrap();
    let file = dir.path().join(&card.trees.unwrap().file);
    let text = std::fs::read_to_string(&file).unwrap();
    let refused = || {
        let e = LstmModel::load(dir.path(), &TelemetryConfig::default()).err();
        format!("{:#}", e.expect("refused"))
    };
    std::fs::write(
        &file,
        text.replacen("feature_names=wind_speed ", "feature_names=wind_sped ", 1),
    )
    .unwrap();
    let err = refused();
    assert!(
        err.contains("trees.txt") && err.contains("input 0 is 'wind_sped'"),
        "{err}"
    );
    std::fs::write(&file, "garbage").unwrap();
    let err = refused();
    assert!(
        err.contains("trees.txt") && err.contains("not a LightGBM text model"),
        "{err}"
    );
}
