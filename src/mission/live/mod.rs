//! The live mission forecast: a step of each vehicle's chain ([`MissionStep`], run by the
//! chain's telemetry stage on that vehicle's messages, after the demultiplexer) that takes
//! the vehicle's mission from the link (downloading it from that vehicle with
//! [`super::protocol`] on a live link, overhearing it in a replayed `.tlog`), flies it on
//! paper once per mission ([`super::trajectory`], [`super::forecast`]), and on each
//! MISSION_CURRENT and vehicle position re-forecasts what is left (the rest of the
//! mission, the return and the landing) in microseconds. Every vehicle of a fleet has its
//! own.
//!
//! ```text
//! demux ─TimedMessage→ telemetry_stage (+ MissionStep) ─Window→ … ─Estimate→ energy_stage
//!                            │ MissionUpdate (source time order)          ▲
//!                            └────────────────────────────────────────────┘
//!                              (mission_energy_wh, mission_margin_wh, alerts)
//! ```
//!
//! The energy stage takes each [`MissionStatus`] once its estimates reach the status's
//! source time, so a flat-out replay accounts it exactly when the flight did. The only
//! I/O: frames the step sends on the vehicle's link (requests, the ACK).
//!
//! Where the vehicle is on the plan: MISSION_CURRENT's `seq` (minus ArduPilot's home item)
//! is the item it flies to; the nearest trajectory sample (3-D, GLOBAL_POSITION_INT's
//! latitude, longitude and height above home) among that item's legs is where it is
//! ([`super::trajectory::Trajectory::locate`]). Home is ArduPilot's item 0, else
//! HOME_POSITION, else the first position heard.
//!
//! What is left is corrected by the flight's own showing, as `plan-eval` scores it
//! ([`super::forecast::live_scaled`]): the energy drawn since the vehicle's HEARTBEAT was
//! seen to turn armed (battery voltage × current, BATTERY_STATUS else SYS_STATUS, read as the
//! telemetry stage reads it: [`crate::source::messages::power`]) against the forecast of the
//! part of the plan flown, weight `[forecast.calibration] live_weight`.

use std::time::Duration;

use super::forecast::{forecast, MissionForecast};
use super::plan::{GeoPoint, Plan};
use super::protocol::{Event, MissionClient};
use super::trajectory::{enu_of, fly_as, Conditions, Trajectory, Wind};
use crate::features::VehicleClass;
use crate::model::PowerModel;
use crate::report::{MissionStatus, MissionUpdate};
use crate::source::TimedMessage;
use crate::MavMessage;

/// How often (source time) the re-forecast is published while nothing else changes, s.
const PUBLISH_EVERY_S: f64 = 1.0;
/// The mission is flown on paper again when the live wind estimate differs from the wind
/// it was flown in by more than this (vector difference, m/s) …
const REFLY_WIND_M_S: f64 = 1.5;
/// … at most this often (source time), s.
const REFLY_EVERY_S: f64 = 30.0;
/// A gap between two power readings longer than this adds nothing to the energy
/// so far (the link was lost), s.
const POWER_GAP_S: f64 = 5.0;
/// A power message of a lower rank ([`crate::source::messages::power`]: SYS_STATUS) counts once the
/// preferred one (BATTERY_STATUS) has been silent this long, s: under [`POWER_GAP_S`], so
/// the handover loses nothing.
const PREFERRED_STALE_S: f64 = 3.0;
/// How often the download's timeouts are checked (live link), wall clock.
pub const TICK: Duration = Duration::from_millis(250);

/// What the live forecast needs, gathered from the configuration by the pipeline.
pub struct LiveSetup {
    /// `[forecast]`: kinematics and calibration.
    pub forecast: super::ForecastConfig,
    /// The power models the forecast may run (the calibration's members among them for the
    /// fitted P50: those missing are left out with a warning; with none, the first one's
    /// power, uncorrected).
    pub models: Vec<Box<dyn PowerModel>>,
    /// Sample rate, Hz, and window length T of the models.
    pub rate_hz: f64,
    pub window: usize,
    /// Payload, g, and commanded speed, m/s (`[mission]`).
    pub payload_g: f64,
    pub speed_m_s: Option<f64>,
    /// Download over the link (a live link); else only overhear (a replay).
    pub active: bool,
    /// Ids dronewatt sends the protocol with (the MAVLink sink's; no system id: the
    /// vehicle's own, as its companion computer).
    pub system_id: Option<u8>,
    pub component_id: u8,
    /// The vehicles it may follow (`[fleet] vehicles` / `--vehicles`): another vehicle's
    /// heartbeat, position or MISSION_CURRENT is not looked at (a ground station's mission
    /// messages still are: a logged upload).
    pub follows: crate::source::messages::fleet::VehicleFilter,
    /// The vehicle profile's `[vehicle] class`, when it sets one: wins over the HEARTBEAT's
    /// type, which picks how the plan is flown otherwise (a plane and a VTOL as
    /// [`super::trajectory::plane`] flies them; the fixed-wing model must be among `models`).
    pub class: Option<VehicleClass>,
    /// The profile's `[fixed_wing_flight]`: how a plane or VTOL flies the plan.
    pub flight: crate::model::physics::fixed_wing::Flight,
}

/// A mission flown on paper.
struct Flown {
    plan: Plan,
    seq_offset: u16,
    items: u16,
    traj: Trajectory,
    forecast: MissionForecast,
    /// The wind it was flown in, and when (source time).
    wind: Wind,
    /// The class it was flown as.
    class: VehicleClass,
    flown_at: f64,
    /// The route for a map: every `route_stride`-th trajectory point, east/north.
    route: std::sync::Arc<Vec<[f32; 2]>>,
    route_stride: usize,
    /// `[forecast.calibration] live_weight` of the members it was forecast with (0 when
    /// none of them runs: the weight was fitted with them).
    live_weight: f64,
}

/// One vehicle's live forecast: the protocol client, the mission in hand, where the vehicle is.
pub struct LiveMission {
    setup: LiveSetup,
    client: MissionClient,
    flown: Option<Flown>,
    home: Option<GeoPoint>,
    /// GLOBAL_POSITION_INT: latitude, longitude (deg), height above home (m).
    position: Option<(f64, f64, f64)>,
    current_seq: Option<u16>,
    last_published: Option<(f64, u16)>,
    /// The autopilot's latest wind estimate (WIND, WIND_COV).
    wind: Wind,
    /// A mission heard before any home (PX4: no home item), flown once a home is known.
    waiting_for_home: Option<super::protocol::Mission>,
    /// The vehicle's class from its HEARTBEAT type, and whether a fixed-wing was seen to be
    /// a VTOL (EXTENDED_SYS_STATE `vtol_state`, an ArduPlane Q mode).
    heard_class: Option<VehicleClass>,
    vtol_seen: bool,
    /// Whether the vehicle's HEARTBEAT says armed (None: not heard yet).
    armed: Option<bool>,
    /// Energy drawn since the vehicle was seen to arm, Wh (battery voltage × current, each
    /// reading held to the next): the flight's own showing for the live correction
    /// ([`super::forecast::live_scaled`]). None until an arming is seen, and after a new
    /// mission arrives in flight (the flight so far was not that plan's).
    so_far_wh: Option<f64>,
    /// The last pack power while armed: source time, s, and W.
    last_power: Option<(f64, f64)>,
    /// The preferred power message heard lately: its rank ([`crate::source::messages::power`]) and
    /// when.
    power_rank: Option<(usize, f64)>,
}

impl LiveMission {
    /// The state for a run.
    pub fn new(setup: LiveSetup) -> Self {
        let client = MissionClient::new(setup.active, setup.system_id, setup.component_id);
        Self {
            setup,
            client,
            flown: None,
            home: None,
            position: None,
            current_seq: None,
            last_published: None,
            wind: Wind::default(),
            waiting_for_home: None,
            heard_class: None,
            vtol_seen: false,
            armed: None,
            so_far_wh: None,
            last_power: None,
            power_rank: None,
        }
    }

    /// Energy drawn since the vehicle was seen to arm, Wh, when known (battery voltage ×
    /// current, each reading held to the next): what the live correction sets against the
    /// forecast of the part flown.
    pub fn energy_so_far_wh(&self) -> Option<f64> {
        self.so_far_wh
    }

    /// Track arming from the vehicle's HEARTBEAT: a disarmed-to-armed change starts the
    /// energy so far at 0 (a monitor started in flight never learns it).
    fn learn_armed(&mut self, m: &MavMessage) {
        let MavMessage::HEARTBEAT(h) = m else {
            return;
        };
        if !crate::source::messages::fleet::is_vehicle_heartbeat(h) {
            return;
        }
        let armed = h
            .base_mode
            .contains(crate::dialect::MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
        if armed && self.armed == Some(false) {
            self.so_far_wh = Some(0.0);
            self.last_power = None;
        }
        if !armed {
            self.last_power = None;
        }
        self.armed = Some(armed);
    }

    /// Integrate the pack's power while armed (each reading held to the next; a gap over
    /// [`POWER_GAP_S`] counts nothing). Of BATTERY_STATUS and SYS_STATUS, the telemetry
    /// stage's choice ([`crate::source::messages::power`]): a SYS_STATUS reading counts only while no
    /// BATTERY_STATUS reading was heard in the last [`PREFERRED_STALE_S`].
    fn learn_power(&mut self, t_s: f64, rank: usize, power_w: f64) {
        if let Some((best, at)) = self.power_rank {
            if rank > best && t_s - at <= PREFERRED_STALE_S {
                return;
            }
        }
        self.power_rank = Some((rank, t_s));
        if self.armed != Some(true) || !power_w.is_finite() {
            return;
        }
        if let (Some(e), Some((t0, p0))) = (self.so_far_wh.as_mut(), self.last_power) {
            let dt = t_s - t0;
            if dt > 0.0 && dt <= POWER_GAP_S {
                *e += p0.max(0.0) * dt / 3600.0;
            }
        }
        self.last_power = Some((t_s, power_w));
    }

    /// The class the plan is flown as: the profile's, else the HEARTBEAT's (a fixed-wing
    /// seen to hover is a VTOL), else a multirotor.
    pub fn class(&self) -> VehicleClass {
        let heard = match self.heard_class {
            Some(VehicleClass::FixedWing) if self.vtol_seen => Some(VehicleClass::Vtol),
            c => c,
        };
        self.setup.class.or(heard).unwrap_or_default()
    }

    /// Take the class from a HEARTBEAT or EXTENDED_SYS_STATE; fly the mission in hand again
    /// when it changes how the plan is flown.
    fn learn_class(&mut self, m: &MavMessage, t_s: f64) -> Option<MissionStatus> {
        let before = self.class();
        match m {
            MavMessage::HEARTBEAT(h) if crate::source::messages::fleet::is_vehicle_heartbeat(h) => {
                let t = h.mavtype as u8;
                self.heard_class = Some(crate::features::class::class_of_mav_type(t));
                self.vtol_seen |= h.autopilot
                    == crate::dialect::MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA
                    && t == 1
                    && crate::features::class::arduplane_q_mode(h.custom_mode);
            }
            MavMessage::EXTENDED_SYS_STATE(e) => {
                self.vtol_seen |= crate::features::VtolState::from_mav(e.vtol_state as u8)
                    != crate::features::VtolState::Undefined;
            }
            _ => return None,
        }
        let now = self.class();
        let fl = self.flown.as_ref()?;
        if now == before || now == fl.class {
            return None;
        }
        tracing::info!(
            "mission forecast: the vehicle is a {now}; the mission is flown again as one"
        );
        let (plan, seq_offset, items) = (fl.plan.clone(), fl.seq_offset, fl.items);
        let source = plan.source.clone();
        self.flown = self.fly(&source, plan, seq_offset, items, t_s);
        self.status(t_s, true)
    }

    /// The protocol client (its counters).
    pub fn client(&self) -> &MissionClient {
        &self.client
    }

    /// One message at `now_s` (the client's clock: wall time live, the message's time in a
    /// replay) with its source time `t_s`. Frames to send go to `out`; an update to publish
    /// is returned (a status, or none when the mission in hand went away).
    // MISSION_ITEM is deprecated, and still what older ground stations log.
    #[allow(deprecated)]
    pub fn on_message(
        &mut self,
        now_s: f64,
        m: &TimedMessage,
        out: &mut Vec<MavMessage>,
    ) -> Option<MissionUpdate> {
        let mission_protocol = matches!(
            m.msg,
            MavMessage::MISSION_COUNT(_)
                | MavMessage::MISSION_ITEM_INT(_)
                | MavMessage::MISSION_ITEM(_)
                | MavMessage::MISSION_ACK(_)
        );
        if !mission_protocol && !self.setup.follows.contains(m.header.system_id) {
            return None;
        }
        let had = self.flown.is_some();
        match self.step(now_s, m, out) {
            Some(s) => Some(MissionUpdate {
                t_s: s.t_s,
                status: Some(s),
            }),
            None if had && self.flown.is_none() => Some(MissionUpdate {
                t_s: m.t_s,
                status: None,
            }),
            None => None,
        }
    }

    fn step(
        &mut self,
        now_s: f64,
        m: &TimedMessage,
        out: &mut Vec<MavMessage>,
    ) -> Option<MissionStatus> {
        if let Some(ev) = self.client.on_message(now_s, &m.header, &m.msg, out) {
            self.on_event(ev, m.t_s);
            return self.status(m.t_s, true);
        }
        match &m.msg {
            MavMessage::HEARTBEAT(_) | MavMessage::EXTENDED_SYS_STATE(_) => {
                self.learn_armed(&m.msg);
                self.learn_class(&m.msg, m.t_s)
            }
            MavMessage::SYS_STATUS(_) | MavMessage::BATTERY_STATUS(_) => {
                if let Some(r) = crate::source::messages::power::power_reading(&m.msg) {
                    self.learn_power(m.t_s, r.rank, r.power_w());
                }
                None
            }
            MavMessage::MISSION_CURRENT(c) => {
                let changed = self.current_seq != Some(c.seq);
                self.current_seq = Some(c.seq);
                self.status(m.t_s, changed)
            }
            MavMessage::GLOBAL_POSITION_INT(p) if p.lat != 0 || p.lon != 0 => {
                let (lat, lon) = (f64::from(p.lat) * 1e-7, f64::from(p.lon) * 1e-7);
                if self.home.is_none() {
                    self.home = Some(GeoPoint {
                        lat_deg: lat,
                        lon_deg: lon,
                        alt_m: f64::from(p.alt) * 1e-3 - f64::from(p.relative_alt) * 1e-3,
                    });
                }
                self.position = Some((lat, lon, f64::from(p.relative_alt) * 1e-3));
                if let Some(waiting) = self.waiting_for_home.take() {
                    self.on_event(Event::Mission(waiting), m.t_s);
                    return self.status(m.t_s, true);
                }
                self.status(m.t_s, false)
            }
            // ArduPilot: the bearing it blows from; PX4: the NED vector it blows toward.
            MavMessage::WIND(w) if w.speed.is_finite() && w.direction.is_finite() => {
                self.wind = Wind {
                    speed_m_s: f64::from(w.speed).max(0.0),
                    from_deg: f64::from(w.direction).rem_euclid(360.0),
                };
                self.refly_in_wind(m.t_s)
            }
            MavMessage::WIND_COV(w) if w.wind_x.is_finite() && w.wind_y.is_finite() => {
                let (n, e) = (f64::from(w.wind_x), f64::from(w.wind_y));
                self.wind = Wind {
                    speed_m_s: n.hypot(e),
                    from_deg: (e.atan2(n).to_degrees() + 180.0).rem_euclid(360.0),
                };
                self.refly_in_wind(m.t_s)
            }
            MavMessage::HOME_POSITION(h) if h.latitude != 0 || h.longitude != 0 => {
                self.home = Some(GeoPoint {
                    lat_deg: f64::from(h.latitude) * 1e-7,
                    lon_deg: f64::from(h.longitude) * 1e-7,
                    alt_m: f64::from(h.altitude) * 1e-3,
                });
                let waiting = self.waiting_for_home.take()?;
                self.on_event(Event::Mission(waiting), m.t_s);
                self.status(m.t_s, true)
            }
            _ => None,
        }
    }

    /// Timeouts of a download under way.
    pub fn tick(&mut self, now_s: f64, out: &mut Vec<MavMessage>) {
        if let Some(ev) = self.client.tick(now_s, out) {
            let t = self.last_published.map_or(0.0, |p| p.0);
            self.on_event(ev, t);
        }
    }

    fn on_event(&mut self, ev: Event, t_s: f64) {
        let m = match ev {
            Event::Failed(why) => {
                tracing::warn!("mission download failed ({why}); trying again later");
                return;
            }
            Event::Mission(m) => m,
        };
        let source = format!("mission ({:?}, id {})", m.origin, m.mission_id).to_lowercase();
        if m.items.is_empty() {
            tracing::info!("{source}: the vehicle holds no mission");
            self.flown = None;
            return;
        }
        if !m.home_is_item0 && self.home.is_none() {
            tracing::debug!(
                "{source}: no home yet; flown once HOME_POSITION or a position is heard"
            );
            self.waiting_for_home = Some(m);
            self.flown = None;
            return;
        }
        let (plan, seq_offset) = match Plan::from_mission(&source, &m, self.home) {
            Ok(p) => p,
            Err(e) => {
                tracing::warn!("{e}; no mission forecast");
                self.flown = None;
                return;
            }
        };
        for i in plan.not_modelled() {
            tracing::info!(
                "{source}: item {} ({}): MAV_CMD {} not modelled (flown through: {})",
                i.index,
                i.origin,
                i.command,
                i.command < 100
            );
        }
        let items = u16::try_from(m.items.len()).unwrap_or(u16::MAX);
        if self.armed == Some(true) {
            // a mission arriving in flight: the energy so far was not drawn on its plan
            self.so_far_wh = None;
        }
        self.flown = self.fly(&source, plan, seq_offset, items, t_s);
        self.last_published = None;
    }

    /// The re-forecast at source time `t_s`; None when there is no mission or it was
    /// published less than [`PUBLISH_EVERY_S`] ago (unless `now`).
    fn status(&mut self, t_s: f64, now: bool) -> Option<MissionStatus> {
        let fl = self.flown.as_ref()?;
        let seq = self.current_seq.unwrap_or(fl.seq_offset);
        if !now
            && self
                .last_published
                .is_some_and(|(t, s)| s == seq && t_s - t < PUBLISH_EVERY_S && t_s >= t)
        {
            return None;
        }
        let k = locate(fl, seq, self.position);
        self.last_published = Some((t_s, seq));
        // the live correction plan-eval measures: the flight's energy so far against the
        // forecast of the part flown
        let r = fl
            .forecast
            .remaining_from(k, self.so_far_wh, fl.live_weight);
        let n = fl.traj.samples.len().max(1);
        Some(MissionStatus {
            t_s,
            current_seq: seq,
            items: fl.items,
            time_left_s: r.time_s,
            energy_p50_wh: r.energy_p50_wh,
            energy_p90_wh: r.energy_p90_wh,
            progress_pct: 100.0 * (k + 1) as f64 / n as f64,
            route_en_m: fl.route.clone(),
            route_at: k / fl.route_stride,
        })
    }
}

mod fly;
use fly::locate;
mod step;
pub use step::{MissionStep, STATUS_DEPTH};

#[cfg(test)]
mod tests;
