//! The battery stage for one window ([`dronewatt::energy::pack::Pack::update`]): the
//! equivalent circuit's RLS step on the measured voltage and current, and, once a second of
//! source time (every tenth window at 10 Hz), the loaded-voltage forecast for the rest of the
//! flight and to the low threshold. Goal: ≤ 5 µs a window, the forecast included (averaged
//! over its period); the forecast alone is measured beside it.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use dronewatt::battery::{forecast, CircuitParams, Estimator, OcvCurve};
use dronewatt::energy::pack::{pack_model, Load, Pack};
use dronewatt::report::{BatteryFacts, Provenance, Sourced};

fn bench(c: &mut Criterion) {
    let facts = BatteryFacts::m100();
    let mut pack = Pack::default();
    // Rest 4 s, then fly: the state is started and the forecast runs.
    let mut t = 0.0;
    while t < 10.0 {
        let (v, i) = if t < 4.0 { (24.3, 0.1) } else { (22.0, 20.0) };
        pack.update(t, Some(v), Some(i), Some(Load::constant(450.0)), &facts);
        t += 0.1;
    }
    // A flight of 300 s (3,000 windows) from there, over and over: the pack never runs flat,
    // so every forecast flies the whole rest of the flight, as it does in the air.
    let (template, t0) = (pack.clone(), t);
    let mut k = 0u32;
    c.bench_function(
        "battery: one window (RLS step; the forecast once in ten windows)",
        |b| {
            b.iter(|| {
                k = k.wrapping_add(1);
                if k.is_multiple_of(3000) {
                    pack = template.clone();
                    t = t0;
                }
                t += 0.1;
                let wobble = f64::from(k % 50) * 0.1;
                pack.update(
                    black_box(t),
                    Some(22.0 - 0.01 * wobble),
                    Some(20.0 + wobble),
                    Some(Load::constant(450.0)),
                    &facts,
                )
            })
        },
    );
    let est =
        Estimator::new(CircuitParams::default(), OcvCurve::tb48d(), 24.3, 0.0).expect("a state");
    let profile = vec![(5.0, 450.0); 720];
    c.bench_function(
        "battery: the voltage forecast alone (720 steps of 5 s)",
        |b| b.iter(|| forecast(black_box(&est), black_box(&profile), &[21.0])),
    );

    // A 4S3P Li-ion pack: the sag's growth as it empties (battery::deep) and its learned slope
    // in every forecast step. Flown 200 s first, so the slope's bands hold evidence.
    let li = BatteryFacts {
        cell_count: Sourced::new(4, Provenance::Config),
        capacity_wh: Some(Sourced::new(88.0, Provenance::Config)),
        chemistry: Sourced::new("liion".into(), Provenance::Config),
        ..BatteryFacts::default()
    };
    let (curve, params) = pack_model(&li).expect("a Li-ion pack");
    let mut est = Estimator::new(params, curve, 15.6, 0.0).expect("a state");
    for k in 0..2000 {
        let i = 8.0 + f64::from(k % 20) * 0.1;
        est.update(0.1, i, 15.0 - 0.03 * i - 0.0002 * f64::from(k));
    }
    let mut li_pack = Pack::default();
    let mut t = 0.0;
    while t < 10.0 {
        let (v, i) = if t < 4.0 { (15.6, 0.1) } else { (14.8, 8.0) };
        li_pack.update(t, Some(v), Some(i), Some(Load::constant(120.0)), &li);
        t += 0.1;
    }
    let (template, t0) = (li_pack.clone(), t);
    let mut k = 0u32;
    c.bench_function(
        "battery: one window, 4S3P Li-ion with the deepening sag (the forecast once in ten)",
        |b| {
            b.iter(|| {
                k = k.wrapping_add(1);
                if k.is_multiple_of(3000) {
                    li_pack = template.clone();
                    t = t0;
                }
                t += 0.1;
                let wobble = f64::from(k % 50) * 0.02;
                li_pack.update(
                    black_box(t),
                    Some(14.8 - 0.01 * wobble),
                    Some(8.0 + wobble),
                    Some(Load::constant(120.0)),
                    &li,
                )
            })
        },
    );
    let profile = vec![(5.0, 120.0); 720];
    c.bench_function(
        "battery: one-hour forecast, 4S3P Li-ion with the deepening sag (720 steps of 5 s)",
        |b| b.iter(|| forecast(black_box(&est), black_box(&profile), &[13.2])),
    );
}

criterion_group!(benches, bench);
criterion_main!(benches);
