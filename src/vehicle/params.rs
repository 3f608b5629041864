//! Reading the vehicle: its identity (HEARTBEAT, AUTOPILOT_VERSION) and the parameters that
//! size its battery, over MAVLink's parameter protocol.
//!
//! [`ParamReader`] is a pure state machine: messages and their times in, requests out. It
//! learns the vehicle from the first autopilot HEARTBEAT (its system and component id, its
//! type and autopilot), then — when it may speak ([`ParamReader::live`]) — asks for each
//! parameter of that autopilot's list ([`ARDUPILOT_PARAMS`], [`PX4_PARAMS`]) with a
//! PARAM_REQUEST_READ and for AUTOPILOT_VERSION with MAV_CMD_REQUEST_MESSAGE. An unanswered
//! request is sent again after [`RESEND_S`], at most [`MAX_TRIES`] times in all; then the
//! parameter is *absent* (the vehicle does not have it, or the link drops everything we
//! send). Nothing ever waits on it: the pipeline carries on with the config and the
//! defaults, and takes the vehicle's values when they come.
//!
//! Replaying a `.tlog` ([`ParamReader::passive`]) it never asks: it takes the PARAM_VALUE
//! messages the ground station logged when it fetched the parameters.
//!
//! [`Driver`] is the thin part that talks: it frames the requests as dronewatt's MAVLink
//! component (the `[sinks.mavlink]` ids, default system 1, component 191) and queues them on
//! the live link ([`crate::report::status::LinkHandle`]).
//!
//! ## Decoding PARAM_VALUE
//!
//! `param_value` is a float whatever the parameter's type. ArduPilot *casts* integers
//! (`BATT_CAPACITY` 3300 arrives as 3300.0); PX4 *packs* them bytewise into the float's bits
//! (`BAT1_N_CELLS` 4 arrives as the float whose bits are 0x00000004). [`decode`] reads
//! integer types by the autopilot: bits for PX4, the float's value for everyone else.

use std::collections::BTreeMap;

use crate::dialect::{self, MavAutopilot, MavParamType, MavType};
use crate::source::TimedMessage;
use crate::MavMessage;

/// ArduPilot parameters that matter to energy: capacity (mAh), low/critical pack voltage
/// (V), low/critical remaining (mAh), hover throttle (0–1), frame class.
pub const ARDUPILOT_PARAMS: [&str; 9] = [
    "BATT_CAPACITY",
    "BATT_LOW_VOLT",
    "BATT_CRT_VOLT",
    "BATT_LOW_MAH",
    "BATT_CRT_MAH",
    "MOT_THST_HOVER",
    "FRAME_CLASS",
    // The pack's cells: usually cells × 4.2 (or 4.35) and cells × 3.3 when set (0: off).
    "MOT_BAT_VOLT_MAX",
    "MOT_BAT_VOLT_MIN",
];
/// PX4 parameters that matter to energy: capacity (mAh), cells, full and empty cell
/// voltage (V).
pub const PX4_PARAMS: [&str; 4] = [
    "BAT1_CAPACITY",
    "BAT1_N_CELLS",
    "BAT1_V_CHARGED",
    "BAT1_V_EMPTY",
];
/// Seconds before an unanswered request is sent again.
pub const RESEND_S: f64 = 1.5;
/// Requests sent for one item before it counts as absent.
pub const MAX_TRIES: u32 = 3;
/// The MAVLink message id of AUTOPILOT_VERSION (asked for with MAV_CMD_REQUEST_MESSAGE).
const AUTOPILOT_VERSION_ID: f32 = 148.0;

/// Which autopilot firmware: it decides how integer parameters are encoded.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize, strum::Display,
)]
#[serde(rename_all = "lowercase")]
#[strum(serialize_all = "lowercase")]
pub enum Autopilot {
    ArduPilot,
    Px4,
    /// Anything else that sends an autopilot heartbeat (parameters decoded as cast).
    Other,
}

impl Autopilot {
    fn from_mav(a: MavAutopilot) -> Option<Self> {
        match a {
            MavAutopilot::MAV_AUTOPILOT_INVALID => None,
            MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA => Some(Autopilot::ArduPilot),
            MavAutopilot::MAV_AUTOPILOT_PX4 => Some(Autopilot::Px4),
            _ => Some(Autopilot::Other),
        }
    }

    /// The parameters worth asking this autopilot for.
    pub fn wanted(self) -> &'static [&'static str] {
        match self {
            Autopilot::ArduPilot => &ARDUPILOT_PARAMS,
            Autopilot::Px4 => &PX4_PARAMS,
            Autopilot::Other => &[],
        }
    }
}

/// Who the vehicle is.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Identity {
    /// MAVLink system id of the autopilot.
    pub system_id: u8,
    /// MAVLink component id of the autopilot (normally 1).
    pub component_id: u8,
    pub autopilot: Autopilot,
    /// HEARTBEAT `type` (`MAV_TYPE_QUADROTOR` …).
    pub vehicle_type: String,
    /// AUTOPILOT_VERSION's board uid, where the vehicle sends one (non-zero).
    pub uid: Option<u64>,
    /// The network it was heard on (`crate::report::VehicleId::network`; 0: the only one):
    /// with no uid, the vehicle store tells two fleets' system id 1 apart by it.
    #[serde(skip_serializing_if = "is_zero", default)]
    pub network: u8,
}

fn is_zero(n: &u8) -> bool {
    *n == 0
}

/// One parameter's value as the vehicle sent it, before decoding.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RawParam {
    pub value: f32,
    pub param_type: MavParamType,
}

/// Decode a PARAM_VALUE's float for `autopilot` (module docs): PX4's integer types are the
/// float's bits, everyone else's are the float's value.
pub fn decode(autopilot: Autopilot, raw: RawParam) -> f64 {
    use MavParamType as T;
    let bits = raw.value.to_bits();
    let int = matches!(
        raw.param_type,
        T::MAV_PARAM_TYPE_UINT8
            | T::MAV_PARAM_TYPE_INT8
            | T::MAV_PARAM_TYPE_UINT16
            | T::MAV_PARAM_TYPE_INT16
            | T::MAV_PARAM_TYPE_UINT32
            | T::MAV_PARAM_TYPE_INT32
    );
    if autopilot != Autopilot::Px4 || !int {
        return f64::from(raw.value);
    }
    match raw.param_type {
        T::MAV_PARAM_TYPE_UINT8 => f64::from(bits as u8),
        T::MAV_PARAM_TYPE_INT8 => f64::from(bits as u8 as i8),
        T::MAV_PARAM_TYPE_UINT16 => f64::from(bits as u16),
        T::MAV_PARAM_TYPE_INT16 => f64::from(bits as u16 as i16),
        T::MAV_PARAM_TYPE_UINT32 => f64::from(bits),
        _ => f64::from(bits as i32),
    }
}

/// The vehicle's parameters that were read, decoded, by name.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VehicleParams {
    /// The vehicle, once its heartbeat was heard.
    pub identity: Option<Identity>,
    /// Decoded values by parameter name.
    pub values: BTreeMap<String, f64>,
    /// Parameters asked for [`MAX_TRIES`] times and never answered.
    pub absent: Vec<String>,
    /// Cells the battery monitor reports one by one (BATTERY_STATUS `voltages`: two or more
    /// entries, each a cell's voltage; 65535 is "no cell"), when it does.
    pub battery_cells: Option<u32>,
    /// The pack, where the vehicle identifies it ([`crate::vehicle::pack_identity`]).
    pub pack_id: Option<String>,
    /// The chemistry BATTERY_STATUS / BATTERY_INFO `type` names (LiPo, LiFe, Li-ion).
    pub battery_chemistry: Option<crate::battery::Chemistry>,
    /// What a smart battery says of itself in BATTERY_INFO: its full-charge (else design)
    /// capacity, Ah, and its cells in series, where it gives them.
    pub battery_info: Option<(Option<f64>, Option<u32>)>,
}

impl VehicleParams {
    /// A parameter's decoded value.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.values.get(name).copied()
    }
    /// These parameters over `earlier` ones: what these do not say (a value, the
    /// identity, the pack) is taken from `earlier`. A fleet worker's replay after a
    /// checkpoint hears only the stream's last seconds, not the parameters fetched at the
    /// start.
    pub fn over(mut self, earlier: &VehicleParams) -> Self {
        for (k, v) in &earlier.values {
            self.values.entry(k.clone()).or_insert(*v);
        }
        self.absent.retain(|a| !self.values.contains_key(a));
        self.identity = self.identity.or_else(|| earlier.identity.clone());
        self.battery_cells = self.battery_cells.or(earlier.battery_cells);
        self.pack_id = self.pack_id.or_else(|| earlier.pack_id.clone());
        self.battery_chemistry = self.battery_chemistry.or(earlier.battery_chemistry);
        self.battery_info = self.battery_info.or(earlier.battery_info);
        self
    }

    /// Parameters from (name, value) pairs (tests, logs).
    pub fn from_pairs(pairs: &[(&str, f64)]) -> Self {
        Self {
            values: pairs.iter().map(|(n, v)| (n.to_string(), *v)).collect(),
            ..Default::default()
        }
    }
}

/// Where one request stands.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Ask {
    /// Sent `tries` times, last at `at_s`.
    Sent { tries: u32, at_s: f64 },
    /// Answered.
    Got,
    /// Asked [`MAX_TRIES`] times, no answer.
    Absent,
}

/// The parameter protocol as a state machine (module docs).
#[derive(Debug)]
pub struct ParamReader {
    /// May send requests (a live link) or only listen (a replay).
    live: bool,
    identity: Option<Identity>,
    raw: BTreeMap<String, RawParam>,
    /// Requests by parameter name; `AUTOPILOT_VERSION` for the version request.
    asks: BTreeMap<&'static str, Ask>,
    changed: bool,
    /// Cells BATTERY_STATUS reports one by one ([`cells_reported`]).
    cells: Option<u32>,
    pack_id: Option<String>,
    chemistry: Option<crate::battery::Chemistry>,
    info: Option<(Option<f64>, Option<u32>)>,
}

/// The cells a BATTERY_STATUS reports one by one: its entries that are not "no cell"
/// (65535 in `voltages`, 0 in `voltages_ext`), when there are two or more and each is a
/// cell's voltage (2.5-4.5 V). A monitor that knows only the pack puts it all in the first
/// entry: that is no cell count.
pub fn cells_reported(b: &crate::dialect::BATTERY_STATUS_DATA) -> Option<u32> {
    let cells: Vec<u16> = b
        .voltages
        .iter()
        .copied()
        .filter(|&c| c != u16::MAX)
        .chain(b.voltages_ext.iter().copied().filter(|&c| c != 0))
        .collect();
    (cells.len() >= 2 && cells.iter().all(|c| (2500..=4500).contains(c)))
        .then_some(cells.len() as u32)
}

/// The key the AUTOPILOT_VERSION request is kept under in the request table.
const VERSION_KEY: &str = "AUTOPILOT_VERSION";

impl ParamReader {
    /// A reader that asks the vehicle (a live link).
    pub fn live() -> Self {
        Self {
            live: true,
            identity: None,
            raw: BTreeMap::new(),
            asks: BTreeMap::new(),
            changed: false,
            cells: None,
            pack_id: None,
            chemistry: None,
            info: None,
        }
    }
    /// A reader that only listens (a replayed log).
    pub fn passive() -> Self {
        Self {
            live: false,
            ..Self::live()
        }
    }

    /// Take in one message: the first autopilot HEARTBEAT fixes the vehicle; its
    /// AUTOPILOT_VERSION and PARAM_VALUEs are kept.
    pub fn on_message(&mut self, m: &TimedMessage) {
        let (sys, comp) = (m.header.system_id as u8, m.header.component_id);
        match &m.msg {
            MavMessage::HEARTBEAT(h) if self.identity.is_none() => {
                let Some(autopilot) = Autopilot::from_mav(h.autopilot) else {
                    return;
                };
                if h.mavtype == MavType::MAV_TYPE_GCS {
                    return;
                }
                self.identity = Some(Identity {
                    system_id: sys,
                    component_id: comp,
                    autopilot,
                    vehicle_type: format!("{:?}", h.mavtype),
                    uid: None,
                    network: m.network,
                });
                self.changed = true;
            }
            MavMessage::AUTOPILOT_VERSION(v) if self.is_vehicle(sys, comp) => {
                if let Some(id) = &mut self.identity {
                    id.uid = (v.uid != 0).then_some(v.uid);
                }
                self.asks.insert(VERSION_KEY, Ask::Got);
                self.changed = true;
            }
            MavMessage::BATTERY_STATUS(b)
                if b.id == 0 && self.identity.as_ref().is_none_or(|id| id.system_id == sys) =>
            {
                let cells = cells_reported(b);
                if cells.is_some() && cells != self.cells {
                    self.cells = cells;
                    self.changed = true;
                }
                self.take_chemistry(b.mavtype as u8);
            }
            MavMessage::BATTERY_INFO(b)
                if b.id == 0 && self.identity.as_ref().is_none_or(|id| id.system_id == sys) =>
            {
                let id = crate::vehicle::pack_identity(b);
                self.changed |= id.is_some() && id != self.pack_id;
                self.pack_id = id.or(self.pack_id.take());
                self.take_chemistry(b.mavtype as u8);
                // NaN or 0: not given; a capacity over 1000 Ah is no drone's pack.
                let ah = [b.full_charge_capacity, b.design_capacity]
                    .into_iter()
                    .map(f64::from)
                    .find(|a| a.is_finite() && *a > 0.05 && *a < 1000.0);
                let cells = Some(u32::from(b.cells_in_series)).filter(|n| (1..=24).contains(n));
                let info = (ah.is_some() || cells.is_some()).then_some((ah, cells));
                if info.is_some() && info != self.info {
                    self.info = info;
                    self.changed = true;
                }
            }
            MavMessage::PARAM_VALUE(p) => {
                // Before the heartbeat, take an autopilot's (component 1) values; after it,
                // only the vehicle's.
                let ours = match &self.identity {
                    Some(id) => id.system_id == sys && id.component_id == comp,
                    None => comp == 1,
                };
                let Ok(name) = p.param_id.to_str() else {
                    return;
                };
                let name = name.trim_end_matches('\0');
                if !ours
                    || !ARDUPILOT_PARAMS
                        .iter()
                        .chain(&PX4_PARAMS)
                        .any(|n| *n == name)
                {
                    return;
                }
                let raw = RawParam {
                    value: p.param_value,
                    param_type: p.param_type,
                };
                if self.raw.get(name) != Some(&raw) {
                    self.raw.insert(name.to_string(), raw);
                    self.changed = true;
                }
                if let Some(key) = ARDUPILOT_PARAMS
                    .iter()
                    .chain(&PX4_PARAMS)
                    .find(|n| **n == name)
                {
                    self.asks.insert(key, Ask::Got);
                }
            }
            _ => {}
        }
    }

    /// The chemistry a battery message's MAV_BATTERY_TYPE names, when it names one.
    fn take_chemistry(&mut self, mav_type: u8) {
        let c = crate::battery::Chemistry::from_mav_type(mav_type);
        if c.is_some() && c != self.chemistry {
            self.chemistry = c;
            self.changed = true;
        }
    }

    fn is_vehicle(&self, sys: u8, comp: u8) -> bool {
        self.identity
            .as_ref()
            .is_some_and(|id| id.system_id == sys && id.component_id == comp)
    }

    /// The requests due at `t_s` (none for a passive reader or before the heartbeat):
    /// first asks, and resends of those unanswered for [`RESEND_S`]. Items asked
    /// [`MAX_TRIES`] times become absent; their names are returned in `gave_up`.
    pub fn poll(&mut self, t_s: f64, gave_up: &mut Vec<&'static str>) -> Vec<MavMessage> {
        let mut out = Vec::new();
        let Some(id) = self.identity.clone().filter(|_| self.live) else {
            return out;
        };
        let items = id.autopilot.wanted().iter().copied().chain([VERSION_KEY]);
        for name in items {
            let due = match self.asks.get(name) {
                None => Some(1),
                Some(Ask::Sent { tries, at_s }) if t_s - at_s >= RESEND_S => {
                    if *tries >= MAX_TRIES {
                        self.asks.insert(name, Ask::Absent);
                        gave_up.push(name);
                        self.changed = true;
                        None
                    } else {
                        Some(tries + 1)
                    }
                }
                _ => None,
            };
            if let Some(tries) = due {
                self.asks.insert(name, Ask::Sent { tries, at_s: t_s });
                out.push(request(&id, name));
            }
        }
        out
    }

    /// Whether it asks the vehicle (a live link), rather than only listening.
    pub fn asks(&self) -> bool {
        self.live
    }

    /// Whether every request has been answered or given up (always true when passive).
    pub fn settled(&self) -> bool {
        !self.live
            || self.identity.as_ref().is_some_and(|_| {
                self.asks.values().all(|a| !matches!(a, Ask::Sent { .. })) && !self.asks.is_empty()
            })
    }

    /// True once after anything new was learned (a heartbeat, a value, a give-up).
    pub fn take_changed(&mut self) -> bool {
        std::mem::take(&mut self.changed)
    }

    /// What has been read so far, decoded by the vehicle's autopilot (ArduPilot's cast
    /// before any heartbeat).
    pub fn params(&self) -> VehicleParams {
        let autopilot = self
            .identity
            .as_ref()
            .map_or(Autopilot::ArduPilot, |id| id.autopilot);
        VehicleParams {
            identity: self.identity.clone(),
            values: self
                .raw
                .iter()
                .map(|(n, r)| (n.clone(), decode(autopilot, *r)))
                .collect(),
            absent: self
                .asks
                .iter()
                .filter(|(_, a)| **a == Ask::Absent)
                .map(|(n, _)| n.to_string())
                .collect(),
            battery_cells: self.cells,
            pack_id: self.pack_id.clone(),
            battery_chemistry: self.chemistry,
            battery_info: self.info,
        }
    }
}

/// The request for one item of the table: PARAM_REQUEST_READ by name, or
/// MAV_CMD_REQUEST_MESSAGE(AUTOPILOT_VERSION).
fn request(id: &Identity, name: &str) -> MavMessage {
    if name == VERSION_KEY {
        return MavMessage::COMMAND_LONG(dialect::COMMAND_LONG_DATA {
            param1: AUTOPILOT_VERSION_ID,
            param2: 0.0,
            param3: 0.0,
            param4: 0.0,
            param5: 0.0,
            param6: 0.0,
            param7: 0.0,
            command: dialect::MavCmd::MAV_CMD_REQUEST_MESSAGE,
            target_system: id.system_id,
            target_component: id.component_id,
            confirmation: 0,
        });
    }
    MavMessage::PARAM_REQUEST_READ(dialect::PARAM_REQUEST_READ_DATA {
        param_index: -1,
        target_system: id.system_id,
        target_component: id.component_id,
        param_id: name.into(),
    })
}

/// The thin part that talks: a [`ParamReader`] whose requests go out on the live link as
/// dronewatt's MAVLink component, and whose news is published for the energy stage.
pub struct Driver {
    reader: ParamReader,
    link: crate::report::status::LinkHandle,
    system_id: u8,
    component_id: u8,
    /// Requests the link could not take (none attached, or full).
    pub unsent: u64,
    /// Asks for the streams the chain needs ([`super::streams`]), on a live link.
    streams: Option<super::streams::StreamAsker>,
}

impl Driver {
    /// A driver for `reader`, sending on `link` as (`system_id`, `component_id`).
    pub fn new(
        reader: ParamReader,
        link: crate::report::status::LinkHandle,
        system_id: u8,
        component_id: u8,
    ) -> Self {
        Self {
            reader,
            link,
            system_id,
            component_id,
            unsent: 0,
            streams: None,
        }
    }

    /// Also ask the vehicle for the streams the chain needs (`on`: a live link that may
    /// speak, [`super::streams`]).
    pub fn with_streams(mut self, on: bool) -> Self {
        self.streams = on.then(super::streams::StreamAsker::new);
        self
    }

    /// Take in one message, send what is due; `Some(params)` when something new was
    /// learned. Logs each parameter given up on (once).
    pub fn on_message(&mut self, m: &TimedMessage) -> Option<VehicleParams> {
        self.reader.on_message(m);
        let mut gave_up = Vec::new();
        let mut reqs = self.reader.poll(m.t_s, &mut gave_up);
        if let Some(s) = &mut self.streams {
            reqs.extend(s.on_message(m, self.reader.identity.as_ref()));
        }
        for req in reqs {
            // Numbered by the link's one writer of this identity (the sink and the
            // mission client send as it too).
            if !self.link.send_as(self.system_id, self.component_id, &req) {
                self.unsent += 1;
            }
        }
        if !gave_up.is_empty() {
            tracing::warn!(
                "vehicle did not answer for {} after {MAX_TRIES} requests: using the config and defaults for them",
                gave_up.join(", ")
            );
        }
        self.reader.take_changed().then(|| self.reader.params())
    }

    /// The reader's state.
    pub fn reader(&self) -> &ParamReader {
        &self.reader
    }
}

#[cfg(test)]
#[path = "params_tests.rs"]
mod tests;
