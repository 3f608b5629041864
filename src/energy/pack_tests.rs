//! Tests of `energy::pack` (its own file: the module is long enough).
use super::*;
use crate::report::Sourced;

fn tb48d() -> BatteryFacts {
    BatteryFacts::m100()
}

/// Rest at `v`, then fly at `amps` with a voltage sagging by `sag` V per A.
fn run(p: &mut Pack, facts: &BatteryFacts, rest_v: f64, t_end: f64) -> PackNow {
    let mut now = PackNow::default();
    let mut t = 0.0;
    while t < t_end {
        let (v, i) = if t < 5.0 {
            (rest_v, 0.1)
        } else {
            (rest_v - 0.06 * 20.0, 20.0)
        };
        now = p.update(t, Some(v), Some(i), Some(Load::constant(450.0)), facts);
        t += 0.1;
    }
    now
}

#[test]
fn a_half_used_tb48d_starts_well_under_full() {
    let mut p = Pack::default();
    let now = run(&mut p, &tb48d(), 23.2, 4.0);
    // 23.2 V at rest is 3.87 V a cell: about 45 % of the fitted curve, not full.
    let soc = 100.0 * OcvCurve::tb48d().soc(23.2 / 6.0);
    assert!(
        now.rest_v.is_some_and(|v| (v - 23.2).abs() < 1e-9),
        "{now:?}"
    );
    assert!(soc < 60.0 && soc > 30.0, "{soc}");
    assert!(now.energy_wh.unwrap_or(f64::NAN) < 0.6 * 103.4, "{now:?}");
}

#[test]
fn flying_forecasts_the_low_voltage_and_a_usable_floor() {
    let mut p = Pack::default();
    let now = run(&mut p, &tb48d(), 24.3, 60.0);
    let (v_min, _) = now.v_min_forecast.expect("a forecast");
    assert!(v_min < 24.3, "{now:?}");
    let usable = now.usable_wh.expect("usable");
    assert!(
        usable > 0.0 && usable < now.energy_wh.unwrap_or(0.0),
        "{now:?}"
    );
    assert!(now.time_to_low_v_s.is_some_and(|t| t > 60.0), "{now:?}");
    assert!(
        now.internal_r_ohm.is_some_and(|r| r > 0.0 && r < 0.5),
        "{now:?}"
    );
}

#[test]
fn garbage_and_a_swapped_pack() {
    let mut p = Pack::default();
    let f = tb48d();
    assert_eq!(
        p.update(0.0, Some(f64::NAN), Some(0.0), None, &f),
        PackNow::default()
    );
    assert_eq!(
        p.update(0.1, Some(0.0), Some(0.0), None, &f),
        PackNow::default()
    );
    assert_eq!(
        p.update(0.2, Some(24.0), Some(-30.0), None, &f),
        PackNow::default()
    );
    assert_eq!(p.update(0.3, None, Some(1.0), None, &f), PackNow::default());
    run(&mut p, &f, 23.4, 60.0);
    assert!(p.notes.is_empty());
    // Landed, then a fresh pack: the voltage at rest jumps up.
    for k in 0..40 {
        p.update(60.0 + f64::from(k) * 0.1, Some(25.9), Some(0.2), None, &f);
    }
    assert_eq!(p.notes.len(), 1, "{:?}", p.notes);
    assert!(p.now.rest_v.is_some_and(|v| (v - 25.9).abs() < 1e-9));
}

#[test]
fn other_packs_use_their_chemistry_scaled_to_capacity() {
    let mut f = tb48d();
    f.cell_count = Sourced::new(3, Provenance::Parameter("BAT1_N_CELLS".into()));
    f.capacity_wh = Some(Sourced::new(
        36.6,
        Provenance::Parameter("BATT_CAPACITY".into()),
    ));
    f.chemistry = Sourced::new("lipo".into(), Provenance::Default);
    let (curve, params) = pack_model(&f).expect("a model");
    assert!((curve.capacity() - 36.6).abs() < 1e-9);
    assert_eq!(params.n_cells, 3);
    // A full 3S LiPo at rest holds the whole capacity.
    assert!((curve.energy(12.6 / 3.0) - 36.6).abs() < 1e-9);
}

#[test]
fn the_same_pack_soon_after_carries_its_resistance_and_warmth() {
    let f = tb48d();
    let hist = |gap_s: f64| PackHistory {
        identified: false,
        gap_s,
        r_scale: Some(1.4),
        heat: 100_000.0,
        end_rest_v: Some(23.3),
        deep_slope: None,
    };
    let mut soon = Pack {
        history: Some(hist(300.0)),
        ..Pack::default()
    };
    let mut cold = Pack {
        history: Some(hist(3.0 * 3600.0)),
        ..Pack::default()
    };
    let (a, b) = (
        run(&mut soon, &f, 23.4, 30.0),
        run(&mut cold, &f, 23.4, 30.0),
    );
    assert!(a.carried && !b.carried, "{a:?} {b:?}");
    // A resistance 1.4× the nominal carried over, shrunk: more sag than a fresh start, but
    // the warmth carried lowers it too; the model differs either way.
    assert_ne!(a.v_model, b.v_model);
    assert!(
        a.r_scale.is_some() && a.heat.is_some_and(|h| h > 0.0),
        "{a:?}"
    );
    // A pack at a voltage it could not have relaxed to is another pack.
    let mut other = Pack {
        history: Some(hist(300.0)),
        ..Pack::default()
    };
    assert!(!run(&mut other, &f, 25.9, 10.0).carried);
}

/// A 4S Li-ion pack (`capacity`: None, not known) rested at 16.0 V, then flown at 10 A with its
/// loaded voltage falling 2 mV/s from 15.4 V: the threshold 14.0 V is 700 s after take-off.
fn falling(capacity: Option<f64>, t_end: f64) -> PackNow {
    let facts = BatteryFacts {
        cell_count: Sourced::new(4, Provenance::Config),
        capacity_wh: capacity.map(|c| Sourced::new(c, Provenance::Config)),
        chemistry: Sourced::new("liion".into(), Provenance::Config),
        low_voltage_v: Some(Sourced::new(14.0, Provenance::Config)),
        ..BatteryFacts::default()
    };
    let mut p = Pack::default();
    let mut now = PackNow::default();
    let mut t = 0.0;
    while t < t_end {
        let (v, i) = if t < 5.0 {
            (16.0, 0.1)
        } else {
            (15.4 - 0.002 * (t - 5.0), 10.0)
        };
        now = p.update(t, Some(v), Some(i), Some(Load::constant(v * i)), &facts);
        t += 0.1;
    }
    now
}

#[test]
fn the_time_to_low_follows_the_measured_fall_and_is_never_later_than_it() {
    // 300 s after take-off the line crosses 14.0 V in 400 s: the sooner of the circuit's and
    // the trend's (battery::trend), so never later than the line
    let now = falling(Some(200.0), 305.0);
    let t = now.time_to_low_v_s.expect("a time to the low voltage");
    assert!(
        t <= 400.0 + 5.0,
        "{t} s: later than the measured fall says; {now:?}"
    );
    assert!(t > 0.0, "{now:?}");
    // with no capacity (no circuit), the trend's alone: the line's 400 s
    let now = falling(None, 305.0);
    let t = now
        .time_to_low_v_s
        .expect("a time to the low voltage without the capacity");
    assert!((t - 400.0).abs() < 20.0, "{t} s; {now:?}");
}

#[test]
fn a_cell_count_heard_after_the_rest_is_checked_even_on_a_bad_reading() {
    // energy::props found it: a rest read at 3.31 V on one cell, then BAT1_N_CELLS = 5, then a
    // voltage of 0: the stale 3.31 V open-circuit voltage must not stand for five cells
    let mut facts = BatteryFacts {
        cell_count: Sourced::new(1, Provenance::Default),
        ..BatteryFacts::default()
    };
    let mut p = Pack::default();
    let mut t = 0.0;
    while t < 2.5 {
        p.update(t, Some(3.313), Some(0.3), None, &facts);
        t += 0.25;
    }
    assert!(p
        .update(t, Some(3.313), Some(0.3), None, &facts)
        .ocv_v
        .is_some());
    facts.cell_count = Sourced::new(5, Provenance::Config);
    let now = p.update(t + 0.05, Some(0.0), Some(0.0), None, &facts);
    let (lo, hi) = (5.0 * Chemistry::LiPo.loaded_min_v(), 5.0 * 4.35);
    assert!(now.ocv_v.is_none_or(|v| (lo..=hi).contains(&v)), "{now:?}");
}

#[test]
fn the_slope_of_a_packs_deeper_sag_is_carried_to_its_next_flight() {
    let facts = |chem: &str| BatteryFacts {
        cell_count: Sourced::new(4, Provenance::Config),
        capacity_wh: Some(Sourced::new(40.0, Provenance::Config)),
        chemistry: Sourced::new(chem.into(), Provenance::Config),
        ..BatteryFacts::default()
    };
    // the pack, known by its identity, flew a day ago (recharged since) and showed a slope of 3
    let hist = PackHistory {
        identified: true,
        gap_s: 86_400.0,
        r_scale: None,
        heat: 0.0,
        end_rest_v: Some(14.8),
        deep_slope: Some(3.0),
    };
    let fly = |history: Option<PackHistory>, chem: &str| {
        let mut p = Pack {
            history,
            ..Pack::default()
        };
        let mut now = PackNow::default();
        let mut t = 0.0;
        while t < 20.0 {
            let (v, i) = if t < 5.0 { (16.4, 0.1) } else { (15.6, 5.0) };
            now = p.update(
                t,
                Some(v),
                Some(i),
                Some(Load::constant(v * i)),
                &facts(chem),
            );
            t += 0.1;
        }
        now.deep_slope
    };
    let prior = crate::battery::deep::PRIOR_SLOPE;
    let near = |x: Option<f64>, want: f64| x.is_some_and(|x| (x - want).abs() < 0.3);
    assert!(near(fly(None, "liion"), prior));
    // 15 s of flight hold next to no evidence of the slope: the carried one stands
    assert!(
        near(fly(Some(hist), "liion"), 3.0),
        "{:?}",
        fly(Some(hist), "liion")
    );
    // another pack (not identified, long ago): the prior
    let other = PackHistory {
        identified: false,
        ..hist
    };
    assert!(near(fly(Some(other), "liion"), prior));
    // a LiPo keeps one resistance (no growth prior): nothing carried into it
    assert_eq!(fly(Some(hist), "lipo"), Some(0.0));
}

/// A 3S1P 2.5 Ah Li-ion pack (27 Wh; BATT_LOW_VOLT 10.5 V) flown at 2 A, under the M100's
/// 3 A: from `rest_s` of rest at 11.4 V (0: attached in flight), its loaded voltage falling
/// 2 mV/s from 11.2 V for `fly_s`, then 5 s landed at 11.3 V.
fn small_pack(rest_s: f64, fly_s: f64) -> (Pack, PackNow, PackNow) {
    let facts = BatteryFacts {
        cell_count: Sourced::new(3, Provenance::Config),
        capacity_wh: Some(Sourced::new(27.0, Provenance::Config)),
        chemistry: Sourced::new("liion".into(), Provenance::Config),
        low_voltage_v: Some(Sourced::new(10.5, Provenance::Config)),
        ..BatteryFacts::default()
    };
    let mut p = Pack::default();
    let (mut flying, mut landed) = (PackNow::default(), PackNow::default());
    let mut t = 0.0;
    while t < rest_s + fly_s + 5.0 {
        let (v, i) = if t < rest_s {
            (11.4, 0.1)
        } else if t < rest_s + fly_s {
            (11.2 - 0.002 * (t - rest_s), 2.0)
        } else {
            (11.3, 0.1)
        };
        let now = p.update(t, Some(v), Some(i), Some(Load::constant(v * i)), &facts);
        if t < rest_s + fly_s {
            flying = now;
        } else {
            landed = now;
        }
        t += 0.1;
    }
    (p, flying, landed)
}

#[test]
fn a_small_pack_under_3_a_is_loaded_by_its_own_threshold() {
    // the pack's own threshold: 3 A scaled by its charge (2.5 of the TB48D's 4.5 Ah); the
    // M100's stays 3 A exactly, and 3 A with the capacity not known
    let mut facts = BatteryFacts {
        cell_count: Sourced::new(3, Provenance::Config),
        capacity_wh: Some(Sourced::new(27.0, Provenance::Config)),
        chemistry: Sourced::new("liion".into(), Provenance::Config),
        ..BatteryFacts::default()
    };
    let a = load_current_a(&facts);
    assert!(a > 1.5 && a < 1.8, "{a}");
    assert_eq!(load_current_a(&tb48d()), LOAD_CURRENT_A);
    facts.capacity_wh = None;
    assert_eq!(load_current_a(&facts), LOAD_CURRENT_A);
    // rested, flown at 2 A, landed: counted as flown (the landing's rest is the flight's
    // end, not a new start), and a time to the low voltage in flight
    let (p, flying, landed) = small_pack(5.0, 60.0);
    assert!(p.flown, "{landed:?}");
    assert!(landed.end_rest_v.is_some(), "{landed:?}");
    assert!(flying.time_to_low_v_s.is_some(), "{flying:?}");
    // attached in flight at 2 A: started load-compensated, the forecast's 10 s hold under
    // load passes and a time to the low voltage is given
    let (_, flying, _) = small_pack(0.0, 60.0);
    assert_eq!(flying.start, Some(FROM_LOAD), "{flying:?}");
    assert_eq!(flying.withheld, None, "{flying:?}");
    assert!(flying.time_to_low_v_s.is_some(), "{flying:?}");
}

#[test]
fn a_micro_packs_hover_under_1_a_is_flight_not_rest() {
    // 2S 1.0 Ah Li-ion (7.2 Wh): loaded from 0.66 A, resting under 0.33 A (the M100's 1 A
    // and 3 A unchanged, and 1 A with the capacity not known). Rested at 8.1 V, then hovering
    // at 0.8 A with its voltage falling 2 mV/s from 7.9 V (still enough to pass as "settled"):
    // a flight, not a new resting voltage read off the loaded pack.
    let facts = BatteryFacts {
        cell_count: Sourced::new(2, Provenance::Config),
        capacity_wh: Some(Sourced::new(7.2, Provenance::Config)),
        chemistry: Sourced::new("liion".into(), Provenance::Config),
        low_voltage_v: Some(Sourced::new(7.0, Provenance::Config)),
        ..BatteryFacts::default()
    };
    let (rest, load) = (rest_current_a(&facts), load_current_a(&facts));
    assert!(rest < 0.8 && load < 0.8 && rest < load, "{rest} {load}");
    assert_eq!(rest_current_a(&tb48d()), REST_CURRENT_A);
    let unknown = BatteryFacts {
        capacity_wh: None,
        ..facts.clone()
    };
    assert_eq!(rest_current_a(&unknown), REST_CURRENT_A);
    // a 3S 4 Wh pack: its ground idle (2 W, 0.18 A) is still a rest
    let tiny = BatteryFacts {
        cell_count: Sourced::new(3, Provenance::Config),
        capacity_wh: Some(Sourced::new(4.0, Provenance::Config)),
        ..facts.clone()
    };
    assert_eq!(rest_current_a(&tiny), REST_FLOOR_A);
    let mut p = Pack::default();
    let mut flying = PackNow::default();
    let mut t = 0.0;
    while t < 65.0 {
        let (v, i) = if t < 5.0 {
            (8.1, 0.1)
        } else {
            (7.9 - 0.002 * (t - 5.0), 0.8)
        };
        flying = p.update(t, Some(v), Some(i), Some(Load::constant(v * i)), &facts);
        t += 0.1;
    }
    assert!(p.flown, "{flying:?}");
    // read through its 0.1 A of ground idle (a Li-ion table: energy::pack::rest)
    let r = prior_r_ohm(2, pack_ah(&facts, Chemistry::LiIon));
    let rest_v = flying.rest_v.unwrap_or(f64::NAN);
    assert!((rest_v - (8.1 + 0.1 * r)).abs() < 1e-9, "{flying:?}");
    assert_eq!(flying.start, Some(FROM_REST), "{flying:?}");
    assert!(flying.time_to_low_v_s.is_some(), "{flying:?}");
}

#[test]
fn a_micro_pack_with_no_capacity_gets_a_time_to_the_low_voltage_under_3_a() {
    // 3S Li-ion, capacity not known (no circuit: the trend alone), rested, then hovering at
    // 2 A with its loaded voltage falling 2 mV/s from 11.2 V: the trend takes it (it needed
    // the M100's 3 A before), and the time is where its line crosses 10.5 V
    let facts = BatteryFacts {
        cell_count: Sourced::new(3, Provenance::Config),
        capacity_wh: None,
        chemistry: Sourced::new("liion".into(), Provenance::Config),
        low_voltage_v: Some(Sourced::new(10.5, Provenance::Config)),
        ..BatteryFacts::default()
    };
    let mut p = Pack::default();
    let mut flying = PackNow::default();
    let mut t = 0.0;
    while t < 65.0 {
        let (v, i) = if t < 5.0 {
            (11.4, 0.1)
        } else {
            (11.2 - 0.002 * (t - 5.0), 2.0)
        };
        flying = p.update(t, Some(v), Some(i), Some(Load::constant(v * i)), &facts);
        t += 0.1;
    }
    // at 65 s: 11.08 V, falling 2 mV/s: about 290 s to 10.5 V
    let ttl = flying.time_to_low_v_s.expect("a time to the low voltage");
    assert!((250.0..320.0).contains(&ttl), "{flying:?}");
}
