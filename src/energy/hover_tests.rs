use super::*;

fn reference() -> HoverReference {
    HoverReference {
        ideal_w: 100.0,
        avionics_w: 8.0,
        prior_eta: 0.4,
        mass_kg: 2.0,
        eta_per_ln_mass: 0.0,
    }
}

/// Climb for 10 s, then `hover_s` still at `hover_w`, then cruise at 10 m/s and 2× the
/// power, 10 Hz; the news and the time it came.
fn fly(
    c: &mut HoverCalibrator,
    hover_s: f64,
    hover_w: f64,
    cruise_s: f64,
) -> Vec<(f64, HoverNews)> {
    let mut out = Vec::new();
    let mut t = 0.0;
    let mut step = |t: f64, h: f64, v: f64, vz: f64, p: f64, out: &mut Vec<(f64, HoverNews)>| {
        if let Some(n) = c.observe(t, Some(h), v, vz, None, Some(p)) {
            out.push((t, n));
        }
    };
    for i in 0..100 {
        step(t, f64::from(i) * 0.3, 0.0, 3.0, 300.0, &mut out);
        t += 0.1;
    }
    for _ in 0..(hover_s * 10.0) as usize {
        step(t, 30.0, 0.2, 0.05, hover_w, &mut out);
        t += 0.1;
    }
    for _ in 0..(cruise_s * 10.0) as usize {
        step(t, 30.0, 10.0, 0.0, 2.0 * hover_w, &mut out);
        t += 0.1;
    }
    out
}

#[test]
fn thirty_seconds_of_hover_set_the_efficiency() {
    let mut c = HoverCalibrator::new(Ok(reference()), true);
    let news = fly(&mut c, 60.0, 208.0, 10.0);
    assert_eq!(news.len(), 1, "{news:?}");
    let (t, HoverNews::Calibrated(cal)) = news[0] else {
        panic!("{news:?}")
    };
    // settled 3 s into the hover, then 30 s averaged: at 10 + 33 s
    assert!((t - 43.0).abs() < 0.3, "{t}");
    assert!((cal.hover_w - 208.0).abs() < 1e-9);
    assert!(
        (cal.eta_h - 0.5).abs() < 1e-9,
        "100 W ideal over 200 W: {cal:?}"
    );
    assert!((cal.hover_s - 30.0).abs() < 0.15);
    assert!(cal.applied);
    // the member's powers rescale by 0.4/0.5, the avionics stay
    assert!((cal.power_w(258.0) - (250.0 * 0.8 + 8.0)).abs() < 1e-9);
    // an energy over an hour: 8 Wh of avionics unscaled
    assert!((cal.energy_wh(108.0, 3600.0) - (100.0 * 0.8 + 8.0)).abs() < 1e-9);
    assert_eq!(c.calibration(), Some(&cal));
    // nothing more after it
    assert!(c
        .observe(200.0, Some(30.0), 0.0, 0.0, None, Some(50.0))
        .is_none());
}

#[test]
fn a_hover_flown_with_a_payload_is_the_loaded_mass_s_efficiency() {
    // 2 kg with 0.5 kg on board: the ideal power is 100 W × 1.25^1.5 = 139.75 W, so a
    // hover of 139.75 / 0.5 + 8 W is η_h 0.5 (the unloaded mass's ideal would read 0.358,
    // and every forecast with the payload would pay for the payload twice)
    let r = reference();
    let ideal = 100.0 * 1.25_f64.powf(1.5);
    assert!((r.ideal_at(0.5) - ideal).abs() < 1e-9);
    assert!((r.ideal_at(f64::NAN) - 100.0).abs() < 1e-9);
    let mut c = HoverCalibrator::new(Ok(r), true);
    c.set_payload_kg(0.5);
    let news = fly(&mut c, 60.0, ideal / 0.5 + 8.0, 10.0);
    let [(_, HoverNews::Calibrated(cal))] = news.as_slice() else {
        panic!("{news:?}")
    };
    assert!((cal.eta_h - 0.5).abs() < 1e-9, "{cal:?}");
    assert!((cal.payload_kg - 0.5).abs() < 1e-12);
    // a member whose η grows with the mass (a spec sheet's, d ln η / d ln m 0.25): the
    // same hover is η 0.5 at the loaded 2.5 kg, 0.5 / 1.25^0.25 = 0.4729 at the take-off 2 kg
    let grows = HoverReference {
        eta_per_ln_mass: 0.25,
        ..reference()
    };
    let eta = grows.eta_at(ideal / 0.5 + 8.0, 0.5).unwrap();
    assert!((eta - 0.5 / 1.25f64.powf(0.25)).abs() < 1e-9, "{eta}");
    assert!((grows.eta_at(208.0, 0.0).unwrap() - 0.5).abs() < 1e-9);
    // a checkpoint written before the mass was kept: the unloaded ideal, as then
    let old = HoverReference {
        mass_kg: 0.0,
        ..reference()
    };
    assert!((old.ideal_at(0.5) - 100.0).abs() < 1e-9);
}

#[test]
fn a_hover_of_twenty_seconds_calibrates_when_it_ends() {
    let mut c = HoverCalibrator::new(Ok(reference()), false);
    let news = fly(&mut c, 20.0, 208.0, 10.0);
    let [(t, HoverNews::Calibrated(cal))] = news.as_slice() else {
        panic!("{news:?}")
    };
    assert!((*t - 30.0).abs() < 0.3, "at the hover's end: {t}");
    assert!((cal.hover_s - 17.0).abs() < 0.15, "{cal:?}");
    assert!(!cal.applied);
}

#[test]
fn straight_into_cruise_is_no_hover_and_says_so() {
    let mut c = HoverCalibrator::new(Ok(reference()), true);
    // a 10 s pause is too short; then cruise past the search
    let news = fly(&mut c, 10.0, 208.0, 200.0);
    let [(t, HoverNews::NoHover(why))] = news.as_slice() else {
        panic!("{news:?}")
    };
    assert!(why.contains("no hover") && why.contains("cruise"), "{why}");
    assert!(*t > 180.0 && *t < 200.0, "{t}");
    assert!(matches!(c.state(), HoverState::None(_)));
    assert!(c.calibration().is_none());
}

#[test]
fn on_the_ground_nothing_counts() {
    let mut c = HoverCalibrator::new(Ok(reference()), true);
    for i in 0..2000 {
        // still, drawing power, but on the ground (and without a home)
        let h = if i % 2 == 0 { Some(0.5) } else { None };
        assert!(c
            .observe(f64::from(i) * 0.1, h, 0.0, 0.0, None, Some(200.0))
            .is_none());
    }
    assert_eq!(c.state(), &HoverState::Searching);
}

#[test]
fn a_power_momentum_theory_cannot_give_is_refused() {
    let mut c = HoverCalibrator::new(Ok(reference()), true);
    // 60 W: below the 100 W ideal
    let news = fly(&mut c, 40.0, 60.0, 1.0);
    let [(_, HoverNews::NoHover(why))] = news.as_slice() else {
        panic!("{news:?}")
    };
    assert!(why.contains("60 W") && why.contains("100 W ideal"), "{why}");
}

#[test]
fn a_plane_has_no_hover_to_calibrate() {
    let plane = VehicleProfile::named_or_file("plane").unwrap();
    let why = HoverReference::of(&plane).unwrap_err();
    assert!(why.contains("does not hover"), "{why}");
    let mut c = HoverCalibrator::new(Err(why), true);
    assert!(c
        .observe(0.0, Some(30.0), 0.0, 0.0, None, Some(200.0))
        .is_none());
    assert!(matches!(c.state(), HoverState::None(w) if w.contains("does not hover")));
}

#[test]
fn the_reference_is_momentum_theory_for_the_profile() {
    let m100 = VehicleProfile::m100();
    let r = HoverReference::of(&m100).unwrap();
    let t = m100.mass_kg(0.0) * m100.air.g_m_s2;
    let want = t.powf(1.5) / (2.0 * m100.air.rho_kg_m3 * m100.disk_area_m2()).sqrt();
    assert!((r.ideal_w - want).abs() < 1e-9);
    assert_eq!(r.prior_eta, m100.stolaroff.eta);
    assert!(r
        .eta_of(want / 0.5 + r.avionics_w)
        .is_some_and(|e| (e - 0.5).abs() < 1e-9));
    assert!(r.eta_of(f64::NAN).is_none());
}

/// Fly slowly (2 m/s: never still by the hover's 1 m/s) at `throttle` % for `secs`, 10 Hz.
fn slow_at_throttle(
    c: &mut HoverCalibrator,
    throttle: f64,
    power_w: f64,
    secs: f64,
) -> Vec<HoverNews> {
    (0..(secs * 10.0) as usize)
        .filter_map(|i| {
            let t = i as f64 * 0.1;
            let p = power_w + if i % 2 == 0 { 5.0 } else { -5.0 };
            c.observe(t, Some(20.0), 2.0, 0.1, Some(throttle), Some(p))
        })
        .collect()
}

#[test]
fn the_hover_throttle_with_the_packs_power_calibrates_without_a_still_hover() {
    let mut c = HoverCalibrator::new(Ok(reference()), true);
    assert!(c.set_hover_throttle(Some(0.42)).is_ok());
    // at 43 % (within 3 points of MOT_THST_HOVER 42 %), moving at 2 m/s: 10 s of it calibrate
    let news = slow_at_throttle(&mut c, 43.0, 258.0, 12.0);
    let Some(HoverNews::Calibrated(cal)) = news.first() else {
        panic!("{news:?}")
    };
    assert_eq!(cal.source, crate::report::hover::HoverSource::HoverThrottle);
    assert!((cal.hover_w - 258.0).abs() < 1.0, "{cal:?}");
    // η_h = 100 / (258 − 8) = 0.4
    assert!((cal.eta_h - 0.4).abs() < 0.002, "{cal:?}");
    assert!((cal.hover_s - 10.0).abs() < 0.2, "{cal:?}");
}

#[test]
fn a_throttle_away_from_the_hover_throttle_or_an_unlearned_one_calibrates_nothing() {
    // cruise at 60 % against a hover throttle of 42 %: not hover power
    let mut c = HoverCalibrator::new(Ok(reference()), true);
    c.set_hover_throttle(Some(0.42)).unwrap();
    assert!(slow_at_throttle(&mut c, 60.0, 300.0, 20.0).is_empty());
    // MOT_THST_HOVER = 0 (never learned): refused, said, and the throttle is not used
    let mut c = HoverCalibrator::new(Ok(reference()), true);
    let why = c.set_hover_throttle(Some(0.0)).unwrap_err();
    assert!(
        why.contains("MOT_THST_HOVER = 0") && why.contains("flown"),
        "{why}"
    );
    assert!(c.hover_throttle().is_none());
    assert!(slow_at_throttle(&mut c, 0.0, 258.0, 20.0).is_empty());
    // no throttle in the telemetry: only a flown hover calibrates
    let mut c = HoverCalibrator::new(Ok(reference()), true);
    c.set_hover_throttle(Some(0.42)).unwrap();
    let none: Vec<_> = (0..200)
        .filter_map(|i| c.observe(f64::from(i) * 0.1, Some(20.0), 2.0, 0.1, None, Some(258.0)))
        .collect();
    assert!(none.is_empty());
}

#[test]
fn plan_hover_w_and_the_live_first_hover_give_a_loaded_hover_the_same_efficiency() {
    // `plan --hover-w` (model::spec::calibrate_hover) and the live first hover take a hover
    // flown with 300 g alike, η growing with the mass or not.
    let mut p = VehicleProfile::named_or_file("x500").unwrap();
    for slope in [0.0, 0.2572] {
        p.stolaroff.eta_per_ln_mass = slope;
        let live = HoverReference::of(&p).unwrap().eta_at(330.0, 0.3).unwrap();
        let plan = crate::model::spec::calibrate_hover(p.clone(), 330.0, 0.3).unwrap();
        assert!(
            (plan.stolaroff.eta - live).abs() < 1e-9,
            "slope {slope}: plan {} live {live}",
            plan.stolaroff.eta
        );
    }
}
