//! The hand-written LSTM forward ([`dronewatt::model::lstm_cpu`]) on the paper network's weights
//! (2 layers, 128 hidden), no libtorch: per instruction set this CPU has, at batch 1 (the
//! live case), 5 (a remainder tile) and 256 (two full chunks). `torch/benches/lstm.rs`
//! compares the same forward with libtorch's.

use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use dronewatt::model::lstm_cpu::{CpuLstm, Isa};

fn bench(c: &mut Criterion) {
    let path = std::path::Path::new("config/models/lstm-m100-h128/model.safetensors");
    let mut m = CpuLstm::from_safetensors(path, 2, 128)
        .expect("the paper network's weights, config/models/lstm-m100-h128");
    let per = 10 * m.inputs();
    let xs: Vec<f32> = (0..256 * per)
        .map(|i| ((i % 97) as f32 - 48.0) / 32.0)
        .collect();
    let mut out = vec![0.0f32; 256 * m.outputs()];
    let mut g = c.benchmark_group("lstm_cpu");
    g.sample_size(20)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    for isa in Isa::available() {
        m.set_isa(isa);
        for b in [1usize, 5, 256] {
            g.throughput(Throughput::Elements(b as u64));
            let o = b * m.outputs();
            g.bench_with_input(BenchmarkId::new(format!("{isa:?}"), b), &b, |bch, &b| {
                bch.iter(|| m.forward_batch(&xs[..b * per], 10, &mut out[..o]))
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
