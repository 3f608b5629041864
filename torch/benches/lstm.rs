//! LSTM inference speed on the shipped model, one thread (`DRONEWATT_BENCH_THREADS` to
//! change libtorch's): the hand-written batched forward (src/model/lstm_cpu.rs, the CPU
//! path for every batch size) against libtorch on the same weights, per window at batch
//! 1 (the live case), 4, 32, 256 and 1024 (a fleet's windows falling due together, a
//! replay flat out). Criterion's throughput is windows, so it prints windows/s; the time
//! per window is the iteration time over the batch size. Compare with
//! `scripts/bench_torch.py` (PyTorch eager, same weights). `DRONEWATT_BENCH_MODEL=DIR`
//! benches another model folder (an ensemble runs every member).

use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use dronewatt::features::{Sample, N_FEATURES};
use dronewatt::model::lstm::{resolve_model_path, LstmModel};
use dronewatt::model::PowerModel;
use dronewatt::telemetry::window::Window;
use dronewatt::telemetry::TelemetryConfig;

/// A plausible in-flight window (values near the data set's means).
fn window(i: usize) -> Window {
    let samples = (0..10)
        .map(|k| {
            let mut f = [0.0f32; N_FEATURES];
            f[0] = 5.0 + (i % 7) as f32;
            f[2] = -79.78;
            f[3] = 40.46;
            f[4] = 290.0 + k as f32 * 0.1;
            f[8] = 1.0;
            f[10] = 4.0 + (k % 3) as f32;
            f[17] = -9.81;
            f[18] = 10.0;
            f[19] = 250.0;
            f[20] = 50.0;
            Sample {
                t_s: (i * 10 + k) as f64 * 0.1,
                features: f,
                measured_w: None,
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

fn bench(c: &mut Criterion) {
    let threads = std::env::var("DRONEWATT_BENCH_THREADS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    tch::set_num_threads(threads);
    // DRONEWATT_BENCH_MODEL: another model folder (a candidate, an ensemble) instead. Cargo
    // runs a bench in its package's folder (torch/), so a relative path that is not there is
    // read from the workspace root, as the docs write it (`config/models/lstm-m100-h128`).
    let other = std::env::var_os("DRONEWATT_BENCH_MODEL")
        .map(std::path::PathBuf::from)
        .map(|p| {
            let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
            if p.is_relative() && !p.exists() {
                root.join(p)
            } else {
                p
            }
        });
    let path = resolve_model_path(other.as_deref())
        .expect("no shipped model under config/models/lstm-m100");
    let kernel =
        LstmModel::load(&path, &TelemetryConfig::default()).expect("load the shipped model");
    let torch = LstmModel::load_with(
        &path,
        &TelemetryConfig::default(),
        Some(dronewatt_torch::load_on_libtorch),
    )
    .expect("load the shipped model on libtorch");
    let windows: Vec<Window> = (0..1024).map(window).collect();
    // In the training range, so a card's trees (`[trees]`) run too and are timed with it.
    assert!(windows.iter().all(|w| kernel.in_training_range(w)));
    let mut models = [("hand_written", kernel), ("libtorch", torch)];
    let mut out = Vec::new();
    let mut g = c.benchmark_group("lstm_batch");
    g.sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    for b in [1usize, 4, 32, 256, 1024] {
        g.throughput(Throughput::Elements(b as u64));
        for (name, model) in &mut models {
            g.bench_with_input(BenchmarkId::new(*name, b), &windows[..b], |bch, ws| {
                bch.iter(|| model.predict(ws, &mut out))
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
