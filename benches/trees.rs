//! The shipped model's trees (`config/models/lstm-m100/trees.txt`, LightGBM's text model)
//! on the CPU path ([`dronewatt::model::trees`]): one row, the cost they add to a live
//! window on top of the network's (`torch/benches/lstm.rs` times the two together).

use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use dronewatt::model::card::ModelCard;
use dronewatt::model::trees::Trees;

fn bench(c: &mut Criterion) {
    let dir = std::path::Path::new("config/models/lstm-m100");
    let card = ModelCard::load(&dir.join("card.toml")).expect("the shipped card");
    let t = card.trees.expect("the shipped card blends trees");
    let text = std::fs::read_to_string(dir.join(&t.file)).expect("the shipped trees");
    let trees = Trees::parse(&text).expect("a LightGBM text model");
    // Rows at the training mean, each input nudged per row so the paths differ.
    let n = trees.feature_names().len();
    let rows: Vec<Vec<f64>> = (0..64)
        .map(|r| {
            (0..n)
                .map(|i| {
                    let f = i % card.feature_mean.len();
                    let z = (((r * 31 + i * 7) % 13) as f64 - 6.0) / 3.0;
                    f64::from(card.feature_mean[f]) + z * f64::from(card.feature_std[f])
                })
                .collect()
        })
        .collect();
    let mut g = c.benchmark_group("trees");
    g.sample_size(30)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    let mut k = 0;
    g.bench_function(format!("{} trees, one row", trees.len()), |b| {
        b.iter(|| {
            k = (k + 1) % rows.len();
            trees.predict(&rows[k])
        })
    });
    g.bench_function("parse the text model", |b| b.iter(|| Trees::parse(&text)));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
