//! Online adaptation ([`dronewatt::model::adapt`]) for one window: every model of the live
//! ensemble (the seven physics forms and the LSTM: 8) corrected and taught with the measured
//! power. Goal: ≤ 20 µs a window (it runs on every window, beside the models).

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use dronewatt::model::adapt::{AdaptConfig, Adaptation};
use dronewatt::model::physics::Kind;

fn bench(c: &mut Criterion) {
    // The seven physics models, then the LSTM.
    let names: Vec<String> = Kind::ALL
        .iter()
        .map(|k| k.name().to_string())
        .chain(["lstm".to_string()])
        .collect();
    let mut ad = Adaptation::new(&AdaptConfig::default(), &names, 0.1, 127.0);
    let mut k = 0u32;
    c.bench_function(
        "adapt: 8 models, one window (correct + teach both fits)",
        |b| {
            b.iter(|| {
                k = k.wrapping_add(1);
                let wobble = (k % 100) as f32;
                let measured = 380.0 + wobble;
                let mut sum = 0.0f32;
                for i in 0..names.len() {
                    let raw = 300.0 + 20.0 * i as f32 + wobble;
                    if let Some(a) = ad.step(i, black_box(raw), Some(black_box(measured)), true) {
                        sum += a.adapted_w;
                    }
                }
                sum
            })
        },
    );
}

criterion_group!(benches, bench);
criterion_main!(benches);
