//! Range checks for validation, with one message shape for every key:
//! `KEY = VALUE: must be in (0, 100] Hz` (or `> 0`, `≥ 0`, `≤ 1`, `in [1, 1000]`, `finite`).
//!
//! The config's sections, the vehicle profile and the simulator's route options call
//! [`in_range`] (or [`Errors::range`] to collect every broken key of a section) instead of
//! writing each message by hand. A number outside its range, NaN, or an infinite float is
//! refused; the message names the key, the value, the allowed range and its unit. This
//! module imports nothing from the crate, so every module may use it.

use std::fmt::{self, Display};
use std::ops::{Bound, RangeBounds};

/// A number a range check accepts: integers, and floats that must also be finite.
pub trait Number: PartialOrd + Display + Copy {
    /// `false` for NaN and ±∞ (always `true` for integers).
    fn is_finite(self) -> bool;
}

impl Number for f64 {
    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }
}

impl Number for f32 {
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }
}

macro_rules! integer_number {
    ($($t:ty),*) => {$(
        impl Number for $t {
            fn is_finite(self) -> bool {
                true
            }
        }
    )*};
}
integer_number!(u8, u16, u32, u64, usize, i32, i64);

/// `> lo` (the std range syntax has no open lower end).
pub fn above<T>(lo: T) -> (Bound<T>, Bound<T>) {
    (Bound::Excluded(lo), Bound::Unbounded)
}

/// `(lo, hi]`: above `lo`, at most `hi`.
pub fn above_to<T>(lo: T, hi: T) -> (Bound<T>, Bound<T>) {
    (Bound::Excluded(lo), Bound::Included(hi))
}

/// How a range reads in a message: `> 0`, `≥ 0`, `≤ 1`, `< 1`, `in (0, 100]`, `finite` (`..`).
pub struct Shown<'a, T, R: ?Sized>(&'a R, std::marker::PhantomData<T>);

/// [`Shown`] for `range`.
pub fn show<T, R: RangeBounds<T> + ?Sized>(range: &R) -> Shown<'_, T, R> {
    Shown(range, std::marker::PhantomData)
}

impl<T: Display, R: RangeBounds<T> + ?Sized> Display for Shown<'_, T, R> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use Bound::{Excluded, Included, Unbounded};
        match (self.0.start_bound(), self.0.end_bound()) {
            (Unbounded, Unbounded) => f.write_str("finite"),
            (Included(lo), Unbounded) => write!(f, "≥ {lo}"),
            (Excluded(lo), Unbounded) => write!(f, "> {lo}"),
            (Unbounded, Included(hi)) => write!(f, "≤ {hi}"),
            (Unbounded, Excluded(hi)) => write!(f, "< {hi}"),
            (lo, hi) => {
                let (open, lo) = match lo {
                    Included(v) => ('[', v),
                    Excluded(v) => ('(', v),
                    Unbounded => unreachable!("an unbounded start is matched above"),
                };
                let (close, hi) = match hi {
                    Included(v) => (']', v),
                    Excluded(v) => (')', v),
                    Unbounded => unreachable!("an unbounded end is matched above"),
                };
                write!(f, "in {open}{lo}, {hi}{close}")
            }
        }
    }
}

/// What is wrong with `v` for `range`: `None` when it is in range (and finite),
/// else `must be in (0, 100] Hz` (the range, then `unit` when not empty).
pub fn violation<T: Number, R: RangeBounds<T>>(v: T, range: &R, unit: &str) -> Option<String> {
    if v.is_finite() && range.contains(&v) {
        return None;
    }
    let sep = if unit.is_empty() { "" } else { " " };
    Some(format!("must be {}{sep}{unit}", show(range)))
}

/// `Err("KEY = VALUE: must be in (0, 100] Hz")` when `v` is outside `range`, NaN or
/// infinite; `unit` may be empty.
pub fn in_range<T: Number, R: RangeBounds<T>>(
    key: &str,
    v: T,
    range: R,
    unit: &str,
) -> Result<(), String> {
    match violation(v, &range, unit) {
        None => Ok(()),
        Some(why) => Err(format!("{key} = {v}: {why}")),
    }
}

/// Every validation error of a section, collected so one run reports every broken key.
#[derive(Debug, Default)]
pub struct Errors(Vec<String>);

impl Errors {
    /// No errors yet.
    pub fn new() -> Self {
        Self::default()
    }
    /// [`in_range`], kept when it fails.
    pub fn range<T: Number, R: RangeBounds<T>>(&mut self, key: &str, v: T, range: R, unit: &str) {
        if let Err(e) = in_range(key, v, range, unit) {
            self.0.push(e);
        }
    }
    /// A message written by hand (cross-field rules, formats).
    pub fn push(&mut self, message: String) {
        self.0.push(message);
    }
    /// Several messages.
    pub fn extend(&mut self, messages: impl IntoIterator<Item = String>) {
        self.0.extend(messages);
    }
    /// `Ok` when none; else every message, one per line.
    pub fn into_result(self) -> Result<(), String> {
        if self.0.is_empty() {
            Ok(())
        } else {
            Err(self.0.join("\n"))
        }
    }
    /// The messages.
    pub fn into_vec(self) -> Vec<String> {
        self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_the_key_the_value_and_the_range() {
        let cases: [(Result<(), String>, &str); 9] = [
            (
                in_range("telemetry.rate_hz", 0.0, above_to(0.0, 100.0), "Hz"),
                "telemetry.rate_hz = 0: must be in (0, 100] Hz",
            ),
            (
                in_range("telemetry.window", 0usize, 1..=1000, "samples"),
                "telemetry.window = 0: must be in [1, 1000] samples",
            ),
            (
                in_range("energy.smoothing_s", -1.0, above(0.0), ""),
                "energy.smoothing_s = -1: must be > 0",
            ),
            (
                in_range("energy.landing_s", f64::NAN, 0.0.., "s"),
                "energy.landing_s = NaN: must be ≥ 0 s",
            ),
            (
                in_range("energy.reserve_pct", 100.0, 0.0..100.0, "%"),
                "energy.reserve_pct = 100: must be in [0, 100) %",
            ),
            (
                in_range("x", f64::INFINITY, above(0.0), ""),
                "x = inf: must be > 0",
            ),
            (in_range("x", 2.5, ..=1.0, ""), "x = 2.5: must be ≤ 1"),
            (in_range("x", 1.0, ..1.0, ""), "x = 1: must be < 1"),
            (
                in_range("sinks.mqtt.port", 0u16, 1..=65535, ""),
                "sinks.mqtt.port = 0: must be in [1, 65535]",
            ),
        ];
        for (got, want) in cases {
            assert_eq!(got, Err(want.to_string()));
        }
    }

    #[test]
    fn the_ends_are_as_the_range_says() {
        assert!(in_range("k", 100.0, above_to(0.0, 100.0), "").is_ok());
        assert!(in_range("k", 1e-300, above(0.0), "").is_ok());
        assert!(in_range("k", 0.0, 0.0..1.0, "").is_ok());
        assert!(in_range("k", 1000usize, 1..=1000, "").is_ok());
        assert!(in_range("k", 1001usize, 1..=1000, "").is_err());
    }

    /// What a user with a broken file reads: every broken key of every section, each with
    /// its value, range and unit, in the file's section order.
    #[test]
    fn a_config_file_reports_each_key_value_and_range() {
        let cfg: crate::config::Config = toml::from_str(
            "[telemetry]\nrate_hz = 0\nwindow = 2000\n\
             [energy]\nreserve_pct = 100\ncell_count = 0\nlanding_s = -1\n\
             [energy.select]\nmargin = 1.5\n\
             [sinks.web]\nhistory = 5\n\
             [sinks.mqtt]\nport = 0\n\
             [fleet]\nlstm_rate_hz = 200\n",
        )
        .expect("the keys exist");
        assert_eq!(
            cfg.errors(),
            [
                "telemetry.rate_hz = 0: must be in (0, 100] Hz",
                "telemetry.window = 2000: must be in [1, 1000] samples",
                "telemetry.max_gap_s = 1: must be longer than one sample period (1/rate_hz)",
                "energy.landing_s = -1: must be ≥ 0 s",
                "energy.reserve_pct = 100: must be in [0, 100) %",
                "energy.cell_count = 0: must be in [1, 24] cells",
                "energy.select.margin = 1.5: must be in [0, 1)",
                "sinks.web.history = 5: must be in [10, 1000000] points",
                "sinks.mqtt.port = 0: must be in [1, 65535]",
                "fleet.lstm_rate_hz = 200: must be in (0, 100] Hz",
            ]
        );
        assert_eq!(
            crate::config::Config::default().errors(),
            Vec::<String>::new()
        );
    }

    #[test]
    fn errors_collect_every_key_one_per_line() {
        let mut e = Errors::new();
        assert_eq!(Errors::new().into_result(), Ok(()));
        e.range("a", -1.0, 0.0.., "");
        e.range("b", 0.5, 0.0..1.0, "");
        e.push("c: hand-written".into());
        assert_eq!(
            e.into_result(),
            Err("a = -1: must be ≥ 0\nc: hand-written".into())
        );
    }
}
