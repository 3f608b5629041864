//! Tests of the parent module.

use super::*;
use crate::mission::plan::{GeoPoint, Plan};
use crate::mission::trajectory::{fly, Conditions, KinematicsConfig, Wind};

fn plan(n: usize) -> Plan {
    let home = GeoPoint {
        lat_deg: 40.0,
        lon_deg: -80.0,
        alt_m: 300.0,
    };
    let wps: Vec<GeoPoint> = (0..n)
        .map(|i| GeoPoint {
            lat_deg: 40.0 + 0.001 * (i % 2) as f64,
            lon_deg: -80.0 + 0.001 * i as f64,
            alt_m: 30.0,
        })
        .collect();
    Plan::from_waypoints("zigzag", home, &wps, 8.0)
}

/// `plan` flown on paper at 10 Hz with the default kinematics, in `wind` with `payload_g`.
fn flown(plan: &Plan, payload_g: f64, wind: Wind) -> crate::mission::trajectory::Trajectory {
    fly(
        plan,
        &KinematicsConfig::default(),
        &Conditions {
            wind,
            payload_g,
            speed_m_s: None,
            rate_hz: 10.0,
        },
    )
}

fn run(payload_g: f64, wind: Wind, cal: &Calibration) -> MissionForecast {
    let tr = flown(&plan(6), payload_g, wind);
    let mut models = crate::model::physics::models(&crate::model::profile::VehicleProfile::m100());
    forecast(&tr, &mut models, cal, 10, 5)
}

#[test]
fn energy_adds_up_and_grows_with_payload_and_wind() {
    let cal = Calibration {
        p90_ratio: 1.1,
        ..Calibration::uncorrected("dandrea")
    };
    let f = run(0.0, Wind::default(), &cal);
    assert_eq!(f.model, "dandrea");
    let legs: f64 = f.legs.iter().map(|l| l.energy_p50_wh).sum();
    assert!(
        (legs - f.energy_p50_wh).abs() < 1e-9,
        "legs sum to the whole: {legs} vs {}",
        f.energy_p50_wh
    );
    assert!((f.energy_p90_wh / f.energy_p50_wh - 1.1).abs() < 1e-12);
    let mean_w = f.energy_p50_wh * 3600.0 / f.duration_s;
    assert!(
        (150.0..1500.0).contains(&mean_w),
        "an M100's power: {mean_w} W"
    );
    let heavy = run(500.0, Wind::default(), &cal);
    assert!(
        heavy.energy_p50_wh > f.energy_p50_wh * 1.02,
        "payload costs energy"
    );
    let windy = run(0.0, "8@0".parse().unwrap(), &cal);
    assert!(windy.energy_p50_wh > f.energy_p50_wh, "wind costs energy");
    let scaled = run(
        0.0,
        Wind::default(),
        &Calibration {
            members: vec![Member {
                scale: 1.2,
                ..Member::of("dandrea")
            }],
            ..cal.clone()
        },
    );
    assert!((scaled.energy_p50_wh / f.energy_p50_wh - 1.2).abs() < 1e-9);
}

/// A model with a target lag whose power is a function of the whole window (every
/// sample's time and speed): any window built wrong changes it.
struct WholeWindow;
impl PowerModel for WholeWindow {
    fn name(&self) -> &str {
        "whole_window"
    }
    fn predict(&mut self, windows: &[Window], out: &mut Vec<Prediction>) {
        out.clear();
        out.extend(windows.iter().map(|w| {
            let p = w
                .samples
                .iter()
                .enumerate()
                .map(|(i, s)| (i + 1) as f64 * (s.t_s + f64::from(s.features[idx::VY]).abs()))
                .sum::<f64>();
            Prediction {
                power_w: p as f32,
                band_w: None,
            }
        }));
    }
    fn target_lag(&self) -> usize {
        3
    }
}

#[test]
fn batched_windows_forecast_exactly_what_one_window_at_a_time_does() {
    // The forecast builds its windows in reused batches; the plain way (one window,
    // copied fresh, predicted alone, its power held until the next) must agree exactly,
    // for a plan of more windows than a batch and models of two lags.
    let tr = flown(&plan(60), 250.0, "3@40".parse().unwrap());
    let (t, stride, n) = (10, 5, tr.samples.len());
    assert!(
        n / stride > 2 * BATCH,
        "{n} samples: more windows than two batches"
    );
    let mut models = crate::model::physics::models(&crate::model::profile::VehicleProfile::m100());
    models.push(Box::new(WholeWindow));
    let cal = Calibration::uncorrected("whole_window");
    let f = forecast(&tr, &mut models, &cal, t, stride);
    let last = models.len() - 1;
    for (mi, m) in models.iter_mut().enumerate() {
        let lag = m.target_lag();
        let mut p = vec![0.0f32; n];
        let mut out = Vec::new();
        for j in (0..n).step_by(stride) {
            let end = (j + lag).min(n - 1);
            let samples = (0..t)
                .map(|i| {
                    let mut s = tr.samples[(end + i + 1).saturating_sub(t)].clone();
                    if end + 1 < t {
                        s.t_s = (end as f64 + i as f64 + 1.0 - t as f64) * tr.dt_s;
                    }
                    s
                })
                .collect();
            m.predict(
                &[Window {
                    samples,
                    arrived: None,
                }],
                &mut out,
            );
            p[j..(j + stride).min(n)].fill(out[0].power_w.max(0.0));
        }
        let e = p.iter().map(|&w| f64::from(w)).sum::<f64>() * tr.dt_s / 3600.0;
        let (name, got) = &f.models_raw_wh[mi];
        assert_eq!(name, m.name());
        assert!((got - e).abs() <= 1e-12 * e.abs(), "{name}: {got} vs {e}");
        if mi == last {
            let mut cum = 0.0;
            for (k, &w) in p.iter().enumerate() {
                cum += f64::from(w) * tr.dt_s / 3600.0;
                assert!(
                    (f.cum_p50_wh[k] - cum).abs() <= 1e-12 * cum.abs(),
                    "sample {k}"
                );
            }
        }
    }
}

#[test]
fn a_slanted_climb_costs_its_climb_work() {
    // Take off to 25 m, climb to 100 m on a 400 m leg north (slanted), come back down
    // to 25 m on the way east, return. The work term adds w·m·g·Δh for every metre
    // climbed, vertical or slanted, and nothing for the descent when its weight is 0.
    let home = GeoPoint {
        lat_deg: 40.0,
        lon_deg: -80.0,
        alt_m: 300.0,
    };
    let d = 400.0 / 111_320.0;
    let wps = [
        GeoPoint {
            lat_deg: 40.0 + d,
            lon_deg: -80.0,
            alt_m: 100.0,
        },
        GeoPoint {
            lat_deg: 40.0 + d,
            lon_deg: -80.0 + d,
            alt_m: 25.0,
        },
    ];
    let mut plan = Plan::from_waypoints("slanted", home, &wps, 10.0);
    for it in plan.items.iter_mut() {
        if let crate::mission::plan::ItemKind::Takeoff { alt_m } = &mut it.kind {
            *alt_m = 25.0;
        }
    }
    let tr = flown(&plan, 500.0, Wind::default());
    let slanted = tr
        .samples
        .iter()
        .filter(|s| {
            s.features[idx::VZ] > 0.5 && s.features[idx::VX].hypot(s.features[idx::VY]) > 1.0
        })
        .count();
    assert!(
        slanted as f64 * tr.dt_s > 30.0,
        "the leg north climbs while it flies: {slanted} samples"
    );
    let mut models = crate::model::physics::models(&crate::model::profile::VehicleProfile::m100());
    let base = Calibration::of(Member {
        scale: 0.97,
        ..Member::of("tseng_solo")
    });
    let w = 2.5;
    let with = Calibration::of(Member {
        scale: 0.97,
        climb_work: [w, 0.0],
        ..Member::of("tseng_solo")
    });
    let f0 = forecast(&tr, &mut models, &base, 10, 5);
    let f1 = forecast(&tr, &mut models, &with, 10, 5);
    let m = base.vehicle_kg + 0.5;
    let climb_wh = |h: f64| 0.97 * w * m * 9.81 * h / 3600.0;
    let extra = f1.energy_p50_wh - f0.energy_p50_wh;
    assert!(
        (extra / climb_wh(100.0) - 1.0).abs() < 0.01,
        "25 m take-off + 75 m slanted: {extra} Wh vs {}",
        climb_wh(100.0)
    );
    let leg = |f: &MissionForecast| f.legs[1].energy_p50_wh;
    assert!(
        (leg(&f1) - leg(&f0)) / climb_wh(75.0) - 1.0 < 0.01
            && (leg(&f1) - leg(&f0)) / climb_wh(75.0) - 1.0 > -0.01,
        "the slanted leg itself carries its 75 m"
    );
    assert!(
        (f1.legs[2].energy_p50_wh / f0.legs[2].energy_p50_wh - 1.0).abs() < 1e-9,
        "descending legs unchanged"
    );
    // tseng_solo has no climb term of its own: without the work term a slanted climb is free
    let flat = Plan::from_waypoints(
        "flat",
        home,
        &[
            GeoPoint {
                alt_m: 25.0,
                ..wps[0]
            },
            wps[1],
        ],
        10.0,
    ); // take-off to 25 m
    let tf = flown(&flat, 500.0, Wind::default());
    let ff = forecast(&tf, &mut models, &base, 10, 5);
    assert!(
        (ff.legs[1].energy_p50_wh - f0.legs[1].energy_p50_wh).abs()
            < 0.02 * ff.legs[1].energy_p50_wh
    );
    assert!(
        with.validate().is_ok()
            && Calibration {
                vehicle_kg: 0.0,
                ..with.clone()
            }
            .validate()
            .unwrap_err()
            .contains("vehicle_kg")
    );
}

#[test]
fn the_calibration_table_reads_its_documented_keys_and_names_a_bad_one() {
    // the README's block: plan-eval's fit, the defaults
    let text = "p90_ratio = 1.0363\nlive_weight = 0.25\nvehicle_kg = 2.431\nmembers = [\n\
                { model = \"dorling_cal\", scale = 0.9983, recent_flights = 20, phase_scale = [0.9739, 0.9739, 0.9739], climb_work = [1.6593, 0.0] },\n\
                { model = \"tseng_solo_cal\", scale = 0.9909, recent_flights = 40, phase_scale = [0.9670, 0.9670, 0.9670], climb_work = [1.7320, 0.0] },\n\
                { model = \"tseng_cal\", scale = 0.9987, recent_flights = 20, phase_scale = [1.0042, 1.0042, 1.0042], climb_work = [1.5432, 0.0] },\n\
                { model = \"kirschstein_cal\", scale = 0.9961, recent_flights = 20, phase_scale = [0.9622, 0.9622, 0.9622], climb_work = [1.7957, 0.0] },\n]\n";
    let c: Calibration = toml::from_str(text).unwrap();
    assert_eq!(c, Calibration::default());
    let one: Calibration = toml::from_str("members = [{ model = \"tseng\" }]").unwrap();
    assert_eq!(
        one.members,
        vec![Member::of("tseng")],
        "a key left out keeps its default"
    );
    assert_eq!(one.p90_ratio, Calibration::default().p90_ratio);
    let e = toml::from_str::<Calibration>("model = \"tseng\"")
        .unwrap_err()
        .to_string();
    assert!(e.contains("model"), "{e}");
    let e = toml::from_str::<Calibration>("members = [{ model = \"tseng\", climb_weight = 2 }]")
        .unwrap_err()
        .to_string();
    assert!(e.contains("climb_weight"), "{e}");
    let mut bad = Calibration::default();
    bad.members[2].climb_work = [f64::NAN, 0.0];
    let e = bad.validate().unwrap_err();
    assert!(
        e.contains("forecast.calibration.members[2] (\"tseng_cal\"): climb_work"),
        "{e}"
    );
    assert!(Calibration {
        members: vec![],
        ..Calibration::default()
    }
    .validate()
    .unwrap_err()
    .contains("members: empty"));
}

#[test]
fn the_p50_is_the_mean_of_the_members_that_ran() {
    let single = |m: Member| run(0.0, Wind::default(), &Calibration::of(m)).energy_p50_wh;
    let a = Member {
        scale: 0.9,
        climb_work: [1.5, 0.0],
        ..Member::of("dandrea")
    };
    let b = Member {
        scale: 1.1,
        phase_scale: [1.2, 0.8, 1.0],
        ..Member::of("tseng")
    };
    let both = run(
        0.0,
        Wind::default(),
        &Calibration {
            members: vec![a.clone(), b.clone()],
            ..Calibration::uncorrected("")
        },
    );
    assert_eq!(both.model, "dandrea + tseng");
    assert!((both.energy_p50_wh - 0.5 * (single(a.clone()) + single(b))).abs() < 1e-9);
    // a member whose model did not run is left out, not counted as zero
    let with_ghost = run(
        0.0,
        Wind::default(),
        &Calibration {
            members: vec![a.clone(), Member::of("no_such_model")],
            ..Calibration::uncorrected("")
        },
    );
    assert_eq!(with_ghost.model, "dandrea");
    assert!((with_ghost.energy_p50_wh - single(a)).abs() < 1e-9);
    // none ran: the first model that did, uncorrected
    let none = run(
        0.0,
        Wind::default(),
        &Calibration::uncorrected("no_such_model"),
    );
    assert_eq!(
        none.model,
        crate::model::physics::models(&crate::model::profile::VehicleProfile::m100())[0].name()
    );
    assert!(none.energy_p50_wh > 0.0);
}

#[test]
fn the_live_reforecast_reads_what_is_left() {
    let cal = Calibration {
        p90_ratio: 1.1,
        live_weight: 1.0,
        ..Calibration::uncorrected("dandrea")
    };
    let f = run(0.0, Wind::default(), &cal);
    let n = f.cum_p50_wh.len();
    let r0 = f.remaining_from(0, None, 1.0);
    assert!((r0.energy_p50_wh - f.energy_p50_wh).abs() < 0.01 * f.energy_p50_wh);
    let half = f.remaining_from(n / 2, None, 1.0);
    assert!(half.energy_p50_wh < r0.energy_p50_wh && half.energy_p50_wh > 0.0);
    assert!((half.time_s - f.duration_s / 2.0).abs() < 1.0);
    // a flight drawing 10 % more than forecast so far is forecast 10 % more for the rest
    let done = f.energy_to_wh(n / 2);
    let hot = f.remaining_from(n / 2, Some(done * 1.1), 1.0);
    assert!((hot.energy_p50_wh / half.energy_p50_wh - 1.1).abs() < 1e-9);
    assert_eq!(f.remaining_from(n - 1, None, 1.0).energy_p50_wh, 0.0);
}

#[test]
fn the_live_correction_waits_for_a_quarter_of_the_plan_and_is_bounded() {
    // 10 Wh left of a 20 Wh plan, 10 Wh forecast flown
    assert!((live_scaled(10.0, 12.0, 10.0, 20.0, 0.25) - 10.5).abs() < 1e-12);
    assert!((live_scaled(10.0, 9.0, 10.0, 20.0, 0.25) - 9.75).abs() < 1e-12);
    // clamped at 1.25 × the forecast flown
    assert!((live_scaled(10.0, 30.0, 10.0, 20.0, 1.0) - 12.5).abs() < 1e-12);
    // only the climb flown (under a quarter of the plan), or nothing measured: unchanged
    assert_eq!(live_scaled(18.0, 4.0, 2.0, 20.0, 0.25), 18.0);
    assert_eq!(live_scaled(10.0, 0.0, 10.0, 20.0, 0.25), 10.0);
    assert_eq!(live_scaled(10.0, f64::NAN, 10.0, 20.0, 0.25), 10.0);
}
