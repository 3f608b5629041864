//! LSTM inference speed: one window (the live case: the hand-written forward, and libtorch
//! for comparison) and a batch of 256 (a replay flat out: libtorch), on the shipped model,
//! one thread (`DRONEWATT_BENCH_THREADS` to change libtorch's). Compare with `scripts/bench_torch.py` (PyTorch eager, same weights).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use dronewatt::model::lstm::{resolve_model_path, LstmModel};
use dronewatt::model::PowerModel;
use dronewatt::telemetry::{Sample, TelemetryConfig, N_FEATURES};
use dronewatt::window::Window;

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
            f[9] = 8.0 + (k % 3) as f32;
            f[17] = -9.81;
            f[18] = 10.0;
            f[19] = 250.0;
            f[20] = 50.0;
            Sample { t_s: (i * 10 + k) as f64 * 0.1, features: f, measured_w: None, voltage_v: None, home: None, stale_mask: 0, battery_remaining_pct: None }
        })
        .collect();
    Window { samples }
}

fn bench(c: &mut Criterion) {
    let threads = std::env::var("DRONEWATT_BENCH_THREADS").ok().and_then(|s| s.parse().ok()).unwrap_or(1);
    tch::set_num_threads(threads);
    let path = resolve_model_path(None).expect("no shipped model under config/models/lstm-m100");
    let mut model = LstmModel::load(&path, &TelemetryConfig::default()).expect("load the shipped model");
    let one = vec![window(0)];
    let batch: Vec<Window> = (0..256).map(window).collect();
    let mut out = Vec::new();
    c.bench_function("lstm_single_window", |b| b.iter(|| model.predict(&one, &mut out)));
    model.set_libtorch_only(true);
    c.bench_function("lstm_single_window_libtorch", |b| b.iter(|| model.predict(&one, &mut out)));
    model.set_libtorch_only(false);
    let four: Vec<Window> = (0..4).map(window).collect();
    let mut g = c.benchmark_group("lstm_batch_4");
    g.throughput(Throughput::Elements(4));
    g.bench_function("hand_written", |b| b.iter(|| model.predict(&four, &mut out)));
    model.set_libtorch_only(true);
    g.bench_function("libtorch", |b| b.iter(|| model.predict(&four, &mut out)));
    model.set_libtorch_only(false);
    g.finish();
    let mut g = c.benchmark_group("lstm_batch");
    g.throughput(Throughput::Elements(256));
    g.bench_function("256_windows", |b| b.iter(|| model.predict(&batch, &mut out)));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
