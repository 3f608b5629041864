//! The BiLSTM learns, saves and reloads through its card, and refuses a card that does not
//! match the ingest path. Synthetic windows: power is a known function of the inputs, so
//! these run without the data set.

use dronewatt::features::{Sample, N_FEATURES};
use dronewatt::model::card::{FeatureSet, ModelCard, TrainingInfo, WeightsFormat};
use dronewatt::model::lstm::{push_inputs, LstmModel};
use dronewatt::model::PowerModel;
use dronewatt::telemetry::window::Window;
use dronewatt::telemetry::TelemetryConfig;
use dronewatt_torch::Net;
use tch::nn::{self, OptimizerConfig};
use tch::{Device, Kind, Tensor};

/// A window whose power depends on payload and the speed history.
fn synthetic_window(i: usize) -> Window {
    let payload = (i % 4) as f32 * 250.0;
    let samples = (0..10)
        .map(|k| {
            let mut f = [0.0f32; N_FEATURES];
            f[9] = ((i * 7 + k) % 13) as f32; // velocity_x
            f[19] = payload;
            f[17] = -9.81;
            let p = 200.0 + 0.1 * payload + 3.0 * f[9];
            Sample {
                t_s: k as f64 * 0.1,
                features: f,
                measured_w: Some(p),
                voltage_v: None,
                home: None,
                stale_mask: 0,
                battery_remaining_pct: None,
                vehicle: Default::default(),
                air: Default::default(),
            }
        })
        .collect();
    Window {
        samples,
        arrived: None,
    }
}

fn card(dir: &std::path::Path, window: usize) -> ModelCard {
    ModelCard {
        format: 1,
        name: "lstm".into(),
        weights: "model.safetensors".into(),
        members: Vec::new(),
        weights_format: WeightsFormat::Safetensors,
        feature_set: FeatureSet::Paper,
        feature_names: FeatureSet::Paper.names(),
        rate_hz: 10.0,
        window,
        feature_mean: vec![0.0; N_FEATURES],
        feature_std: vec![100.0; N_FEATURES],
        power_scale_w: 500.0,
        trees: None,
        target_lag: 0,
        readout: Default::default(),
        band_quantiles: (0.05, 0.95),
        band_widen_w: 0.0,
        band_calibration: Default::default(),
        hidden: 16,
        layers: 2,
        training: TrainingInfo {
            dropout: 0.2,
            ..Default::default()
        },
        metrics: None,
        validation_metrics: None,
    }
    .tap_save(dir)
}

trait TapSave {
    fn tap_save(self, dir: &std::path::Path) -> Self;
}
impl TapSave for ModelCard {
    fn tap_save(self, dir: &std::path::Path) -> Self {
        self.save(&dir.join("card.toml")).unwrap();
        self
    }
}

#[test]
fn network_learns_saves_and_reloads() {
    tch::set_num_threads(1);
    tch::manual_seed(1);
    let windows: Vec<Window> = (0..256).map(synthetic_window).collect();
    let x = standardised(&windows);
    let y = Tensor::from_slice(
        &windows
            .iter()
            .map(|w| w.last().measured_w.unwrap() / 500.0)
            .collect::<Vec<_>>(),
    );
    let mut vs = nn::VarStore::new(Device::Cpu);
    let net = Net::new(&vs.root(), 16, 2, 0.2, None);
    let mut opt = nn::Adam::default().build(&vs, 1e-2).unwrap();
    let mut losses = Vec::new();
    for _ in 0..150 {
        let out = net.forward_t(&x, true);
        let loss = (out.select(1, 0) - &y).abs().mean(Kind::Float);
        opt.backward_step(&loss);
        losses.push(loss.double_value(&[]) * 500.0);
    }
    let (first, last) = (losses[0], *losses.last().unwrap());
    assert!(
        last < first / 3.0,
        "MAE should fall: {first:.1} W → {last:.1} W"
    );

    let dir = tempfile::tempdir().unwrap();
    vs.freeze();
    vs.save(dir.path().join("model.safetensors")).unwrap();
    card(dir.path(), 10);
    let direct = tch::no_grad(|| net.forward_t(&x.narrow(0, 0, 4), false)).select(1, 0) * 500.0;
    let mut model = LstmModel::load(dir.path(), &TelemetryConfig::default()).unwrap();
    let mut out = Vec::new();
    model.predict(&windows[..4], &mut out);
    assert_eq!(out.len(), 4);
    for (i, p) in out.iter().enumerate() {
        let d = direct.double_value(&[i as i64]) as f32;
        assert!(
            (p.power_w - d).abs() < 1e-2,
            "reloaded model disagrees: {} vs {d}",
            p.power_w
        );
        let (lo, hi) = p.band_w.expect("band heads give a band");
        assert!(lo <= p.power_w && p.power_w <= hi);
    }
}

#[test]
fn card_mismatch_names_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let vs = nn::VarStore::new(Device::Cpu);
    let _net = Net::new(&vs.root(), 16, 2, 0.2, None);
    vs.save(dir.path().join("model.safetensors")).unwrap();
    card(dir.path(), 20);
    let err = LstmModel::load(dir.path(), &TelemetryConfig::default())
        .err()
        .expect("window 20 vs 10 must fail");
    let msg = format!("{err:#}");
    assert!(
        msg.contains("window = 20") && msg.contains("telemetry.window = 10"),
        "{msg}"
    );

    // Each mismatch written to the card is refused at load, the message naming it.
    let refused = |c: &ModelCard, tcfg: &TelemetryConfig, what: &str| {
        c.save(&dir.path().join("card.toml")).unwrap();
        let err = LstmModel::load(dir.path(), tcfg).err();
        format!("{:#}", err.unwrap_or_else(|| panic!("{what} must fail")))
    };
    let mut c = card(dir.path(), 10);
    c.feature_names.swap(0, 1);
    let msg = refused(&c, &TelemetryConfig::default(), "swapped names");
    assert!(msg.contains("feature_names[0] is 'wind_angle'"), "{msg}");

    let tcfg = TelemetryConfig {
        rate_hz: 5.0,
        ..Default::default()
    };
    c.feature_names.swap(0, 1);
    let msg = refused(&c, &tcfg, "rate 5 vs 10");
    assert!(
        msg.contains("rate_hz = 10") && msg.contains("telemetry.rate_hz = 5"),
        "{msg}"
    );

    // An instant readout needs the instant inside the window.
    c.readout = dronewatt::model::card::Readout::Instant;
    c.target_lag = 10;
    let msg = refused(
        &c,
        &TelemetryConfig::default(),
        "an instant readout at lag 10 of a 10-sample window",
    );
    assert!(
        msg.contains("readout = \"instant\"") && msg.contains("target_lag (10)"),
        "{msg}"
    );
}

/// A card with `members` runs every member on the kernel and publishes their mean: the
/// point and the band, as libtorch computes each network.
#[test]
fn an_ensemble_publishes_the_members_mean() {
    tch::set_num_threads(1);
    let windows: Vec<Window> = (0..6).map(synthetic_window).collect();
    let x = standardised(&windows);
    let dir = tempfile::tempdir().unwrap();
    let mut direct = Vec::new();
    for (seed, file) in [(3, "a.safetensors"), (4, "b.safetensors")] {
        tch::manual_seed(seed);
        let vs = nn::VarStore::new(Device::Cpu);
        let net = Net::new(&vs.root(), 16, 2, 0.2, None);
        vs.save(dir.path().join(file)).unwrap();
        direct.push(tch::no_grad(|| net.forward_t(&x, false)) * 500.0);
    }
    let mut c = card(dir.path(), 10);
    c.weights = "a.safetensors".into();
    c.members = vec!["b.safetensors".into()];
    c.save(&dir.path().join("card.toml")).unwrap();

    let mut model = LstmModel::load(dir.path(), &TelemetryConfig::default()).unwrap();
    let rows = model.forward_w(&windows).unwrap();
    for (i, row) in rows.iter().enumerate() {
        let mean = |col: i64| {
            (direct[0].double_value(&[i as i64, col]) + direct[1].double_value(&[i as i64, col]))
                as f32
                / 2.0
        };
        assert!(
            (row[0] - mean(0)).abs() < 1e-2,
            "point {} vs the mean {}",
            row[0],
            mean(0)
        );
        assert!(
            (row[1] - mean(1).min(row[0])).abs() < 1e-2,
            "low {} vs {}",
            row[1],
            mean(1)
        );
        assert!(
            (row[2] - mean(2).max(row[0])).abs() < 1e-2,
            "high {} vs {}",
            row[2],
            mean(2)
        );
    }
    // The members differ, so the mean is neither member alone.
    let a = direct[0].double_value(&[0, 0]) as f32;
    assert!(
        (rows[0][0] - a).abs() > 1e-3,
        "the ensemble ran the first member only"
    );

    // A member that is missing is named, not skipped.
    c.members = vec!["gone.safetensors".into()];
    c.save(&dir.path().join("card.toml")).unwrap();
    let msg = format!(
        "{:#}",
        LstmModel::load(dir.path(), &TelemetryConfig::default())
            .err()
            .expect("a missing member must fail")
    );
    assert!(msg.contains("gone.safetensors"), "{msg}");
}

/// The windows' paper inputs `[n, 10, 21]` as the networks see them: the cards here
/// standardise with mean 0 and std 100, so x / 100.
fn standardised(windows: &[Window]) -> Tensor {
    let mut x = Vec::new();
    for w in windows {
        push_inputs(w, FeatureSet::Paper, 10, &mut x);
    }
    Tensor::from_slice(&x).view([windows.len() as i64, 10, N_FEATURES as i64]) / 100.0
}
