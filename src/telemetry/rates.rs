//! What the link's rates mean for the estimate, said to the operator once.
//!
//! [`RateWatch`] looks at the [`Resampler`] after each message and says (through `tracing`):
//!
//! - **a slow signal**, once, when its period is known (8 intervals): "position at 1.0 Hz:
//!   the models see it interpolated between updates" under [`SLOW_HZ`], and "position at
//!   0.3 Hz: too slow to follow, held between updates" under [`TOO_SLOW_HZ`];
//! - **a signal that stops**: "position silent for 3.1 s: held and marked stale" when it
//!   goes past its own stale limit, and "position back after 9.4 s" when it returns; at most
//!   once a [`REPEAT_S`] per signal (of the link's clock): the silences in between are
//!   counted and the next line said gives their number (a flapping link, or a fleet of
//!   thousands on a busy machine, would otherwise write a line per vehicle per second);
//! - **a signal never heard**, once, [`NEVER_AFTER_S`] into the stream: which features the
//!   models will not have, and that the measured power (when it comes) still counts.
//!
//! The limits themselves adapt to the link ([`crate::telemetry::resample`]); this only
//! reports.

use super::resample::{Resampler, Signal, N_SIGNALS, SIGNALS};

/// Under this rate a signal has at most one update in the models' 1 s window (10 samples
/// at 10 Hz): the rest is interpolated. Said once, as a fact about the figures.
pub const SLOW_HZ: f64 = 2.0;
/// Under this rate a signal is often stale between its updates: too slow to follow (0.5 Hz,
/// with a radio's jitter, measures 0.45-0.5 Hz and is followed).
pub const TOO_SLOW_HZ: f64 = 0.4;
/// A signal not heard this long after the stream started is said to be missing, s.
pub const NEVER_AFTER_S: f64 = 5.0;
/// A silence this long is said even before the signal's period is known, s.
const MAX_SILENT_UNSAID_S: f64 = 5.0;
/// A signal's silence is said at most once this often, s (module docs).
pub const REPEAT_S: f64 = 60.0;
/// Intervals a period needs before its rate is judged.
const JUDGED_AFTER: usize = 8;

#[derive(Debug, Default, Clone, Copy)]
struct Said {
    rate: bool,
    /// Quiet since (µs) while it is.
    quiet_since: Option<i64>,
    /// When a silence was last said (µs), whether the one now was, and how many were
    /// not said since.
    said_at: Option<i64>,
    quiet_said: bool,
    unsaid: u32,
}

/// The per-signal notes made so far (see the module docs).
#[derive(Debug, Default)]
pub struct RateWatch {
    said: [Said; N_SIGNALS],
    start_us: Option<i64>,
    never_said: bool,
}

impl RateWatch {
    /// Look at `r` at time `now_us`; `source` names the message feeding a signal (if any).
    pub fn check(
        &mut self,
        r: &Resampler,
        now_us: i64,
        source: impl Fn(Signal) -> Option<&'static str>,
    ) {
        let start = *self.start_us.get_or_insert(now_us);
        for sig in SIGNALS {
            let said = &mut self.said[sig as usize];
            let Some(age) = r.age_s(sig) else { continue };
            let from = source(sig).unwrap_or("?");
            if !said.rate && r.intervals_seen(sig) >= JUDGED_AFTER {
                said.rate = true;
                if let Some(hz) = r.period_s(sig).filter(|&p| p > 0.0).map(|p| 1.0 / p) {
                    say_rate(sig, from, hz, r.stale_limit_s(sig));
                }
            }
            // Before its period is known a slow signal looks silent on the floor limit: a
            // silence is said once four intervals were seen, or past the longest limit.
            let known = r.intervals_seen(sig) >= 4 || age > MAX_SILENT_UNSAID_S;
            match (r.is_quiet(sig) && known, said.quiet_since) {
                (true, None) => {
                    said.quiet_since = Some(now_us);
                    let due = said
                        .said_at
                        .is_none_or(|t| (now_us - t) as f64 / 1e6 >= REPEAT_S);
                    said.quiet_said = due;
                    if !due {
                        said.unsaid += 1;
                        continue;
                    }
                    said.said_at = Some(now_us);
                    let more = match std::mem::take(&mut said.unsaid) {
                        0 => String::new(),
                        n => format!(" ({n} shorter silences since the last said)"),
                    };
                    tracing::warn!(
                        "{} silent for {age:.1} s (last from {from}): held and marked stale, the estimate degrades{more}",
                        sig.name()
                    );
                }
                (false, Some(since)) if !r.is_quiet(sig) => {
                    said.quiet_since = None;
                    let gap = (now_us - since) as f64 / 1e6 + r.stale_limit_s(sig);
                    if std::mem::take(&mut said.quiet_said) {
                        tracing::info!("{} back after {gap:.1} s ({from})", sig.name());
                    }
                }
                _ => {}
            }
        }
        if !self.never_said && (now_us - start) as f64 / 1e6 >= NEVER_AFTER_S {
            self.never_said = true;
            say_never_heard(r);
        }
    }
}

fn say_rate(sig: Signal, from: &str, hz: f64, stale_s: f64) {
    let name = sig.name();
    if hz < TOO_SLOW_HZ {
        tracing::warn!(
            "{name} at {hz:.1} Hz ({from}): too slow to follow, held between updates and stale after {stale_s:.1} s"
        );
    } else if hz < SLOW_HZ {
        tracing::info!(
            "{name} at {hz:.1} Hz ({from}): the models see it interpolated between updates (trained at 10 Hz); stale after {stale_s:.1} s"
        );
    }
}

fn say_never_heard(r: &Resampler) {
    let never: Vec<&str> = SIGNALS
        .iter()
        .filter(|&&s| r.age_s(s).is_none())
        .map(|s| s.name())
        .collect();
    if never.is_empty() {
        return;
    }
    let power = if r.age_s(Signal::Power).is_some() {
        "the measured power and energy still count"
    } else {
        "and no power is measured: energy cannot be counted"
    };
    tracing::warn!(
        "no {} heard in {NEVER_AFTER_S:.0} s: the models see those features held at a neutral value and marked stale; {power}",
        never.join(", ")
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Position stops for 2 s every 5 s (attitude keeps the clock going); returns the
    /// watch after `secs` seconds.
    fn flapping(w: &mut RateWatch, r: &mut Resampler, from_s: i64, secs: i64) {
        for k in from_s * 10..(from_s + secs) * 10 {
            let t = k * 100_000;
            r.update(Signal::Attitude, t, &[1.0, 0.0, 0.0, 0.0]);
            if (k / 10) % 5 < 3 {
                r.update(Signal::Position, t, &[8.5, 47.4, 400.0]);
            }
            w.check(r, t, |_| Some("TEST"));
        }
    }

    #[test]
    fn a_flapping_signal_is_said_once_a_repeat_and_the_rest_counted() {
        let (mut w, mut r) = (RateWatch::default(), Resampler::new(10.0, 0.5, 10.0));
        let pos = Signal::Position as usize;
        flapping(&mut w, &mut r, 0, 50);
        // ten silences in 50 s: the first said, nine counted
        assert_eq!(w.said[pos].said_at, Some(3_500_000));
        assert_eq!(w.said[pos].unsaid, 9);
        flapping(&mut w, &mut r, 50, 20);
        // the first silence past 60 s after the one said is said, with the count
        assert_eq!(w.said[pos].said_at, Some(63_500_000));
        assert_eq!(w.said[pos].unsaid, 1, "the one at 68.5 s is counted anew");
    }
}
