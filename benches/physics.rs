//! All physics models on one window: the live inference stage runs them on every window.
//! Goal: the six models (plus Tseng's Solo form) together in under 5 µs; the fixed-wing
//! model (`model::physics::fixed_wing`) in under 2 µs a window.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use dronewatt::features::{idx, Sample, N_FEATURES};
use dronewatt::model::physics::{Kind, PhysicsModel};
use dronewatt::model::profile::VehicleProfile;
use dronewatt::telemetry::window::Window;

fn cruise_window() -> Window {
    let samples = (0..10)
        .map(|i| {
            let mut f = [0.0f32; N_FEATURES];
            // Cruise at ~10 m/s, 9° nose-down about body x, heading 30°, 500 g payload.
            let (h, p) = (0.26f32, 0.078f32);
            f[idx::QW] = h.cos() * p.cos();
            f[idx::QX] = h.cos() * p.sin();
            f[idx::QY] = h.sin() * p.sin();
            f[idx::QZ] = h.sin() * p.cos();
            f[idx::VX] = 0.3;
            f[idx::VY] = 9.8 + 0.02 * i as f32;
            f[idx::VZ] = 0.1;
            f[idx::WIND_SPEED] = 11.2;
            f[idx::WIND_ANGLE] = 312.0;
            f[idx::PAYLOAD] = 500.0;
            f[idx::AZ] = -9.8;
            Sample {
                t_s: 0.1 * i as f64,
                features: f,
                measured_w: Some(500.0),
                voltage_v: Some(22.0),
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
    let w = cruise_window();
    let models: Vec<PhysicsModel> = Kind::ALL
        .iter()
        .map(|&k| PhysicsModel::new(k, VehicleProfile::m100()))
        .collect();
    c.bench_function("physics: all models, one window", |b| {
        b.iter(|| models.iter().map(|m| m.power_w(black_box(&w))).sum::<f64>())
    });
}

/// A plane's window: the cruise above, flown by a fixed-wing with an airspeed sensor, a
/// 20° bank and the air's temperature.
fn fixed_wing(c: &mut Criterion) {
    use dronewatt::features::{AirData, VehicleClass, VehicleKind};
    use dronewatt::model::physics::fixed_wing::{FixedWing, Params};
    use dronewatt::model::PowerModel;
    let mut w = cruise_window();
    for s in &mut w.samples {
        s.vehicle = VehicleKind {
            class: VehicleClass::FixedWing,
            mav_type: Some(1),
            ..Default::default()
        };
        s.air = AirData {
            airspeed_m_s: Some(14.0),
            airspeed_sensor: true,
            wind_airspeed_m_s: Some(13.5),
            temperature_c: Some(18.0),
            throttle_pct: None,
        };
        s.features[idx::POS_Z] = 420.0;
    }
    let windows = vec![w];
    let mut model = FixedWing::new(Params::default());
    let mut out = Vec::with_capacity(1);
    c.bench_function("physics: fixed_wing, one window", |b| {
        b.iter(|| {
            model.predict(black_box(&windows), &mut out);
            out[0].power_w
        })
    });
}

criterion_group!(benches, bench, fixed_wing);
criterion_main!(benches);
