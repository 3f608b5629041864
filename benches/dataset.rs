//! The whole M100 data set through the live path: CSV (gzip) → MAVLink encoder → tlog bytes
//! → decode → `Telemetry` (state, frames, resampler) → windows. Issue 3's goal: all
//! 247,308 rows in under 20 s on the 2-core CI machine.
//!
//! `DRONEWATT_DATA=/path/flights.csv.gz cargo bench --bench dataset`
//!
//! Measured 2026-11-22 on the shared 2-core machine (load average 13–16 from other
//! builds), with the crate at opt-level 3 on the dev profile's dependencies (opt-level 2):
//! `cargo bench --bench dataset --profile dev --config 'profile.dev.package.dronewatt.opt-level=3'
//! --config 'profile.dev.package.dronewatt.debug-assertions=false'
//! --config 'profile.dev.package.dronewatt.overflow-checks=false'`: all 200 flights
//! (247,308 rows → 371k windows) median 5.16 s; flight 276 alone 1.18 s, most of it
//! gunzipping the whole file.

use criterion::{criterion_group, criterion_main, Criterion};
use dronewatt::offline::data::load_flights;
use dronewatt::telemetry::{MissionConfig, TelemetryConfig};

fn whole_data_set(c: &mut Criterion) {
    let path = dronewatt::default_data_path();
    let cfg = TelemetryConfig::default();
    let mut g = c.benchmark_group("dataset");
    g.sample_size(10);
    g.measurement_time(std::time::Duration::from_secs(60));
    g.bench_function("flight_276", |b| {
        b.iter(|| {
            load_flights(&path, Some(&[276]), &cfg, &MissionConfig::default())
                .expect("data set loads")
        })
    });
    g.bench_function("all_flights", |b| {
        b.iter(|| {
            let f =
                load_flights(&path, None, &cfg, &MissionConfig::default()).expect("data set loads");
            assert_eq!(f.len(), 200);
            f
        })
    });
    g.finish();
}

criterion_group!(benches, whole_data_set);
criterion_main!(benches);
