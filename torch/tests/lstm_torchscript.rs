//! Bring your own model: a TorchScript module exported by PyTorch (`.venv-bench`, made by
//! `scripts/setup-torch-bench.sh`, where it exists; traced through libtorch otherwise, as
//! in CI, where no importable PyTorch is installed) loads with its card and runs as a
//! PowerModel.

use std::process::Command;

use dronewatt::features::{Sample, N_FEATURES};
use dronewatt::model::card::{FeatureSet, ModelCard, TrainingInfo, WeightsFormat};
use dronewatt::model::lstm::LstmModel;
use dronewatt::model::PowerModel;
use dronewatt::telemetry::window::Window;
use dronewatt::telemetry::TelemetryConfig;

const EXPORT: &str = r#"
import sys, torch
class Tiny(torch.nn.Module):
    def forward(self, x):
        p = torch.tanh(x.mean(dim=(1, 2)) * 0.1)
        return torch.stack([p, p - 0.1, p + 0.1], dim=1)
m = torch.jit.script(Tiny())
m.save(sys.argv[1])
"#;

#[test]
fn torchscript_module_loads_with_its_card() {
    let python = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../.venv-bench/bin/python");
    let dir = tempfile::tempdir().unwrap();
    let pt = dir.path().join("tiny.pt");
    // From a file: TorchScript compiles from the module's source.
    let script = dir.path().join("export.py");
    std::fs::write(&script, EXPORT).unwrap();
    let exported = python.is_file()
        && Command::new(&python)
            .arg(&script)
            .arg(&pt)
            .stderr(std::process::Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
    if exported {
        eprintln!("module exported by PyTorch ({})", python.display());
    } else {
        // No importable PyTorch (`.venv-torch` holds libtorch only); trace the same
        // module through libtorch so the TorchScript loading path is still exercised.
        eprintln!("no PyTorch to export with: tracing the module with libtorch instead");
        let x = tch::Tensor::zeros(
            [2, 10, N_FEATURES as i64],
            (tch::Kind::Float, tch::Device::Cpu),
        );
        let m = tch::CModule::create_by_tracing("Tiny", "forward", &[x], &mut |xs| {
            let p = (xs[0].mean_dim(&[1i64, 2][..], false, tch::Kind::Float) * 0.1).tanh();
            vec![tch::Tensor::stack(&[&p, &(&p - 0.1), &(&p + 0.1)], 1)]
        })
        .unwrap();
        m.save(&pt).unwrap();
    }
    let card = ModelCard {
        format: 1,
        name: "byo".into(),
        weights: "tiny.pt".into(),
        members: Vec::new(),
        weights_format: WeightsFormat::Torchscript,
        feature_set: FeatureSet::Paper,
        feature_names: FeatureSet::Paper.names(),
        rate_hz: 10.0,
        window: 10,
        feature_mean: vec![0.0; N_FEATURES],
        feature_std: vec![1.0; N_FEATURES],
        power_scale_w: 100.0,
        trees: None,
        target_lag: 0,
        readout: Default::default(),
        band_quantiles: (0.05, 0.95),
        band_widen_w: 0.0,
        band_calibration: Default::default(),
        hidden: 0,
        layers: 0,
        training: TrainingInfo::default(),
        metrics: None,
        validation_metrics: None,
    };
    card.save(&dir.path().join("card.toml")).unwrap();
    // Without libtorch (the `dronewatt` binary) the module is refused with the error that
    // hands the command to `dronewatt-torch`.
    let err = LstmModel::load_with(&pt, &TelemetryConfig::default(), None)
        .err()
        .expect("TorchScript needs libtorch");
    assert!(err.is::<dronewatt::model::NeedsLibtorch>(), "{err:#}");
    assert!(format!("{err:#}").contains("dronewatt-torch"), "{err:#}");
    // Load through the weights file path, as `--model tiny.pt` does, with libtorch's loader.
    let mut model = LstmModel::load_with(
        &pt,
        &TelemetryConfig::default(),
        Some(dronewatt_torch::load),
    )
    .unwrap();
    assert!(!model.on_kernel());
    assert_eq!(model.name(), "byo");
    let windows: Vec<Window> = (0..3)
        .map(|i| Window {
            samples: (0..10)
                .map(|k| Sample {
                    t_s: k as f64 * 0.1,
                    features: [(i * 10 + k) as f32; N_FEATURES],
                    measured_w: None,
                    voltage_v: None,
                    home: None,
                    stale_mask: 0,
                    battery_remaining_pct: None,
                    vehicle: Default::default(),
                    air: Default::default(),
                })
                .collect(),
            arrived: None,
        })
        .collect();
    let mut out = Vec::new();
    model.predict(&windows, &mut out);
    assert_eq!(out.len(), 3);
    for (i, p) in out.iter().enumerate() {
        let mean = (0..10).map(|k| (i * 10 + k) as f32).sum::<f32>() / 10.0;
        let want = 100.0 * (mean * 0.1).tanh();
        assert!(
            (p.power_w - want).abs() < 1e-3,
            "window {i}: {} W, want {want} W",
            p.power_w
        );
        // The module's band heads are p ∓ 0.1 before scaling: exactly 10 W either side.
        let (lo, hi) = p.band_w.expect("the module has band heads");
        assert!(
            (lo - (want - 10.0)).abs() < 1e-3,
            "window {i}: band low {lo} W, want {} W",
            want - 10.0
        );
        assert!(
            (hi - (want + 10.0)).abs() < 1e-3,
            "window {i}: band high {hi} W, want {} W",
            want + 10.0
        );
    }

    // End to end: `dronewatt` itself (no libtorch) is asked to replay with this module; it
    // hands the whole command to `dronewatt-torch`, whose estimates carry the module's name.
    let lean =
        std::path::Path::new(env!("CARGO_BIN_EXE_dronewatt-torch")).with_file_name("dronewatt");
    assert!(
        lean.is_file(),
        "{}: not built (cargo test --workspace builds it)",
        lean.display()
    );
    let demo = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../replay/demo.tlog");
    let out = Command::new(&lean)
        .arg("replay")
        .arg(&demo)
        .args(["--speed", "max", "-q", "--json", "-", "--model"])
        .arg(&pt)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "replay with a TorchScript model failed: {stderr}"
    );
    assert!(
        stderr.contains("dronewatt-torch"),
        "the hand-off is logged: {stderr}"
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    let byo = stdout
        .lines()
        .filter(|l| l.contains("\"estimate\"") && l.contains("\"byo\""))
        .count();
    assert!(byo > 1000, "{byo} estimates from the TorchScript model");
}
