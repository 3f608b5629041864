//! Tests of the parent module.

use super::*;

const DT: f64 = 0.1;

fn adaptation() -> Adaptation {
    Adaptation::new(&AdaptConfig::default(), &["m".to_string()], DT, 130.0)
}

/// A deterministic wobble of a hover: raw prediction between 300 and 500 W.
fn raw_at(k: usize) -> f64 {
    400.0 + 100.0 * ((k as f64) * 0.05).sin()
}

#[test]
fn learns_a_new_vehicle_within_a_minute() {
    // The vehicle draws 0.3·P + 20 (a 1 kg quad seen through M100 models).
    let mut ad = adaptation();
    let truth = |x: f64| 0.3 * x + 20.0;
    let mut last = None;
    for k in 0..600 {
        let x = raw_at(k);
        last = ad.step(0, x as f32, Some(truth(x) as f32), true);
    }
    let fit = ad.fits()[0].1.adapted;
    assert!(
        (fit.a - 0.3).abs() < 0.02 && (fit.b_w - 20.0).abs() < 8.0,
        "{fit:?}"
    );
    let got = last.unwrap();
    let want = truth(raw_at(599));
    assert!(
        (f64::from(got.adapted_w) - want).abs() / want < 0.02,
        "{got:?} vs {want}"
    );
}

#[test]
fn motors_off_and_out_of_range_windows_do_not_teach() {
    let mut ad = adaptation();
    // 130 W ideal hover × 30 %: 39 W. A vehicle on the ground drawing 12 W for its
    // electronics while the model predicts a hover.
    for k in 0..300 {
        let a = ad.step(0, raw_at(k) as f32, Some(12.0), true).unwrap();
        assert!(!a.taught);
    }
    // Out of the training range, missing, NaN or absurd measured power: no teaching.
    assert!(!ad.step(0, 400.0, Some(100.0), false).unwrap().taught);
    assert!(!ad.step(0, 400.0, None, true).unwrap().taught);
    assert!(!ad.step(0, 400.0, Some(f32::NAN), true).unwrap().taught);
    assert!(!ad.step(0, 400.0, Some(1e9), true).unwrap().taught);
    assert_eq!(ad.fits()[0].1, ModelFit::default());
    // The raw model passes through untouched while nothing has taught.
    assert_eq!(ad.step(0, 400.0, None, true).unwrap().adapted_w, 400.0);
    // A NaN prediction gives no adapted value at all; an unknown model index neither.
    assert!(ad.step(0, f32::NAN, Some(100.0), true).is_none());
    assert!(ad.step(7, 400.0, Some(100.0), true).is_none());
}

#[test]
fn the_reference_resists_a_sudden_fault_that_the_fast_fit_learns() {
    let mut ad = adaptation();
    // Five minutes of normal flight: measured = raw.
    for k in 0..3000 {
        let x = raw_at(k);
        ad.step(0, x as f32, Some(x as f32), true);
    }
    // A motor starts failing: 30 % more power from now on.
    let mut at_10s = None;
    let mut last = None;
    for k in 3000..3600 {
        let x = raw_at(k);
        let a = ad.step(0, x as f32, Some((1.3 * x) as f32), true).unwrap();
        if k == 3100 {
            at_10s = Some((a, 1.3 * x));
        }
        last = Some((a, 1.3 * x));
    }
    let (a, y) = at_10s.unwrap();
    // 10 s in: the reference has moved a few % of the way at most; the deviation is
    // still ~all of the 30 %.
    let dev_ref = (y - f64::from(a.reference_w)) / y;
    assert!(
        dev_ref > 0.18,
        "reference learned the fault away: {a:?}, measured {y}"
    );
    // A minute in: the published fit has followed (it is a forecast, it should).
    let (a, y) = last.unwrap();
    assert!(
        (y - f64::from(a.adapted_w)).abs() / y < 0.05,
        "fast fit did not follow: {a:?} vs {y}"
    );
    assert!(
        (y - f64::from(a.reference_w)) / y > 0.1,
        "reference followed within a minute: {a:?} vs {y}"
    );
}

#[test]
fn bounds_hold_against_garbage() {
    let mut ad = adaptation();
    // Measured power 40× the prediction, then near zero: the gain stays in its range.
    for k in 0..200 {
        ad.step(0, 10.0, Some(if k % 2 == 0 { 40_000.0 } else { 7.0 }), true);
    }
    let f = ad.fits()[0].1;
    for fit in [f.adapted, f.reference] {
        assert!(
            (0.2..=5.0).contains(&fit.a) && fit.b_w.abs() <= 1000.0,
            "{fit:?}"
        );
    }
}

#[test]
fn a_gain_at_its_bound_gets_the_offset_that_fits_with_it() {
    // A model whose output barely moves and falls while the power climbs (Tseng-Solo in a
    // climb): the unconstrained gain runs far past gain_max. The fit must still put the
    // estimate near the measured level, not at a·x + b with a clamped and b not refitted.
    let mut ad = adaptation();
    for k in 0..300 {
        let x = 330.0 + 0.01 * (k % 7) as f64;
        ad.step(0, x as f32, Some(460.0), true);
    }
    let mut last = None;
    for k in 0..400 {
        let x = 316.0 - 0.01 * (k % 5) as f64;
        last = ad.step(0, x as f32, Some(650.0), true);
    }
    // The free fit wants a gain far below 0 (output down, power up): held at gain_min,
    // the offset is refitted with it. Clamping each on its own gave 0.2·316 + 1000 =
    // 1,063 W here (the free offset is thousands of W).
    let f = ad.fits()[0].1.adapted;
    assert_eq!(f.a, 0.2, "{f:?}");
    let est = f.apply(316.0);
    assert!(
        (560.0..=660.0).contains(&est),
        "{f:?}: {est:.0} W for a 650 W climb after 40 s"
    );
    assert!(
        (560.0..=660.0).contains(&f64::from(last.unwrap().adapted_w)),
        "{last:?}"
    );
}

#[test]
fn box_solve_is_the_constrained_minimum() {
    // Brute force over a grid of the box against the closed form.
    let (m, v) = ([4.0e6, 1.2e4, 40.0], [2.0e7, 5.0e4]);
    let det = m[0] * m[2] - m[1] * m[1];
    let free = (
        (m[2] * v[0] - m[1] * v[1]) / det,
        (m[0] * v[1] - m[1] * v[0]) / det,
    );
    let got = box_solve(m, v, free, (0.2, 5.0), 1000.0);
    let cost = |a: f64, b: f64| {
        m[0] * a * a + 2.0 * m[1] * a * b + m[2] * b * b - 2.0 * (v[0] * a + v[1] * b)
    };
    let mut best = f64::INFINITY;
    for i in 0..=480 {
        for j in 0..=400 {
            best = best.min(cost(
                0.2 + 0.01 * f64::from(i),
                -1000.0 + 5.0 * f64::from(j),
            ));
        }
    }
    assert!(
        cost(got.0, got.1) <= best + 1e-6 * best.abs(),
        "{got:?}: {} vs {best}",
        cost(got.0, got.1)
    );
}

#[test]
fn hover_holds_still_without_windup() {
    // An hour of hover at one constant power: nothing winds up, and a
    // manoeuvre afterwards does not kick the fit away from the truth.
    let mut ad = adaptation();
    for _ in 0..36_000 {
        ad.step(0, 400.0, Some(300.0), true);
    }
    let f = ad.fits()[0].1.adapted;
    assert!((f.apply(400.0) - 300.0).abs() < 1.0, "{f:?}");
    let a = ad.step(0, 600.0, Some(450.0), true).unwrap();
    assert!(a.adapted_w > 300.0 && a.adapted_w < 700.0, "{a:?}");
}

#[test]
fn restores_learned_fits_and_rejects_broken_ones() {
    let mut ad = adaptation();
    for k in 0..600 {
        let x = raw_at(k);
        ad.step(0, x as f32, Some((0.5 * x) as f32), true);
    }
    let learned = ad.fits().to_vec();
    let mut next = adaptation();
    assert_eq!(next.restore(&learned), 1);
    // Both fits start from the stored reference (the whole flight, not its last 30 s).
    let (a_next, a_then) = (
        next.step(0, 400.0, None, true).unwrap(),
        ad.step(0, 400.0, None, true).unwrap(),
    );
    assert_eq!(
        (a_next.adapted_w, a_next.reference_w),
        (a_then.reference_w, a_then.reference_w)
    );
    // A fit outside the bounds (a stored database edited by hand, another config).
    let mut bad = learned.clone();
    bad[0].1.adapted.a = 50.0;
    let mut fresh = adaptation();
    assert_eq!(fresh.restore(&bad), 0);
    assert_eq!(fresh.fits()[0].1, ModelFit::default());
    // A fit for a model that does not run is ignored.
    assert_eq!(fresh.restore(&[("other".into(), learned[0].1)]), 0);
}

#[test]
fn config_checks_name_the_key() {
    let bad = AdaptConfig {
        reference_memory_s: 60.0,
        ..Default::default()
    };
    assert!(bad
        .validate()
        .unwrap_err()
        .contains("models.adapt.reference_memory_s"));
    let bad = AdaptConfig {
        gain_min: 1.5,
        ..Default::default()
    };
    assert!(bad.validate().unwrap_err().contains("gain_min"));
    let bad = AdaptConfig {
        memory_s: f64::NAN,
        ..Default::default()
    };
    assert!(bad
        .validate()
        .unwrap_err()
        .contains("models.adapt.memory_s"));
    assert!(AdaptConfig::default().validate().is_ok());
}

#[test]
fn m100_ideal_hover() {
    // 2.431 kg, 4 × 13-inch props: ~127 W ideal (the M100 hovers at ~300–400 W).
    let p = ideal_hover_w(2.431, 9.81, 1.225, 0.34253);
    assert!((120.0..135.0).contains(&p), "{p}");
}
