//! Properties of the unit conversions every reader, the simulator and the forecast share,
//! on any input proptest can find (edge cases shrink to their smallest form).

use dronewatt::features::frames::{ground_distance_m, is_fix, ne_offset_m, offset_ne};
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
}

#[test]
fn no_fix_edge_cases() {
    assert!(!is_fix(0.0, 0.0) && !is_fix(-0.0, 0.0));
    assert!(!is_fix(f64::NAN, 8.5) && !is_fix(47.0, f64::INFINITY) && !is_fix(90.1, 0.0));
    assert!(is_fix(0.0, 8.5) && is_fix(-90.0, 180.0));
}
