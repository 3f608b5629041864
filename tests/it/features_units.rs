//! Properties of the unit conversions every reader, the simulator and the forecast share,
//! on any input proptest can find (edge cases shrink to their smallest form).

use dronewatt::features::frames::{ground_distance_m, is_fix, ne_offset_m, offset_ne};
use dronewatt::features::units::{ceil_ratio, centidegrees, floor_ratio, scaled, whole_degrees};
use proptest::prelude::*;

proptest! {
    /// A point moved by an offset and measured back gives the offset (to a millimetre over
    /// 50 km), anywhere a drone flies (not at the poles).
    #[test]
    fn geo_offset_and_its_inverse_round_trip(
        lat in -85.0f64..85.0,
        lon in -180.0f64..180.0,
        n in -50_000.0f64..50_000.0,
        e in -50_000.0f64..50_000.0,
    ) {
        let (lat2, lon2) = offset_ne(lat, lon, n, e);
        let (n2, e2) = ne_offset_m(lat, lon, lat2, lon2);
        prop_assert!((n2 - n).abs() < 1e-3 && (e2 - e).abs() < 1e-3, "{n2} {e2}");
        prop_assert!((ground_distance_m(lat, lon, lat2, lon2) - n.hypot(e)).abs() < 1e-3);
    }

    /// A fix is a finite point on the globe other than (0, 0).
    #[test]
    fn a_fix_is_on_the_globe_and_not_null_island(lat in any::<f64>(), lon in any::<f64>()) {
        let on_globe = lat.abs() <= 90.0 && lon.abs() <= 180.0;
        prop_assert_eq!(is_fix(lat, lon), on_globe && (lat, lon) != (0.0, 0.0));
    }

    /// Degrees to MAVLink's 1e-7 degrees: the nearest integer, never truncated.
    #[test]
    fn degrees_e7_are_the_nearest_integer(x in -180.0f64..180.0) {
        let v = scaled::<i32>(x, 1e7).unwrap();
        prop_assert!((f64::from(v) - x * 1e7).abs() <= 0.5, "{x} -> {v}");
    }

    /// Metres to millimetres, m/s to cm/s, volts to millivolts: nearest integer, saturated
    /// at the type's bounds, `None` only for a product that is not finite.
    #[test]
    fn scaled_integers_round_and_saturate(x in any::<f64>(), k in prop::sample::select(vec![1.0, 100.0, 1e3, 1e7])) {
        let y = x * k;
        let i16v = scaled::<i16>(x, k);
        let u16v = scaled::<u16>(x, k);
        let i32v = scaled::<i32>(x, k);
        if !y.is_finite() {
            prop_assert!(i16v.is_none() && u16v.is_none() && i32v.is_none());
        } else {
            let near = |v: f64, lo: f64, hi: f64| (v - y.clamp(lo, hi)).abs() <= 0.5;
            prop_assert!(near(f64::from(i16v.unwrap()), -32768.0, 32767.0));
            prop_assert!(near(f64::from(u16v.unwrap()), 0.0, 65535.0));
            prop_assert!(near(f64::from(i32v.unwrap()), f64::from(i32::MIN), f64::from(i32::MAX)));
        }
    }

    /// A course or heading in centidegrees is in [0, 36000) and within 0.005° of the angle
    /// (on the circle: 359.999° is 0).
    #[test]
    fn centidegrees_wrap_below_36000(deg in -1e6f64..1e6) {
        let c = centidegrees(deg).unwrap();
        prop_assert!(c < 36_000);
        let d = (f64::from(c) / 100.0 - deg).rem_euclid(360.0);
        prop_assert!(d.min(360.0 - d) <= 0.005 + 1e-9, "{deg} -> {c}");
    }

    /// Tiny negative angles, where rem_euclid(360) is 360.0 exactly.
    #[test]
    fn tiny_negative_angles_are_north(e in 1e-300f64..1e-10) {
        prop_assert_eq!(centidegrees(-e), Some(0));
        prop_assert_eq!(whole_degrees(-e), Some(0));
    }

    /// Whole degrees in [0, 360), within half a degree on the circle.
    #[test]
    fn whole_degrees_wrap_below_360(deg in -1e6f64..1e6) {
        let h = whole_degrees(deg).unwrap();
        prop_assert!((0..360).contains(&h));
        let d = (f64::from(h) - deg).rem_euclid(360.0);
        prop_assert!(d.min(360.0 - d) <= 0.5 + 1e-9, "{deg} -> {h}");
    }

    /// n steps of a decimal dt: exactly n, by ceil and by floor, whatever the quotient's
    /// last bit (0.7 / 0.1 and 3.0 / 0.1 are not integers in binary).
    #[test]
    fn steps_of_a_decimal_are_exact(n in 0u32..200_000, dt_milli in 1u32..5_000) {
        let dt = f64::from(dt_milli) / 1000.0;
        let span = f64::from(n) * dt;
        prop_assert_eq!(ceil_ratio(span, dt), Some(f64::from(n)));
        prop_assert_eq!(floor_ratio(span, dt), Some(f64::from(n)));
    }

    /// Between whole steps, ceil covers the span and floor stays inside it.
    #[test]
    fn ceil_covers_and_floor_fits(a in 0.0f64..1e5, b in 1e-3f64..10.0) {
        let (c, f) = (ceil_ratio(a, b).unwrap(), floor_ratio(a, b).unwrap());
        prop_assert!(c * b >= a * (1.0 - 1e-9) && f * b <= a * (1.0 + 1e-9));
        prop_assert!(c - f <= 1.0);
    }

    /// A percentile's rank, ceil(q × count): the 7th percentile of 100 values is the 7th.
    #[test]
    fn percentile_ranks_are_exact(k in 1u32..100, m in 1u32..1000) {
        let count = f64::from(100 * m);
        let q = f64::from(k) / 100.0;
        prop_assert_eq!(ceil_ratio(q * count, 1.0), Some(f64::from(k * m)));
    }
}

#[test]
fn the_quotients_that_float_division_gets_wrong() {
    // The raw quotients miss by one ulp (0.07 × 100 is 7.000000000000001, 0.3 / 0.1 is
    // 2.9999999999999996), which ceil and floor turn into a whole step.
    assert_eq!((0.07f64 * 100.0).ceil(), 8.0);
    assert_eq!(ceil_ratio(0.07 * 100.0, 1.0), Some(7.0));
    assert_eq!((0.3f64 / 0.1).floor(), 2.0);
    assert_eq!(floor_ratio(0.3, 0.1), Some(3.0));
    assert_eq!((3.0 * 0.003f64 / 0.003).ceil(), 4.0);
    assert_eq!(ceil_ratio(3.0 * 0.003, 0.003), Some(3.0));
    assert_eq!(ceil_ratio(1.0, 0.0), None);
    assert_eq!(floor_ratio(f64::NAN, 1.0), None);
}

#[test]
fn no_fix_edge_cases() {
    assert!(!is_fix(0.0, 0.0) && !is_fix(-0.0, 0.0));
    assert!(!is_fix(f64::NAN, 8.5) && !is_fix(47.0, f64::INFINITY) && !is_fix(90.1, 0.0));
    assert!(is_fix(0.0, 8.5) && is_fix(-90.0, 180.0));
}
