//! [`LiveMission`] as a step of one vehicle's chain: the telemetry stage hands it each of the
//! vehicle's messages (and, on a live link, a tick for the download's timeouts); it sends
//! the protocol's frames on the vehicle's link and the statuses to the energy stage.

use tokio::sync::mpsc;

use super::{LiveMission, LiveSetup};
use crate::report::status::LinkHandle;
use crate::report::MissionUpdate;
use crate::source::TimedMessage;
use crate::MavMessage;

/// Depth of the status channel to the energy stage (at ~1 Hz: many minutes of lead).
pub const STATUS_DEPTH: usize = 1024;

/// One vehicle's live mission forecast, driven by its chain.
pub struct MissionStep {
    live: LiveMission,
    /// Download over the link (a live link): the client's clock is the wall clock since
    /// `start`; else (a replay) each message's source time.
    active: bool,
    start: tokio::time::Instant,
    /// The vehicle's links (its network's).
    link: LinkHandle,
    statuses: mpsc::Sender<MissionUpdate>,
    out: Vec<MavMessage>,
}

impl MissionStep {
    /// The step for a vehicle, and the receiver of its statuses (the energy stage's).
    pub fn new(setup: LiveSetup, link: LinkHandle) -> (Self, mpsc::Receiver<MissionUpdate>) {
        let (statuses, rx) = mpsc::channel(STATUS_DEPTH);
        let step = Self {
            active: setup.active,
            live: LiveMission::new(setup),
            start: tokio::time::Instant::now(),
            link,
            statuses,
            out: Vec::new(),
        };
        (step, rx)
    }

    /// Whether it downloads over the link (then [`MissionStep::tick`] must run every
    /// [`super::TICK`]).
    pub fn active(&self) -> bool {
        self.active
    }

    /// One of the vehicle's messages (or a ground station's mission messages to it).
    pub fn on_message(&mut self, m: &TimedMessage) {
        let now = if self.active {
            self.start.elapsed().as_secs_f64()
        } else {
            m.t_s
        };
        if let Some(s) = self.live.on_message(now, m, &mut self.out) {
            if self.statuses.try_send(s).is_err() {
                tracing::debug!("mission status dropped (the energy stage is far behind)");
            }
        }
        self.send();
    }

    /// The download's timeouts (a live link).
    pub fn tick(&mut self) {
        self.live
            .tick(self.start.elapsed().as_secs_f64(), &mut self.out);
        self.send();
    }

    fn send(&mut self) {
        let Some((sys, comp)) = self.live.client().sender() else {
            self.out.clear();
            return;
        };
        for msg in self.out.drain(..) {
            // Numbered by the link's (its network's) one writer of this identity.
            if !self.link.send_as(sys, comp, &msg) {
                tracing::debug!("mission protocol frame not sent (no link or link full)");
            }
        }
    }
}

impl Drop for MissionStep {
    fn drop(&mut self) {
        let st = self.live.client().stats;
        tracing::debug!(
            downloads = st.downloads,
            resends = st.resends,
            failures = st.failures,
            "mission protocol"
        );
    }
}
