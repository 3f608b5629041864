//! Mission forecast speed. Goals (issue 12): a plan of 500 waypoints forecasts in < 50 ms
//! (fly it on paper + the forecast model along it + energy per leg); a live re-forecast
//! (locate the vehicle from its current item and position, read what is left) < 1 ms.
//! Run: `cargo bench --locked --profile dev --bench mission` (the project's bench profile:
//! opt-level 2, overflow checks on in dronewatt; plain `cargo bench` builds the `bench`
//! profile, which inherits `release`'s opt-level 3, and rebuilds every dependency for it).

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use dronewatt::mission::forecast::{forecast, Calibration};
use dronewatt::mission::plan::{GeoPoint, Plan};
use dronewatt::mission::trajectory::{fly, Conditions, KinematicsConfig, Wind};
use dronewatt::model::PowerModel;

/// 500 waypoints, a survey-like lawnmower of 100 m lines 30 m apart at 30 m, 8 m/s.
fn plan_500() -> Plan {
    let home = GeoPoint {
        lat_deg: 40.44,
        lon_deg: -79.94,
        alt_m: 300.0,
    };
    let m = 1.0 / 111_320.0;
    let wps: Vec<GeoPoint> = (0..500)
        .map(|i| {
            let row = (i / 2) as f64;
            let east = if (i / 2) % 2 == 0 { i % 2 } else { 1 - i % 2 } as f64 * 100.0;
            GeoPoint {
                lat_deg: 40.44 + row * 30.0 * m,
                lon_deg: -79.94 + east * m / 40.44f64.to_radians().cos(),
                alt_m: 30.0,
            }
        })
        .collect();
    Plan::from_waypoints("lawnmower-500", home, &wps, 8.0)
}

fn bench(c: &mut Criterion) {
    let plan = plan_500();
    let k = KinematicsConfig::default();
    let cond = Conditions {
        wind: Wind {
            speed_m_s: 4.0,
            from_deg: 250.0,
        },
        payload_g: 250.0,
        speed_m_s: None,
        rate_hz: 10.0,
    };
    let cal = Calibration::default();
    // The default forecast's members are `_cal` physics models: the calibrated profile's.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("config/vehicles/m100-calibrated.toml");
    let profile = dronewatt::model::profile::VehicleProfile::load(&path)
        .expect("the shipped calibrated profile");
    let mut models: Vec<Box<dyn PowerModel>> = dronewatt::model::physics::models(&profile)
        .into_iter()
        .filter(|m| cal.members.iter().any(|c| c.model == m.name()))
        .collect();
    assert_eq!(models.len(), cal.members.len(), "the default forecast's members are physics models of the published profile or the calibrated one");
    let tr = fly(&plan, &k, &cond);
    eprintln!(
        "500 waypoints: {} samples, {:.0} s of flight",
        tr.samples.len(),
        tr.duration_s()
    );
    c.bench_function("mission: 500-waypoint plan, fly + forecast", |b| {
        b.iter(|| {
            let tr = fly(black_box(&plan), &k, &cond);
            forecast(&tr, &mut models, &cal, 10, dronewatt::mission::MODEL_STRIDE).energy_p50_wh
        })
    });
    // The two halves apart: where the time goes.
    c.bench_function("mission: 500-waypoint plan, fly only", |b| {
        b.iter(|| fly(black_box(&plan), &k, &cond).samples.len())
    });
    c.bench_function("mission: 500-waypoint plan, forecast only", |b| {
        b.iter(|| {
            forecast(
                black_box(&tr),
                &mut models,
                &cal,
                10,
                dronewatt::mission::MODEL_STRIDE,
            )
            .energy_p50_wh
        })
    });
    let f = forecast(&tr, &mut models, &cal, 10, dronewatt::mission::MODEL_STRIDE);
    let item = 300;
    let pos = tr.enu_m[tr.first_sample_of_item(item) + 40];
    c.bench_function("mission: live re-forecast (locate + remaining)", |b| {
        b.iter(|| {
            let from = tr.first_sample_of_item(black_box(item));
            let k = tr.locate(from, 600, black_box(pos));
            f.remaining_from(k, Some(100.0), 1.0).energy_p50_wh
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = bench
}
criterion_main!(benches);
