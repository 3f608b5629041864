//! Float ↔ integer conversions every reader, the simulator and the sinks share, so a value
//! is scaled one way everywhere: MAVLink's scaled integer fields ([`scaled`]), angles in
//! centidegrees and degrees ([`centidegrees`], [`whole_degrees`]), and counts of steps that
//! a quotient should give exactly ([`ceil_ratio`], [`floor_ratio`]).
//!
//! Each has a property test in `tests/it/features_units.rs`.

use num_traits::{Bounded, NumCast, ToPrimitive};

/// `x × k` rounded to the nearest integer of type `T` (halves away from zero), saturated
/// at `T`'s bounds; `None` for NaN or an infinity (a value nobody measured). Never
/// truncates: 0.29 m × 1000 is 290 mm, not 289.
pub fn scaled<T: Bounded + NumCast + ToPrimitive + Copy>(x: f64, k: f64) -> Option<T> {
    let y = (x * k).round();
    if !y.is_finite() {
        return None;
    }
    let (lo, hi) = (T::min_value(), T::max_value());
    if y <= lo.to_f64()? {
        Some(lo)
    } else if y >= hi.to_f64()? {
        Some(hi)
    } else {
        T::from(y)
    }
}

/// An angle (deg, any value) as MAVLink centidegrees in `[0, 36000)`: wrapped first, then
/// rounded, and 360.00° is 0 (`rem_euclid` of a tiny negative angle is 360.0 exactly, and
/// 359.996° rounds to 36000). `None` for NaN or an infinity.
pub fn centidegrees(deg: f64) -> Option<u16> {
    let c = scaled::<u32>(deg.rem_euclid(360.0), 100.0)?;
    u16::try_from(c % 36_000).ok()
}

/// An angle (deg) as whole degrees in `[0, 360)` (VFR_HUD's heading). `None` for NaN or an
/// infinity.
pub fn whole_degrees(deg: f64) -> Option<i16> {
    let d = scaled::<i32>(deg.rem_euclid(360.0), 1.0)?;
    i16::try_from(d % 360).ok()
}

/// Relative slack under which a quotient counts as the integer it is meant to be:
/// `0.3 / 0.1` is 2.9999999999999996 and `1.1 / 0.1`... is 11.000000000000002.
const RATIO_SLACK: f64 = 1e-9;

/// `ceil(a / b)`, except that a quotient within a billionth of an integer is that integer
/// (the steps of `b` that cover `a`: 0.7 s in steps of 0.1 s is 7, never 8). `None` when
/// the quotient is not finite or `b` is not positive.
pub fn ceil_ratio(a: f64, b: f64) -> Option<f64> {
    let q = quotient(a, b)?;
    let r = q.round();
    Some(if (q - r).abs() <= RATIO_SLACK * r.abs().max(1.0) {
        r
    } else {
        q.ceil()
    })
}

/// `floor(a / b)`, except that a quotient within a billionth of an integer is that integer
/// (whole steps of `b` in `a`: 3 s in steps of 0.1 s is 30, never 29). `None` as
/// [`ceil_ratio`].
pub fn floor_ratio(a: f64, b: f64) -> Option<f64> {
    let q = quotient(a, b)?;
    let r = q.round();
    Some(if (q - r).abs() <= RATIO_SLACK * r.abs().max(1.0) {
        r
    } else {
        q.floor()
    })
}

fn quotient(a: f64, b: f64) -> Option<f64> {
    let q = a / b;
    (b > 0.0 && q.is_finite()).then_some(q)
}

/// A source time that is a Unix time, s (a tlog's or the data set's clock, 2001–2286), not
/// a time since boot or since the run started.
pub fn unix_clock(t_s: f64) -> Option<f64> {
    (t_s.is_finite() && (1e9..1e10).contains(&t_s)).then_some(t_s)
}

/// Standard gravity, m/s² (the one value every part uses).
pub const G: f64 = 9.80665;

/// An angle wrapped into [−π, π), rad.
pub fn wrap_pi(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
}
