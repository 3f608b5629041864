//! Rolling windows of T fixed-rate samples: what every model sees. Owner: features (issue 3).

use crate::telemetry::Sample;

/// The paper's window length.
pub const DEFAULT_T: usize = 10;

/// The last `T` samples, oldest first. The estimate a window yields belongs to its last
/// sample's time.
#[derive(Debug, Clone, PartialEq)]
pub struct Window {
    /// Oldest first; `samples.len()` is the window length T.
    pub samples: Vec<Sample>,
}

impl Window {
    /// The newest sample (the one the estimate is for).
    pub fn last(&self) -> &Sample {
        // A Window is never built empty (the builder only emits full rings).
        &self.samples[self.samples.len() - 1]
    }
    /// Grid time of the newest sample.
    pub fn t_s(&self) -> f64 {
        self.last().t_s
    }
}
