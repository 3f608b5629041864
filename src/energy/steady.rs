//! What the pilot reads, steady from the first second of flight.
//!
//! - **Take-off** ([`Airborne`]): the forecast model's smoothed power restarts at take-off, so
//!   that the first seconds of flight forecast with the power of the phase being flown (the
//!   climb, the hover), not with an average that starts from ground idle (time to empty ran
//!   468 → 58 → 34 → 10 min over the first 20 s, issue 44). Until the measured power in flight
//!   has been averaged for the smoothing time, the pack's forecast flies the forecast model's
//!   power ([`Airborne::measured_long_enough`]).
//! - **No rise in flight** ([`NoRise`]): remaining energy never rises while the pack is under
//!   load (from the smoothing time after take-off: the first seconds show the pack's sag): at most what was shown less the energy counted since. It may rise only with a stated
//!   reason: a change of where it comes from (the source is shown beside it: a resting voltage
//!   read, a pack swapped and read again), at rest (a pack recovers its voltage, the landed
//!   pack's resting voltage is read), or when the estimate has stayed above it for
//!   [`REVISE_AFTER_S`] (the pack's sag learned in flight: revised up once, said in a
//!   warning).

use crate::report::RemainingSource;

/// A landing: this long under the rest current before a new take-off restarts the averages.
pub const LANDED_S: f64 = 5.0;

/// Whether the vehicle flies, and for how long it has.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct Airborne {
    flying: bool,
    /// Seconds in flight since take-off.
    pub flying_s: f64,
    /// Seconds on the ground since the last flight sample (a landing when ≥ [`LANDED_S`]).
    ground_s: f64,
    seen: bool,
}

impl Airborne {
    /// One sample: `flying` (under load, or above the ground) for `dt_s`. True on a take-off
    /// (the first sample in flight after at least [`LANDED_S`] on the ground, or after the
    /// first sample on the ground): the caller restarts its averages.
    pub fn update(&mut self, flying: bool, dt_s: f64) -> bool {
        let dt = if dt_s.is_finite() { dt_s.max(0.0) } else { 0.0 };
        let first = !self.seen;
        self.seen = true;
        if !flying {
            self.ground_s += dt;
            if self.ground_s >= LANDED_S || first {
                self.flying = false;
            }
            return false;
        }
        let took_off = !self.flying && !first;
        if !self.flying {
            self.flying_s = 0.0;
        } else {
            self.flying_s += dt;
        }
        self.flying = true;
        self.ground_s = 0.0;
        took_off
    }

    /// Whether the measured power has been averaged in flight for `tau_s`.
    pub fn measured_long_enough(&self, tau_s: f64) -> bool {
        self.flying && self.flying_s >= tau_s
    }
}

/// How long the estimate must stay above what is shown under load before what is shown is
/// revised up to it (said): a moment's low estimate (the pack's sag not yet learned at
/// take-off) must not hold the display down for the rest of the flight.
pub const REVISE_AFTER_S: f64 = 30.0;

/// Remaining energy that does not rise under load without a stated reason.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct NoRise {
    /// (shown Wh, energy used then Wh, its source).
    last: Option<(f64, f64, RemainingSource)>,
    /// Since when (s) the estimate has stayed above what is shown.
    above_since: Option<f64>,
}

impl NoRise {
    /// The remaining energy to show at `t` (s): `remaining` (Wh, from `source`), no more under
    /// load (`loaded`) than the last shown less the energy used since (`used_wh`, the count),
    /// until the estimate has stayed above that for [`REVISE_AFTER_S`]: then the estimate,
    /// with by how much it was revised up (Wh, to be said).
    pub fn update(
        &mut self,
        t: f64,
        remaining: Option<f64>,
        source: RemainingSource,
        used_wh: f64,
        loaded: bool,
    ) -> (Option<f64>, Option<f64>) {
        let Some(r) = remaining.filter(|r| r.is_finite()) else {
            (self.last, self.above_since) = (None, None);
            return (remaining, None);
        };
        let (shown, revised) = match self.last {
            Some((prev, used0, src)) if loaded && src == source && used_wh >= used0 => {
                let cap = (prev - (used_wh - used0)).max(0.0);
                if r <= cap {
                    self.above_since = None;
                    (r, None)
                } else if t.is_finite() && t - *self.above_since.get_or_insert(t) >= REVISE_AFTER_S
                {
                    self.above_since = None;
                    (r, Some(r - cap))
                } else {
                    (cap, None)
                }
            }
            _ => {
                self.above_since = None;
                (r, None)
            }
        };
        self.last = Some((shown, used_wh, source));
        (Some(shown), revised)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_take_off_is_said_once_after_a_rest_and_not_on_a_flicker() {
        let mut a = Airborne::default();
        assert!(!a.update(false, 0.0));
        for _ in 0..100 {
            assert!(!a.update(false, 0.1));
        }
        assert!(a.update(true, 0.1));
        assert!(!a.measured_long_enough(10.0));
        for _ in 0..100 {
            assert!(!a.update(true, 0.1));
        }
        assert!(a.measured_long_enough(9.9));
        // a dip under the rest current for a second in flight: not a landing
        for _ in 0..10 {
            a.update(false, 0.1);
        }
        assert!(!a.update(true, 0.1));
        assert!(a.measured_long_enough(9.9));
        // attached in flight: flying from the first sample, no take-off said
        let mut b = Airborne::default();
        assert!(!b.update(true, 0.0));
        assert!(!b.update(true, f64::NAN));
    }

    #[test]
    fn remaining_never_rises_under_load_but_may_at_rest_from_a_new_source_or_said() {
        let mut n = NoRise::default();
        let rs = RemainingSource::RestingVoltage;
        assert_eq!(n.update(0.0, Some(30.0), rs, 0.0, true), (Some(30.0), None));
        // the model says more a moment later: held at what was shown less what was used
        assert_eq!(n.update(1.0, Some(33.0), rs, 1.0, true), (Some(29.0), None));
        // less: shown as it is
        assert_eq!(n.update(2.0, Some(20.0), rs, 2.0, true), (Some(20.0), None));
        // more for 30 s: revised up, and by how much
        assert_eq!(n.update(3.0, Some(26.0), rs, 2.0, true), (Some(20.0), None));
        assert_eq!(
            n.update(20.0, Some(26.0), rs, 2.0, true),
            (Some(20.0), None)
        );
        assert_eq!(
            n.update(33.0, Some(26.0), rs, 2.0, true),
            (Some(26.0), Some(6.0))
        );
        // a new source is a stated reason
        let lc = RemainingSource::LoadCompensated;
        assert_eq!(
            n.update(34.0, Some(28.0), lc, 2.0, true),
            (Some(28.0), None)
        );
        // at rest the pack may recover
        assert_eq!(
            n.update(35.0, Some(29.0), lc, 2.0, false),
            (Some(29.0), None)
        );
        assert_eq!(n.update(36.0, None, lc, 2.0, true), (None, None));
        let (nan, _) = n.update(37.0, Some(f64::NAN), lc, 2.0, true);
        assert!(nan.is_some_and(f64::is_nan));
        // never below 0
        assert_eq!(n.update(38.0, Some(1.0), lc, 2.0, true), (Some(1.0), None));
        assert_eq!(n.update(39.0, Some(5.0), lc, 10.0, true), (Some(0.0), None));
    }
}

/// An exponential moving average over irregular time steps.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct Ema(
    /// The average so far (none before the first value).
    pub Option<f64>,
);

impl Ema {
    /// The average after `x` seen `dt_s` after the last value, with time constant `tau_s`.
    pub fn update(&mut self, x: f64, dt_s: f64, tau_s: f64) -> f64 {
        let v = match self.0 {
            None => x,
            Some(prev) => prev + (1.0 - (-dt_s / tau_s).exp()) * (x - prev),
        };
        self.0 = Some(v);
        v
    }
}
