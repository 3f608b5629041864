use super::*;
use crate::features::{AirData, VehicleClass, VehicleKind, N_FEATURES};

/// A plane flying north (body forward = the data set's velocity_y) at `ground` m/s, at
/// `alt` m above sea level, banked `roll_deg`, climbing `vz` m/s, with this air data.
fn sample(ground: f32, alt: f32, roll_deg: f64, vz: f32, air: AirData) -> Sample {
    let mut f = [0.0f32; N_FEATURES];
    // FRD→NED roll about north, heading north, then into the data set's RFU→ENU.
    let q = frames::ned_to_ds(frames::quat_from_euler(roll_deg.to_radians(), 0.0, 0.0));
    f[idx::QW] = q[0] as f32;
    f[idx::QX] = q[1] as f32;
    f[idx::QY] = q[2] as f32;
    f[idx::QZ] = q[3] as f32;
    f[idx::VY] = ground;
    f[idx::VZ] = vz;
    f[idx::POS_Z] = alt;
    Sample {
        vehicle: VehicleKind {
            class: VehicleClass::FixedWing,
            mav_type: Some(1),
            ..Default::default()
        },
        air,
        ..Sample::new(1.0, f, None)
    }
}

fn sensor(v: f32) -> AirData {
    AirData {
        airspeed_m_s: Some(v),
        airspeed_sensor: true,
        ..Default::default()
    }
}

#[test]
fn hand_computed_level_cruise_turn_and_climb() {
    let mut m = FixedWing::new(Params::default());
    // ρ = 101325 / (287.053 × 288.15) = 1.22500 kg/m³. AR = 1.8² / 0.36 = 9.
    // Parasitic ½·1.225·14³·0.36·0.035 = 21.177 W; induced 2·(2·9.80665)²/(1.225·14·0.36·π·0.78·9)
    // = 5.650 W; (21.177 + 5.650) / 0.5 + 5 = 58.654 W.
    let p = m.predict_one(&sample(14.0, 0.0, 0.0, 0.0, sensor(14.0)));
    assert!((p - 58.654).abs() < 0.01, "{p}");
    // A 60° bank: n = 2, the induced term × 4: (21.177 + 22.602) / 0.5 + 5 = 92.557 W.
    let p = m.predict_one(&sample(14.0, 0.0, 60.0, 0.0, sensor(14.0)));
    assert!((p - 92.557).abs() < 0.05, "{p}");
    // Climbing 2 m/s: + 2·9.80665·2 / 0.5 = + 78.453 W.
    let p = m.predict_one(&sample(14.0, 0.0, 0.0, 2.0, sensor(14.0)));
    assert!((p - 137.108).abs() < 0.01, "{p}");
    // A steep glide: the motor draws nothing; the avionics still do.
    let p = m.predict_one(&sample(14.0, 0.0, 0.0, -5.0, sensor(14.0)));
    assert!((p - 5.0).abs() < 1e-9, "{p}");
    // Standing on the ground: the avionics.
    let p = m.predict_one(&sample(0.0, 0.0, 0.0, 0.0, sensor(0.0)));
    assert!((p - 5.0).abs() < 1e-9, "{p}");
    assert_eq!(m.sensor_failures(), 0);
}

#[test]
fn density_follows_altitude_and_temperature() {
    assert!((air_density(0.0, None) - 1.2250).abs() < 1e-4);
    // ISA at 1000 m: T = 281.65 K, p = 89 876 Pa → 1.1116 kg/m³.
    assert!((air_density(1000.0, None) - 1.1116).abs() < 1e-4);
    // 30 °C at sea level: 101325 / (287.053 × 303.15) = 1.1644 kg/m³.
    assert!((air_density(0.0, Some(30.0)) - 1.1644).abs() < 1e-4);
    // A temperature out of any air's range is not taken; nor a NaN altitude.
    assert_eq!(air_density(0.0, Some(400.0)), air_density(0.0, None));
    assert_eq!(air_density(f64::NAN, None), air_density(0.0, None));
}

#[test]
fn airspeed_zero_in_forward_flight_is_a_counted_sensor_failure_not_a_stall() {
    let mut m = FixedWing::new(Params::default());
    let broken = AirData {
        airspeed_m_s: Some(0.0),
        airspeed_sensor: true,
        wind_airspeed_m_s: Some(14.0),
        temperature_c: None,
        throttle_pct: None,
    };
    let s = sample(12.0, 0.0, 0.0, 0.0, broken);
    assert_eq!(airspeed(&s), (14.0, AirspeedFrom::Wind, true));
    let p = m.predict_one(&s);
    assert!((p - 58.654).abs() < 0.01, "flown on the WIND airspeed: {p}");
    m.predict_one(&s);
    assert_eq!(m.sensor_failures(), 2);
    // Without WIND either: the ground speed, still counted.
    let alone = AirData {
        wind_airspeed_m_s: None,
        ..broken
    };
    assert_eq!(
        airspeed(&sample(12.0, 0.0, 0.0, 0.0, alone)),
        (12.0, AirspeedFrom::Ground, true)
    );
}

#[test]
fn missing_airspeed_falls_back_in_order() {
    // No sensor: the WIND airspeed beats the autopilot's own estimate.
    let both = AirData {
        airspeed_m_s: Some(13.0),
        airspeed_sensor: false,
        wind_airspeed_m_s: Some(15.0),
        temperature_c: None,
        throttle_pct: None,
    };
    assert_eq!(
        airspeed(&sample(12.0, 0.0, 0.0, 0.0, both)),
        (15.0, AirspeedFrom::Wind, false)
    );
    let estimate = AirData {
        wind_airspeed_m_s: None,
        ..both
    };
    assert_eq!(
        airspeed(&sample(12.0, 0.0, 0.0, 0.0, estimate)),
        (13.0, AirspeedFrom::Estimate, false)
    );
    assert_eq!(
        airspeed(&sample(12.0, 0.0, 0.0, 0.0, AirData::default())),
        (12.0, AirspeedFrom::Ground, false)
    );
}

#[test]
fn the_defaults_pass_their_own_checks_and_bad_figures_name_the_key() {
    Params::default().validate().unwrap();
    let bad = Params {
        oswald_e: 1.5,
        ..Params::default()
    };
    assert!(bad.validate().unwrap_err().contains("fixed_wing.oswald_e"));
}

/// Whatever the telemetry says (NaN, infinities, the largest floats, negative speeds, a
/// sensor stuck at any value, any bank), the model gives a finite power no lower than the
/// avionics: every combination of the edge values (proptest is not a dependency of this
/// crate; the edge cases are few enough to try them all).
#[test]
fn finite_and_never_below_the_offset_on_any_input() {
    let edges = [
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::MAX,
        -f32::MAX,
        f32::MIN_POSITIVE,
        0.0,
        -1.0,
        0.5,
        2.9,
        14.0,
        250.0,
    ];
    let opt = |i: usize| (i < edges.len()).then(|| edges[i]);
    let mut m = FixedWing::new(Params::default());
    let mut n = 0u64;
    for (gi, &ground) in edges.iter().enumerate() {
        for &alt in &[f32::NAN, -1e6, 0.0, 420.0, 1e9] {
            for &roll in &[0.0, 45.0, 89.9, 90.0, 180.0, -300.0, f64::NAN] {
                for &vz in &[f32::NAN, -1e9, -3.0, 0.0, 2.0, f32::INFINITY] {
                    for ai in 0..=edges.len() {
                        for sensor in [false, true] {
                            let air = AirData {
                                airspeed_m_s: opt(ai),
                                airspeed_sensor: sensor,
                                wind_airspeed_m_s: opt((ai + gi) % (edges.len() + 1)),
                                temperature_c: opt((ai * 7 + gi) % (edges.len() + 1)),
                                throttle_pct: None,
                            };
                            let p = m.predict_one(&sample(ground, alt, roll, vz, air));
                            assert!(
                                (5.0..1e6).contains(&p),
                                "{p} W from ground {ground}, alt {alt}, roll {roll}, vz {vz}, {air:?}"
                            );
                            n += 1;
                        }
                    }
                }
            }
        }
    }
    assert!(n > 60_000, "{n} cases");
}

#[test]
fn the_model_is_its_own_regression_where_the_motor_pulls() {
    let mut m = FixedWing::new(Params::default());
    let window = |s: Sample| Window {
        samples: vec![s],
        arrived: None,
    };
    for (roll, vz) in [(0.0, 0.0), (35.0, 1.5), (10.0, -0.5)] {
        let s = sample(14.0, 420.0, roll, vz, sensor(13.0));
        let (phi, theta0) = m.regressors(&window(s.clone())).expect("flying, motor on");
        let linear: f64 = (0..4).map(|k| theta0[k] * phi[k]).sum();
        let p = m.predict_one(&s);
        assert!((linear - p).abs() < 1e-9 * p, "{linear} vs {p}");
    }
    // On the ground and in a steep glide the model is its floor, not θ·φ.
    assert!(m
        .regressors(&window(sample(0.0, 0.0, 0.0, 0.0, sensor(0.0))))
        .is_none());
    assert!(m
        .regressors(&window(sample(14.0, 0.0, 0.0, -5.0, sensor(14.0))))
        .is_none());
}

#[test]
fn a_profile_carries_its_plane_and_its_class() {
    use crate::model::profile::VehicleProfile;
    let mut text = toml::to_string(&VehicleProfile::m100()).unwrap();
    text = text.replacen("[vehicle]\n", "[vehicle]\nclass = \"fixed_wing\"\n", 1);
    text.push_str("\n[fixed_wing]\nmass_kg = 2.4\nwing_area_m2 = 0.42\nspan_m = 2.0\n");
    let p = VehicleProfile::from_toml(&text, "plane.toml").unwrap();
    assert_eq!(p.vehicle.class, Some(VehicleClass::FixedWing));
    let w = p.fixed_wing.unwrap();
    // What the section leaves out is the generic plane's.
    assert_eq!((w.mass_kg, w.wing_area_m2, w.span_m), (2.4, 0.42, 2.0));
    assert_eq!(w.cd0, Params::default().cd0);
    // An unknown key is an error.
    let bad = format!("{text}wingspan = 3.0\n");
    assert!(VehicleProfile::from_toml(&bad, "plane.toml").is_err());
}

/// 10 samples at 10 Hz of a plane on heading `yaw(t)` (deg, NED) with ground velocity
/// `v(t)` = (right, forward) in the heading frame, and airspeed sensor `air(t)`.
fn flight_window(
    yaw: impl Fn(f64) -> f64,
    v: impl Fn(f64) -> (f32, f32),
    air: impl Fn(f64) -> f32,
) -> Window {
    let samples = (0..10)
        .map(|i| {
            let t = i as f64 * 0.1;
            let mut s = sample(0.0, 0.0, 0.0, 0.0, sensor(air(t)));
            let q = frames::ned_to_ds(frames::quat_from_euler(0.0, 0.0, yaw(t).to_radians()));
            for (k, x) in [idx::QW, idx::QX, idx::QY, idx::QZ].into_iter().zip(q) {
                s.features[k] = x as f32;
            }
            let (right, fwd) = v(t);
            s.features[idx::VX] = right;
            s.features[idx::VY] = fwd;
            s.t_s = 100.0 + t;
            s
        })
        .collect();
    Window {
        samples,
        arrived: None,
    }
}

#[test]
fn the_kinetic_energy_rate_is_paid_for_and_turns_and_gusts_are_not() {
    let mut m = FixedWing::new(Params::default());
    let rho = air_density(0.0, None);
    // Heading east, the ground speed 14 → 15 m/s over the window's 0.9 s: V̇ = 1.111 m/s²,
    // the energy climb rate V·V̇/g = 15 × 1.111 / 9.80665 = 1.699 m/s: +66.6 W at η 0.5.
    let w = flight_window(|_| 90.0, |t| (0.0, (14.0 + t / 0.9) as f32), |_| 15.0);
    let a = path_acceleration(&w);
    assert!((a - 1.0 / 0.9).abs() < 1e-4, "{a}");
    let want = power_w(&Params::default(), rho, 15.0, 1.0, 2.0, 15.0 * a / G);
    let p = m.predict_window(&w);
    assert!(
        (p - want).abs() < 1e-6 && p - m.predict_one(w.last()) > 60.0,
        "{p} vs {want}"
    );
    // The window's regressors carry the same term: θ₀·φ is the prediction.
    let (phi, theta0) = m.regressors(&w).expect("flying, motor on");
    let linear: f64 = (0..4).map(|k| theta0[k] * phi[k]).sum();
    assert!((linear - p).abs() < 1e-9 * p, "{linear} vs {p}");
    // A steady turn at 0.3 rad/s in calm air: the velocity turns, its size does not.
    let w = flight_window(|t| 30.0 + 17.19 * t, |_| (0.0, 15.0), |_| 15.0);
    assert!(path_acceleration(&w).abs() < 1e-6);
    // A loiter in a 5 m/s wind from the north at 15 m/s of airspeed: the ground speed swings
    // (forward 15 − 5·cos ψ, right 5·sin ψ), the airspeed does not: nothing to pay for.
    let psi = |t: f64| (200.0 + 17.19 * t).to_radians();
    let w = flight_window(
        |t| psi(t).to_degrees(),
        |t| {
            (
                (5.0 * psi(t).sin()) as f32,
                (15.0 - 5.0 * psi(t).cos()) as f32,
            )
        },
        |_| 15.0,
    );
    assert!(
        path_acceleration(&w).abs() < 1e-4,
        "{}",
        path_acceleration(&w)
    );
    // A gust: the airspeed jumps 14 → 18 m/s, the ground velocity (the state) has not moved
    // yet: no kinetic energy paid for.
    let w = flight_window(
        |_| 0.0,
        |_| (0.0, 14.0),
        |t| if t < 0.5 { 14.0 } else { 18.0 },
    );
    assert_eq!(path_acceleration(&w), 0.0);
    // Garbage: a NaN velocity, a window of one sample, a window with no time: finite, bounded.
    let w = flight_window(
        |_| 0.0,
        |t| (0.0, if t > 0.5 { f32::NAN } else { 1e30 }),
        |_| 15.0,
    );
    let a = path_acceleration(&w);
    assert!(a.is_finite() && a.abs() <= 2.0 * G, "{a}");
    assert!(m.predict_window(&w).is_finite());
    let mut one = flight_window(|_| 0.0, |t| (0.0, (14.0 + t) as f32), |_| 15.0);
    one.samples.truncate(1);
    assert_eq!(path_acceleration(&one), 0.0);
    let mut still = flight_window(|_| 0.0, |t| (0.0, (14.0 + t) as f32), |_| 15.0);
    for s in &mut still.samples {
        s.t_s = 5.0;
    }
    assert_eq!(path_acceleration(&still), 0.0);
}
