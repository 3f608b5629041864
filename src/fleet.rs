//! Many vehicles on one link: which senders are vehicles, which vehicle a message is
//! about, which vehicles this instance watches (`--vehicles`), and when a vehicle counts
//! as lost and when it is dropped. Pure: no I/O, no clocks (the caller passes the time).
//! [`crate::pipeline`] puts a [`Demux`] in front of one vehicle chain per system id.
//!
//! A vehicle appears with its first HEARTBEAT from a vehicle: not a ground station
//! (`MAV_TYPE_GCS`), not a companion or other onboard component (`MAV_TYPE_ONBOARD_CONTROLLER`,
//! `MAV_AUTOPILOT_INVALID`: dronewatt's own heartbeat is one). So that a log that begins
//! between two heartbeats loses nothing, a telemetry message the chain reads (ATTITUDE,
//! GLOBAL_POSITION_INT, BATTERY_STATUS … — never sent by a ground station) also opens a
//! vehicle, unless that system id has only ever sent a non-vehicle heartbeat.
//!
//! A vehicle with no message for `lost_after_s` is reported lost (alert `vehicle_lost`,
//! cleared when it is heard again); after `drop_after_s` it is dropped: its chain ends
//! (alert `vehicle_dropped`), and a later message makes it a new vehicle.

use std::collections::BTreeMap;

use crate::source::TimedMessage;
use crate::MavMessage;

/// The `[fleet]` table: many vehicles on one link.
#[derive(Debug, Clone, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct FleetConfig {
    /// A vehicle with no message for this long is reported lost (alert `vehicle_lost`), s.
    /// Default 10 (a `telemetry_lost` alert rule is the quicker, configurable alarm).
    pub lost_after_s: f64,
    /// A vehicle with no message for this long is dropped: its chain ends (alert
    /// `vehicle_dropped`), s. Longer than `lost_after_s`. Default 60.
    pub drop_after_s: f64,
    /// Which system ids this instance watches: ids and ranges, e.g. `"1-125"` or
    /// `"3,7,10-20"` (`monitor --vehicles` overrides it). Others are ignored and counted, so
    /// several instances can split one link's vehicles. Default: all (1-255).
    pub vehicles: Option<String>,
    /// With more than one vehicle, the longest a window waits for other vehicles' windows
    /// to join its batch before the models run, ms (one vehicle never waits). Default 2;
    /// 0 runs whatever is queued at once.
    pub batch_wait_ms: f64,
    /// How often each vehicle's LSTM estimate is computed, Hz; the windows in between
    /// carry the vehicle's latest one (held). Default: every window (`telemetry.rate_hz`).
    /// The physics models, energy and alerts always run on every window.
    pub lstm_rate_hz: Option<f64>,
}

impl Default for FleetConfig {
    fn default() -> Self {
        Self { lost_after_s: 10.0, drop_after_s: 60.0, vehicles: None, batch_wait_ms: 2.0, lstm_rate_hz: None }
    }
}

impl FleetConfig {
    /// Range checks; each message names the key (several errors: one per line).
    pub fn validate(&self) -> Result<(), String> {
        let mut errs = Vec::new();
        if !(self.lost_after_s > 0.0 && self.lost_after_s.is_finite()) {
            errs.push(format!("fleet.lost_after_s = {}: must be > 0", self.lost_after_s));
        }
        if !(self.drop_after_s > self.lost_after_s && self.drop_after_s.is_finite()) {
            errs.push(format!("fleet.drop_after_s = {}: must be longer than fleet.lost_after_s ({})", self.drop_after_s, self.lost_after_s));
        }
        if !(0.0..=100.0).contains(&self.batch_wait_ms) {
            errs.push(format!("fleet.batch_wait_ms = {}: must be 0..=100 ms", self.batch_wait_ms));
        }
        if let Some(r) = self.lstm_rate_hz {
            if !(r > 0.0 && r <= 100.0) {
                errs.push(format!("fleet.lstm_rate_hz = {r}: must be in (0, 100] Hz"));
            }
        }
        if let Some(v) = &self.vehicles {
            if let Err(e) = VehicleFilter::parse(v) {
                errs.push(format!("fleet.vehicles = {v:?}: {e}"));
            }
        }
        if errs.is_empty() { Ok(()) } else { Err(errs.join("\n")) }
    }
}

/// A set of MAVLink system ids (1..=255), written as ids and ranges: `1-125`, `3,7,10-20`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct VehicleFilter {
    ids: [bool; 256],
}

impl Default for VehicleFilter {
    /// Every id.
    fn default() -> Self {
        let mut ids = [true; 256];
        ids[0] = false;
        Self { ids }
    }
}

impl VehicleFilter {
    /// Parse `1-125`, `3,7,10-20`; an id outside 1..=255, a reversed range or an empty list
    /// is an error that says which part.
    pub fn parse(s: &str) -> Result<Self, String> {
        let mut ids = [false; 256];
        let id = |p: &str| -> Result<u8, String> {
            match p.trim().parse::<u8>() {
                Ok(v) if v > 0 => Ok(v),
                _ => Err(format!("{:?} is not a system id (1-255)", p.trim())),
            }
        };
        for part in s.split(',') {
            let (lo, hi) = match part.split_once('-') {
                Some((a, b)) => (id(a)?, id(b)?),
                None => (id(part)?, id(part)?),
            };
            if lo > hi {
                return Err(format!("range {:?} runs backwards", part.trim()));
            }
            ids[usize::from(lo)..=usize::from(hi)].iter_mut().for_each(|b| *b = true);
        }
        Ok(Self { ids })
    }
    /// Whether `id` is in the set.
    pub fn contains(&self, id: u32) -> bool {
        usize::try_from(id).ok().and_then(|i| self.ids.get(i)).copied().unwrap_or(false)
    }
}

/// Whether a HEARTBEAT comes from a vehicle's autopilot (not a ground station, a companion
/// computer or another onboard component).
pub fn is_vehicle_heartbeat(h: &crate::dialect::HEARTBEAT_DATA) -> bool {
    use crate::dialect::{MavAutopilot, MavType};
    h.autopilot != MavAutopilot::MAV_AUTOPILOT_INVALID
        && !matches!(h.mavtype, MavType::MAV_TYPE_GCS | MavType::MAV_TYPE_ONBOARD_CONTROLLER)
}

/// Telemetry only a vehicle sends (what the telemetry stage reads its signals from).
fn is_vehicle_telemetry(m: &MavMessage) -> bool {
    matches!(
        m,
        MavMessage::ATTITUDE_QUATERNION(_)
            | MavMessage::ATTITUDE(_)
            | MavMessage::HIGHRES_IMU(_)
            | MavMessage::SCALED_IMU(_)
            | MavMessage::RAW_IMU(_)
            | MavMessage::LOCAL_POSITION_NED(_)
            | MavMessage::ODOMETRY(_)
            | MavMessage::GLOBAL_POSITION_INT(_)
            | MavMessage::GPS_RAW_INT(_)
            | MavMessage::HOME_POSITION(_)
            | MavMessage::WIND(_)
            | MavMessage::WIND_COV(_)
            | MavMessage::VFR_HUD(_)
            | MavMessage::BATTERY_STATUS(_)
            | MavMessage::SYS_STATUS(_)
    )
}

/// Where one message goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Route {
    /// Not about a vehicle this instance watches.
    Ignore,
    /// To vehicle `id`'s chain; `new`: start that chain first; `back`: it had been lost.
    Vehicle { id: u8, new: bool, back: bool },
}

/// What the demultiplexer noticed as time went by.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FleetEvent {
    /// Nothing heard from vehicle `id` for `silent_s` (≥ `lost_after_s`), at time `t_s`.
    Lost { id: u8, t_s: f64, silent_s: f64 },
    /// A lost vehicle was heard again at `t_s` ([`Route::Vehicle`]'s `back`).
    Back { id: u8, t_s: f64 },
    /// Nothing heard for `silent_s` (≥ `drop_after_s`): its chain ends.
    Dropped { id: u8, t_s: f64, silent_s: f64 },
}

#[derive(Debug)]
struct Seen {
    last_t: f64,
    lost: bool,
}

/// Which vehicle each message is about, and which vehicles went silent (module docs).
#[derive(Debug)]
pub struct Demux {
    lost_after_s: f64,
    drop_after_s: f64,
    filter: VehicleFilter,
    vehicles: BTreeMap<u8, Seen>,
    not_vehicles: [bool; 256],
    filtered: u64,
}

impl Demux {
    /// A demultiplexer for this configuration (checked: [`FleetConfig::validate`]);
    /// `filter` overrides the configured `vehicles`.
    pub fn new(cfg: &FleetConfig, filter: Option<VehicleFilter>) -> Result<Self, String> {
        cfg.validate()?;
        let filter = match (filter, &cfg.vehicles) {
            (Some(f), _) => f,
            (None, Some(s)) => VehicleFilter::parse(s)?,
            (None, None) => VehicleFilter::default(),
        };
        Ok(Self {
            lost_after_s: cfg.lost_after_s,
            drop_after_s: cfg.drop_after_s,
            filter,
            vehicles: BTreeMap::new(),
            not_vehicles: [false; 256],
            filtered: 0,
        })
    }

    /// Where message `m` goes (and note when its vehicle was last heard).
    pub fn route(&mut self, m: &TimedMessage) -> Route {
        let sys = m.header.system_id;
        let Ok(id) = u8::try_from(sys) else { return Route::Ignore };
        if id == 0 {
            return Route::Ignore;
        }
        if !self.filter.contains(sys) {
            self.filtered += 1;
            return Route::Ignore;
        }
        if let Some(v) = self.vehicles.get_mut(&id) {
            v.last_t = v.last_t.max(m.t_s);
            let back = std::mem::take(&mut v.lost);
            return Route::Vehicle { id, new: false, back };
        }
        let opens = match &m.msg {
            MavMessage::HEARTBEAT(h) if is_vehicle_heartbeat(h) => true,
            MavMessage::HEARTBEAT(_) => {
                self.not_vehicles[usize::from(id)] = true;
                false
            }
            msg => is_vehicle_telemetry(msg) && !self.not_vehicles[usize::from(id)],
        };
        if !opens || !m.t_s.is_finite() {
            return Route::Ignore;
        }
        self.vehicles.insert(id, Seen { last_t: m.t_s, lost: false });
        Route::Vehicle { id, new: true, back: false }
    }

    /// Time is now `now_s` (the source's clock): push the vehicles that went lost or must be
    /// dropped onto `out`. A dropped vehicle is forgotten.
    pub fn advance(&mut self, now_s: f64, out: &mut Vec<FleetEvent>) {
        let (lost_after, drop_after) = (self.lost_after_s, self.drop_after_s);
        self.vehicles.retain(|&id, v| {
            let silent_s = now_s - v.last_t;
            if silent_s >= drop_after {
                out.push(FleetEvent::Dropped { id, t_s: now_s, silent_s });
                return false;
            }
            if silent_s >= lost_after && !v.lost {
                v.lost = true;
                out.push(FleetEvent::Lost { id, t_s: now_s, silent_s });
            }
            true
        });
    }

    /// The vehicles present now, by system id.
    pub fn vehicles(&self) -> impl Iterator<Item = u8> + '_ {
        self.vehicles.keys().copied()
    }

    /// The system ids followed.
    pub fn filter(&self) -> &VehicleFilter {
        &self.filter
    }

    /// Messages ignored because their system id is outside the filter.
    pub fn filtered(&self) -> u64 {
        self.filtered
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dialect::{MavAutopilot, MavType, HEARTBEAT_DATA};

    fn msg(sys: u32, t_s: f64, msg: MavMessage) -> TimedMessage {
        TimedMessage { t_s, header: mavlink::MavHeader { system_id: sys, component_id: 1, sequence: 0 }, msg, arrived: std::time::Instant::now() }
    }
    fn hb(mavtype: MavType, autopilot: MavAutopilot) -> MavMessage {
        MavMessage::HEARTBEAT(HEARTBEAT_DATA { mavtype, autopilot, ..Default::default() })
    }

    #[test]
    fn filters_parse_ids_and_ranges_and_name_what_is_wrong() {
        let f = VehicleFilter::parse("3, 7,10-20").unwrap();
        assert!(f.contains(3) && f.contains(7) && f.contains(10) && f.contains(20));
        assert!(!f.contains(4) && !f.contains(21) && !f.contains(0) && !f.contains(300));
        assert!(VehicleFilter::parse("1-250").unwrap().contains(250));
        assert!(VehicleFilter::parse("0").unwrap_err().contains("\"0\""));
        assert!(VehicleFilter::parse("20-10").unwrap_err().contains("backwards"));
        assert!(VehicleFilter::parse("5,x").unwrap_err().contains("\"x\""));
        let bad = FleetConfig { vehicles: Some("1-300".into()), drop_after_s: 1.0, ..Default::default() };
        let e = bad.validate().unwrap_err();
        assert!(e.contains("fleet.vehicles") && e.contains("fleet.drop_after_s"), "{e}");
    }

    #[test]
    fn only_vehicles_open_chains_and_silence_makes_them_lost_then_dropped() {
        let mut d = Demux::new(&FleetConfig::default(), None).unwrap();
        let quad = || hb(MavType::MAV_TYPE_QUADROTOR, MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA);
        // A ground station and a companion are not vehicles; their telemetry-less chatter is ignored.
        assert_eq!(d.route(&msg(255, 0.0, hb(MavType::MAV_TYPE_GCS, MavAutopilot::MAV_AUTOPILOT_INVALID))), Route::Ignore);
        assert_eq!(d.route(&msg(255, 0.1, MavMessage::ATTITUDE(Default::default()))), Route::Ignore);
        assert_eq!(d.route(&msg(9, 0.0, hb(MavType::MAV_TYPE_ONBOARD_CONTROLLER, MavAutopilot::MAV_AUTOPILOT_GENERIC))), Route::Ignore);
        assert_eq!(d.route(&msg(1, 0.0, quad())), Route::Vehicle { id: 1, new: true, back: false });
        assert_eq!(d.route(&msg(1, 0.1, quad())), Route::Vehicle { id: 1, new: false, back: false });
        // Telemetry before a heartbeat opens a vehicle too (a log cut between heartbeats).
        assert_eq!(d.route(&msg(2, 0.2, MavMessage::ATTITUDE(Default::default()))), Route::Vehicle { id: 2, new: true, back: false });
        assert_eq!(d.vehicles().collect::<Vec<_>>(), vec![1, 2]);
        let mut ev = Vec::new();
        d.route(&msg(2, 9.0, quad()));
        d.advance(10.5, &mut ev);
        assert!(matches!(ev.as_slice(), [FleetEvent::Lost { id: 1, .. }]), "{ev:?}");
        d.advance(11.0, &mut ev);
        assert_eq!(ev.len(), 1, "lost is said once");
        assert_eq!(d.route(&msg(1, 11.0, quad())), Route::Vehicle { id: 1, new: false, back: true });
        ev.clear();
        d.advance(70.0, &mut ev);
        assert!(matches!(ev.as_slice(), [FleetEvent::Lost { id: 1, .. }, FleetEvent::Dropped { id: 2, .. }]), "{ev:?}");
        assert_eq!(d.vehicles().collect::<Vec<_>>(), vec![1]);
        assert_eq!(d.route(&msg(2, 72.0, quad())), Route::Vehicle { id: 2, new: true, back: false });
    }

    #[test]
    fn a_filter_ignores_and_counts_other_vehicles() {
        let mut d = Demux::new(&FleetConfig::default(), Some(VehicleFilter::parse("1-2").unwrap())).unwrap();
        let quad = hb(MavType::MAV_TYPE_QUADROTOR, MavAutopilot::MAV_AUTOPILOT_PX4);
        assert_eq!(d.route(&msg(3, 0.0, quad.clone())), Route::Ignore);
        assert_eq!(d.route(&msg(2, 0.0, quad)), Route::Vehicle { id: 2, new: true, back: false });
        assert_eq!(d.filtered(), 1);
    }
}
