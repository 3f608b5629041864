//! Turning decoded frames into [`TimedMessage`]s: which clock a source's `t_s` comes from,
//! and how a broken clock is kept from poisoning replay pacing.

use std::time::Instant;

use super::{Frame, FrameDecoder, Framing};
use crate::report::status::IngestStats;
use crate::source::TimedMessage;

/// A raw timestamp this far *behind* the last one is a clock jump, s. Smaller steps back
/// (messages of different types stamped a little out of order) are held at the last `t_s`.
pub const MAX_BACKWARD_S: f64 = 2.0;
/// A raw timestamp this far *ahead* of the last one is a clock jump, s: a minute with
/// nothing recorded is a hole in the log, and replay should not sit through it.
pub const MAX_FORWARD_S: f64 = 60.0;

/// Maps a source's raw timestamps (seconds on whatever clock it has) to `t_s`: 0 at the
/// first timestamp, never decreasing, and immune to a broken clock.
///
/// A timestamp more than [`MAX_BACKWARD_S`] behind or [`MAX_FORWARD_S`] ahead of the last
/// accepted one (a zero, an absurd value, a reboot, a wrap) is a *clock jump*: counted
/// once, and the message keeps the last `t_s`. If the next timestamp agrees with the old
/// clock, the jump was one bad value and time goes on as before; if it agrees with the
/// jumped value, the clock really was re-set and `t_s` continues from where it stood.
#[derive(Debug, Default, Clone)]
pub struct Clock {
    /// (raw, t_s) pair `t_s` is measured from.
    anchor: Option<(f64, f64)>,
    /// Raw value of the last accepted timestamp.
    last_raw: f64,
    /// Last `t_s` handed out.
    last_t: f64,
    /// A jumped-to raw value waiting for confirmation by the next timestamp.
    pending: Option<f64>,
}

impl Clock {
    /// `t_s` for raw timestamp `raw_s`, and whether it was a clock jump (count it).
    pub fn map(&mut self, raw_s: f64) -> (f64, bool) {
        if !raw_s.is_finite() {
            return (self.last_t, true);
        }
        let Some((a_raw, a_t)) = self.anchor else {
            self.anchor = Some((raw_s, 0.0));
            self.last_raw = raw_s;
            return (0.0, false);
        };
        let within = |from: f64| (-MAX_BACKWARD_S..=MAX_FORWARD_S).contains(&(raw_s - from));
        if within(self.last_raw) {
            self.pending = None;
            self.last_raw = raw_s;
            self.last_t = self.last_t.max(a_t + (raw_s - a_raw));
            return (self.last_t, false);
        }
        if let Some(p) = self.pending.take() {
            if within(p) {
                // The clock was re-set: carry on from where t_s stood.
                self.anchor = Some((p, self.last_t));
                self.last_raw = raw_s;
                self.last_t = self.last_t.max(self.last_t + (raw_s - p));
                return (self.last_t, false);
            }
        }
        self.pending = Some(raw_s);
        (self.last_t, true)
    }
}

/// Where a source's `t_s` comes from.
#[derive(Debug, Clone)]
pub enum TimeBase {
    /// The tlog record stamps (µs), through a [`Clock`]: seconds since the first record.
    TlogStamp(Clock),
    /// The messages' own `time_boot_ms` (raw streams), through a [`Clock`]: seconds since
    /// the first message that carried it. Only the first (system, component) seen with a
    /// boot time sets the clock (the autopilot, normally); messages without one, or from
    /// other components, take the latest known time (0 before any).
    BootTime {
        clock: Clock,
        owner: Option<(u32, u8)>,
        now: f64,
    },
    /// Arrival time on this machine (live links): seconds since `start`, monotonic.
    Arrival { start: Instant },
}

/// A [`FrameDecoder`] plus a [`TimeBase`]: bytes in, [`TimedMessage`]s out.
pub struct TimedReader {
    decoder: FrameDecoder,
    base: TimeBase,
}

impl TimedReader {
    /// A `.tlog` reader.
    pub fn tlog() -> Self {
        Self {
            decoder: FrameDecoder::new(Framing::Tlog),
            base: TimeBase::TlogStamp(Clock::default()),
        }
    }
    /// A raw-stream reader timed by `time_boot_ms`.
    pub fn raw() -> Self {
        Self {
            decoder: FrameDecoder::new(Framing::Stream),
            base: TimeBase::BootTime {
                clock: Clock::default(),
                owner: None,
                now: 0.0,
            },
        }
    }
    /// A live-link reader timed by arrival since `start`.
    pub fn arrival(start: Instant) -> Self {
        Self {
            decoder: FrameDecoder::new(Framing::Stream),
            base: TimeBase::Arrival { start },
        }
    }
    /// The input format this reader expects, in words (for "no MAVLink in this file").
    pub fn expected_format(&self) -> &'static str {
        match self.base {
            TimeBase::TlogStamp(_) => {
                "a .tlog: an 8-byte big-endian microsecond timestamp before each MAVLink frame (start byte 0xFE or 0xFD)"
            }
            _ => "a raw MAVLink byte stream: frames starting with 0xFE (v1) or 0xFD (v2)",
        }
    }
    /// Append input.
    pub fn push(&mut self, bytes: &[u8]) {
        self.decoder.push(bytes);
    }
    /// End of input (counts a truncated last frame).
    pub fn finish(&mut self) {
        self.decoder.finish();
    }
    /// Check MAVLink 2 signatures (see [`crate::source::links::signing`]) from now on.
    pub fn set_verifier(&mut self, verifier: super::SharedVerifier) {
        self.decoder.set_verifier(verifier);
    }

    /// Input bytes by what they turned out to be (see [`super::ByteTally`]).
    pub fn byte_tally(&self) -> super::ByteTally {
        self.decoder.byte_tally()
    }
    /// Drop a partial frame and sequence history (a new connection).
    pub fn reset(&mut self) {
        self.decoder.reset();
    }
    /// The next message, with everything skipped counted in `stats` (clock jumps count
    /// as gaps and as `clock_jumps`).
    pub fn next_message(&mut self, stats: &IngestStats) -> Option<TimedMessage> {
        let Frame {
            header,
            msg,
            stamp_us,
            ..
        } = self.decoder.next_frame(stats)?;
        let (t_s, jumped) = match &mut self.base {
            TimeBase::TlogStamp(clock) => {
                // the first stamp is the log's origin (its Unix time, for the vehicle store)
                let _ = stats.log_origin_us.compare_exchange(
                    0,
                    stamp_us.unwrap_or(0),
                    std::sync::atomic::Ordering::Relaxed,
                    std::sync::atomic::Ordering::Relaxed,
                );
                clock.map(stamp_us.unwrap_or(0) as f64 * 1e-6)
            }
            TimeBase::BootTime { clock, owner, now } => {
                let mut jumped = false;
                if let Some(ms) = crate::source::logs::raw::boot_time_ms(&msg) {
                    let me = (header.system_id, header.component_id);
                    if owner.is_none() {
                        *owner = Some(me);
                    }
                    if *owner == Some(me) {
                        let (t, j) = clock.map(ms as f64 * 1e-3);
                        *now = t;
                        jumped = j;
                    }
                }
                (*now, jumped)
            }
            TimeBase::Arrival { start } => (start.elapsed().as_secs_f64(), false),
        };
        if jumped {
            IngestStats::add(&stats.gaps, 1);
            IngestStats::add(&stats.clock_jumps, 1);
        }
        Some(TimedMessage::new(t_s, header, msg))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_bad_stamp_is_one_jump_and_time_goes_on() {
        let mut c = Clock::default();
        assert_eq!(c.map(100.0), (0.0, false));
        assert_eq!(c.map(100.5), (0.5, false));
        assert_eq!(c.map(0.0), (0.5, true)); // zero stamp
        assert_eq!(c.map(101.0), (1.0, false)); // old clock resumes
        assert_eq!(c.map(1e12), (1.0, true)); // absurd
        assert!(!c.map(101.2).1);
    }

    #[test]
    fn a_reset_clock_is_one_jump_then_continues() {
        let mut c = Clock::default();
        c.map(5000.0);
        c.map(5001.0);
        assert_eq!(c.map(0.2), (1.0, true)); // reboot
        let (t, j) = c.map(0.7);
        assert!(!j);
        assert!((t - 1.5).abs() < 1e-9, "{t}");
        let (t, _) = c.map(1.7);
        assert!((t - 2.5).abs() < 1e-9, "{t}");
    }

    #[test]
    fn small_steps_back_are_held_not_jumps() {
        let mut c = Clock::default();
        c.map(10.0);
        c.map(11.0);
        assert_eq!(c.map(10.5), (1.0, false));
        assert_eq!(c.map(11.5), (1.5, false));
        assert_eq!(c.map(f64::NAN), (1.5, true));
    }
}
