//! Rolling windows of T fixed-rate samples: what every model sees.

use crate::features::Sample;

/// The paper's window length.
pub const DEFAULT_T: usize = 10;

/// The last `T` samples, oldest first. The estimate a window yields belongs to its last
/// sample's time.
#[derive(Debug, Clone, PartialEq)]
pub struct Window {
    /// Oldest first; `samples.len()` is the window length T.
    pub samples: Vec<Sample>,
    /// When the newest message that went into it reached dronewatt (monotonic; the
    /// pipeline stamps it, `None` for windows not from a source): the start of the
    /// message → estimate latency.
    pub arrived: Option<std::time::Instant>,
}

impl Window {
    /// The newest sample (the one the estimate is for).
    pub fn last(&self) -> &Sample {
        // A Window is never built empty (the builder only emits full rings).
        &self.samples[self.samples.len() - 1]
    }
    /// The sample `lag` steps before the newest (`back(0)` = [`Window::last`]); the oldest
    /// when the window is shorter. A model trained with a target lag estimates this one.
    pub fn back(&self, lag: usize) -> &Sample {
        &self.samples[self.samples.len().saturating_sub(1 + lag)]
    }
    /// Grid time of the newest sample.
    pub fn t_s(&self) -> f64 {
        self.last().t_s
    }
}

/// Builds sliding windows: after each new sample, once `T` samples are held, the last `T`
/// as one [`Window`] (stride 1). [`WindowRing::clear`] starts over, so no window spans a
/// telemetry gap.
#[derive(Debug, Clone)]
pub struct WindowRing {
    t: usize,
    ring: std::collections::VecDeque<Sample>,
}

impl WindowRing {
    /// A ring of `t` samples (at least 1).
    pub fn new(t: usize) -> Self {
        let t = t.max(1);
        Self {
            t,
            ring: std::collections::VecDeque::with_capacity(t + 1),
        }
    }
    /// Add a sample; returns the window it completes, if the ring is full.
    pub fn push(&mut self, s: Sample) -> Option<Window> {
        if self.ring.len() == self.t {
            self.ring.pop_front();
        }
        self.ring.push_back(s);
        (self.ring.len() == self.t).then(|| Window {
            samples: self.ring.iter().cloned().collect(),
            arrived: None,
        })
    }
    /// Forget the held samples (after a gap).
    pub fn clear(&mut self) {
        self.ring.clear();
    }
}
