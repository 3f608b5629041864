//! The MAVLink mission protocol, the ground-station (client) side, as a pure state
//! machine: messages and the time in, messages to send and finished downloads out. No
//! I/O and no clock of its own; the driver ([`super::live`]) sends what it says and calls
//! [`MissionClient::tick`] for the timeouts.
//!
//! ## Download (active, on a live link)
//!
//! ```text
//! MISSION_REQUEST_LIST ─▶            ◀─ MISSION_COUNT(n)
//! MISSION_REQUEST_INT(0) ─▶          ◀─ MISSION_ITEM_INT(0)   (MISSION_ITEM accepted too)
//! …                                  …
//! MISSION_REQUEST_INT(n−1) ─▶        ◀─ MISSION_ITEM_INT(n−1)
//! MISSION_ACK(ACCEPTED) ─▶
//! ```
//!
//! - An unanswered request is sent again after [`RESEND_S`], at most [`MAX_TRIES`] times
//!   in all; then the download fails and is tried again from the start after
//!   [`RETRY_AFTER_S`]. A MISSION_ACK with an error from the vehicle ends it likewise.
//! - It starts once an autopilot's HEARTBEAT is heard (that sender is the target), and
//!   again whenever MISSION_CURRENT's `mission_id` or `total` differs from what it was
//!   when the mission in hand was downloaded (the mission was changed on the vehicle).
//! - ArduPilot's item 0 is its home position; what to make of that is the caller's
//!   business ([`Mission::home_is_item0`] says whose autopilot it is).
//!
//! ## Overheard (passive: a replayed `.tlog`, or another ground station's download)
//!
//! A MISSION_COUNT followed by items with `seq` 0..count−1, in either direction (a
//! ground station downloading or uploading), is assembled the same way; when every item
//! is there it is a finished [`Mission`]. Only `mission_type` MISSION (0) counts: fences
//! and rally points are other lists.

use crate::dialect as d;
use crate::MavMessage;

/// Seconds before an unanswered request is sent again.
pub const RESEND_S: f64 = 1.5;
/// Requests sent for one step before the download gives up.
pub const MAX_TRIES: u32 = 5;
/// Seconds after a failed download before it is tried again.
pub const RETRY_AFTER_S: f64 = 10.0;

/// One mission item as the protocol carried it (MISSION_ITEM_INT or MISSION_ITEM),
/// positions in degrees.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct MissionItem {
    pub seq: u16,
    /// MAV_FRAME number.
    pub frame: u32,
    /// MAV_CMD number.
    pub command: u32,
    /// param1..param4.
    pub params: [f64; 4],
    /// Latitude, deg (x).
    pub lat_deg: f64,
    /// Longitude, deg (y).
    pub lon_deg: f64,
    /// Altitude, m (z), in `frame`.
    pub alt_m: f64,
}

impl MissionItem {
    /// An item from a MISSION_ITEM(_INT)'s fields, latitude and longitude in degrees.
    fn of(seq: u16, frame: u32, command: u32, p: [f32; 4], lat_lon: [f64; 2], z: f32) -> Self {
        Self {
            seq,
            frame,
            command,
            params: p.map(f64::from),
            lat_deg: lat_lon[0],
            lon_deg: lat_lon[1],
            alt_m: f64::from(z),
        }
    }
}

/// Where a finished mission came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Origin {
    /// Downloaded by this client over the live link.
    Downloaded,
    /// Overheard: items a replayed log (or another ground station) carried.
    Overheard,
}

/// A whole mission list.
#[derive(Debug, Clone, PartialEq)]
pub struct Mission {
    pub items: Vec<MissionItem>,
    /// MISSION_CURRENT's `mission_id` when it was taken (0: not given).
    pub mission_id: u32,
    pub origin: Origin,
    /// The vehicle is ArduPilot, whose item 0 is home (from its HEARTBEAT; a log with no
    /// autopilot heartbeat: true when item 0 is a NAV_WAYPOINT in an absolute frame,
    /// ArduPilot's home row).
    pub home_is_item0: bool,
}

/// What the client has to say after a message or a tick.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// A mission finished downloading (or was overheard whole).
    Mission(Mission),
    /// A download gave up (why); it is tried again later.
    Failed(String),
}

#[derive(Debug, Clone, PartialEq)]
enum State {
    Idle,
    /// MISSION_REQUEST_LIST sent.
    WaitCount {
        sent_at: f64,
        tries: u32,
    },
    /// Items being requested one by one.
    Items {
        items: Vec<Option<MissionItem>>,
        next: u16,
        sent_at: f64,
        tries: u32,
    },
}

/// Counters, for logs and tests.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct ClientStats {
    /// Requests sent again after a timeout.
    pub resends: u64,
    /// Downloads finished.
    pub downloads: u64,
    /// Downloads that gave up.
    pub failures: u64,
}

/// The client. `active`: it may send (a live link); else it only overhears.
#[derive(Debug)]
pub struct MissionClient {
    active: bool,
    /// Its own system id (None: the target vehicle's, as a companion computer of it) and
    /// component id.
    own: (Option<u8>, u8),
    target: Option<(u8, u8)>,
    ardupilot: Option<bool>,
    state: State,
    /// MISSION_CURRENT's (mission_id, total), latest heard.
    current_sig: Option<(u32, u16)>,
    /// The signature when the mission in hand was requested (None: no mission yet).
    held_sig: Option<Option<(u32, u16)>>,
    retry_at: f64,
    overheard: Option<Vec<Option<MissionItem>>>,
    pub stats: ClientStats,
}

impl MissionClient {
    /// A client sending as `system_id` (None: the vehicle's own, as its companion
    /// computer would) and `component_id` when `active`.
    pub fn new(active: bool, system_id: Option<u8>, component_id: u8) -> Self {
        Self {
            active,
            own: (system_id, component_id),
            target: None,
            ardupilot: None,
            state: State::Idle,
            current_sig: None,
            held_sig: None,
            retry_at: f64::NEG_INFINITY,
            overheard: None,
            stats: ClientStats::default(),
        }
    }

    /// The vehicle (system, component) it talks to, once an autopilot was heard.
    pub fn target(&self) -> Option<(u8, u8)> {
        self.target
    }

    /// Who it sends as (system, component); None while it has no system id (its own is not
    /// set and no vehicle was heard yet: it sends nothing then).
    pub fn sender(&self) -> Option<(u8, u8)> {
        self.own
            .0
            .or(self.target.map(|t| t.0))
            .map(|sys| (sys, self.own.1))
    }

    /// Whether a download is under way.
    pub fn busy(&self) -> bool {
        self.state != State::Idle
    }

    /// One message heard at `now_s`; messages to send go to `out`.
    // MISSION_ITEM is deprecated, and still what older ground stations log.
    #[allow(deprecated)]
    pub fn on_message(
        &mut self,
        now_s: f64,
        header: &mavlink::MavHeader,
        msg: &MavMessage,
        out: &mut Vec<MavMessage>,
    ) -> Option<Event> {
        let from = (
            u8::try_from(header.system_id).unwrap_or(0),
            header.component_id,
        );
        if Some(from) == self.sender() {
            return None;
        }
        let from_target = self.target == Some(from);
        match msg {
            MavMessage::HEARTBEAT(h) => {
                let autopilot = h.autopilot != d::MavAutopilot::MAV_AUTOPILOT_INVALID
                    && h.mavtype != d::MavType::MAV_TYPE_GCS;
                if autopilot && self.target.is_none() {
                    self.target = Some(from);
                    self.ardupilot =
                        Some(h.autopilot == d::MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA);
                }
                self.maybe_start(now_s, out);
                None
            }
            MavMessage::MISSION_CURRENT(c) if from_target || self.target.is_none() => {
                self.current_sig = Some((c.mission_id, c.total));
                // Requested before any MISSION_CURRENT was heard: this is that mission's.
                if self.held_sig == Some(None) {
                    self.held_sig = Some(self.current_sig);
                }
                self.maybe_start(now_s, out);
                None
            }
            MavMessage::MISSION_COUNT(c) if is_mission(c.mission_type) => {
                if from_target && matches!(self.state, State::WaitCount { .. }) {
                    if c.count == 0 {
                        self.state = State::Idle;
                        out.push(self.ack(d::MavMissionResult::MAV_MISSION_ACCEPTED));
                        return Some(self.finish(Vec::new(), Origin::Downloaded));
                    }
                    self.state = State::Items {
                        items: vec![None; usize::from(c.count)],
                        next: 0,
                        sent_at: now_s,
                        tries: 1,
                    };
                    out.push(self.request(0));
                    return None;
                }
                if !self.busy() {
                    if c.count == 0 {
                        // an empty list overheard: the mission was cleared
                        self.overheard = None;
                        return Some(self.finish(Vec::new(), Origin::Overheard));
                    }
                    self.overheard = Some(vec![None; usize::from(c.count)]);
                }
                None
            }
            // the same item, positions in 1e-7 degrees or in degrees
            MavMessage::MISSION_ITEM_INT(i) if is_mission(i.mission_type) => {
                let at = [f64::from(i.x) * 1e-7, f64::from(i.y) * 1e-7];
                let p = [i.param1, i.param2, i.param3, i.param4];
                let item = MissionItem::of(i.seq, i.frame as u32, i.command as u32, p, at, i.z);
                self.on_item(now_s, from_target, item, out)
            }
            MavMessage::MISSION_ITEM(i) if is_mission(i.mission_type) => {
                let at = [f64::from(i.x), f64::from(i.y)];
                let p = [i.param1, i.param2, i.param3, i.param4];
                let item = MissionItem::of(i.seq, i.frame as u32, i.command as u32, p, at, i.z);
                self.on_item(now_s, from_target, item, out)
            }
            MavMessage::MISSION_ACK(a)
                if from_target && self.busy() && is_mission(a.mission_type) =>
            {
                if a.mavtype == d::MavMissionResult::MAV_MISSION_ACCEPTED {
                    return None;
                }
                Some(self.fail(
                    now_s,
                    format!("the vehicle refused the download: {:?}", a.mavtype),
                ))
            }
            _ => None,
        }
    }

    fn on_item(
        &mut self,
        now_s: f64,
        from_target: bool,
        item: MissionItem,
        out: &mut Vec<MavMessage>,
    ) -> Option<Event> {
        let seq = usize::from(item.seq);
        if from_target {
            if let State::Items {
                items,
                next,
                sent_at,
                tries,
            } = &mut self.state
            {
                if seq < items.len() && items[seq].is_none() {
                    items[seq] = Some(item);
                }
                match items.iter().position(Option::is_none) {
                    Some(missing) => {
                        let missing = missing as u16;
                        if missing != *next {
                            *next = missing;
                            *sent_at = now_s;
                            *tries = 1;
                            out.push(self.request(missing));
                        }
                        return None;
                    }
                    None => {
                        let items = std::mem::take(items).into_iter().flatten().collect();
                        self.state = State::Idle;
                        out.push(self.ack(d::MavMissionResult::MAV_MISSION_ACCEPTED));
                        return Some(self.finish(items, Origin::Downloaded));
                    }
                }
            }
        }
        // Overheard (a log, another ground station).
        let list = self.overheard.as_mut()?;
        if seq < list.len() {
            list[seq] = Some(item);
        }
        if list.iter().all(Option::is_some) {
            let items = self
                .overheard
                .take()
                .unwrap_or_default()
                .into_iter()
                .flatten()
                .collect();
            return Some(self.finish(items, Origin::Overheard));
        }
        None
    }

    /// Timeouts: resend what was not answered, or give up. Call every few hundred ms.
    pub fn tick(&mut self, now_s: f64, out: &mut Vec<MavMessage>) -> Option<Event> {
        let (sent_at, tries) = match &mut self.state {
            State::Idle => {
                self.maybe_start(now_s, out);
                return None;
            }
            State::WaitCount { sent_at, tries } | State::Items { sent_at, tries, .. } => {
                (sent_at, tries)
            }
        };
        if now_s - *sent_at < RESEND_S {
            return None;
        }
        if *tries >= MAX_TRIES {
            return Some(self.fail(now_s, format!("no answer after {MAX_TRIES} requests")));
        }
        *tries += 1;
        *sent_at = now_s;
        self.stats.resends += 1;
        let msg = match &self.state {
            State::Items { next, .. } => self.request(*next),
            _ => self.request_list(),
        };
        out.push(msg);
        None
    }

    fn maybe_start(&mut self, now_s: f64, out: &mut Vec<MavMessage>) {
        if !self.active || self.busy() || self.target.is_none() || now_s < self.retry_at {
            return;
        }
        let wanted = match self.held_sig {
            None => true,
            Some(held) => self.current_sig.is_some() && held != self.current_sig,
        };
        if wanted {
            self.held_sig = Some(self.current_sig);
            self.state = State::WaitCount {
                sent_at: now_s,
                tries: 1,
            };
            out.push(self.request_list());
        }
    }

    fn fail(&mut self, now_s: f64, why: String) -> Event {
        self.state = State::Idle;
        self.held_sig = None;
        self.retry_at = now_s + RETRY_AFTER_S;
        self.stats.failures += 1;
        Event::Failed(why)
    }

    fn finish(&mut self, items: Vec<MissionItem>, origin: Origin) -> Event {
        if origin == Origin::Downloaded {
            self.stats.downloads += 1;
        }
        let home_is_item0 = self.ardupilot.unwrap_or_else(|| {
            items
                .first()
                .is_some_and(|i| i.command == 16 && i.frame == 0)
        });
        Event::Mission(Mission {
            items,
            mission_id: self.current_sig.map_or(0, |s| s.0),
            origin,
            home_is_item0,
        })
    }

    fn targets(&self) -> (u8, u8) {
        self.target.unwrap_or((1, 1))
    }

    fn request_list(&self) -> MavMessage {
        let (target_system, target_component) = self.targets();
        MavMessage::MISSION_REQUEST_LIST(d::MISSION_REQUEST_LIST_DATA {
            target_system,
            target_component,
            mission_type: d::MavMissionType::MAV_MISSION_TYPE_MISSION,
        })
    }

    fn request(&self, seq: u16) -> MavMessage {
        let (target_system, target_component) = self.targets();
        MavMessage::MISSION_REQUEST_INT(d::MISSION_REQUEST_INT_DATA {
            seq,
            target_system,
            target_component,
            mission_type: d::MavMissionType::MAV_MISSION_TYPE_MISSION,
        })
    }

    fn ack(&self, result: d::MavMissionResult) -> MavMessage {
        let (target_system, target_component) = self.targets();
        MavMessage::MISSION_ACK(d::MISSION_ACK_DATA {
            target_system,
            target_component,
            mavtype: result,
            mission_type: d::MavMissionType::MAV_MISSION_TYPE_MISSION,
            ..Default::default()
        })
    }
}

fn is_mission(t: d::MavMissionType) -> bool {
    t == d::MavMissionType::MAV_MISSION_TYPE_MISSION
}

#[cfg(test)]
#[path = "protocol_tests.rs"]
mod tests;
