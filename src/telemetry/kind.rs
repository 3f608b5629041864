//! The vehicle's kind as its messages say it ([`crate::features::VehicleKind`]), and the
//! air data a fixed-wing model reads ([`crate::features::AirData`]).
//!
//! - **class**: the autopilot HEARTBEAT's `type` (MAV_TYPE), unless the vehicle profile's
//!   `[vehicle] class` says otherwise. A plane (`MAV_TYPE_FIXED_WING`) that reports a VTOL
//!   state (EXTENDED_SYS_STATE `vtol_state` other than undefined) or flies an ArduPlane Q
//!   mode is a VTOL from then on: ArduPlane quadplanes may say `FIXED_WING`.
//! - **VTOL state**: EXTENDED_SYS_STATE `vtol_state` while it is heard (within the stale
//!   time); else, for ArduPilot, a Q mode is MC and another mode FW.
//! - Each change of class or VTOL state is logged (`info`), and the first time the class
//!   is one dronewatt has no model for, one warning says so: "no power model for a
//!   SUBMARINE: estimates from measured power only".
//! - **air data**: VFR_HUD `airspeed`, measured where SYS_STATUS says a differential
//!   pressure sensor is present, enabled and healthy; the horizontal ground velocity minus
//!   the WIND estimate; SCALED_PRESSURE `temperature` within −60…60 °C. Each is `None`
//!   once older than the stale time.

use crate::features::class::{arduplane_q_mode, class_of_mav_type, VehicleKind, VtolState};
use crate::features::{AirData, VehicleClass};
use crate::MavMessage;

/// SYS_STATUS's `MAV_SYS_STATUS_SENSOR_DIFFERENTIAL_PRESSURE` bit.
const DIFF_PRESSURE: u32 = 0x20;
/// MAV_AUTOPILOT_ARDUPILOTMEGA.
const ARDUPILOT: u8 = 3;

/// Follows the vehicle's kind and air data from its messages.
#[derive(Debug, Default)]
pub struct KindTracker {
    kind: VehicleKind,
    /// `[vehicle] class` of the profile: wins over the HEARTBEAT.
    forced: Option<VehicleClass>,
    /// A fixed-wing seen to be a VTOL (EXTENDED_SYS_STATE, a Q mode).
    vtol_seen: bool,
    /// The latest EXTENDED_SYS_STATE vtol_state and its time, µs.
    ess: Option<(VtolState, i64)>,
    /// The latest HEARTBEAT says an ArduPilot Q mode.
    q_mode: Option<bool>,
    airspeed: Option<(f32, i64)>,
    sensor: bool,
    wind_air: Option<(f32, i64)>,
    /// VFR_HUD throttle, %, and when.
    throttle: Option<(f32, i64)>,
    temperature: Option<(f32, i64)>,
    /// The class whose "no model" line was printed.
    said_unmodelled: bool,
    /// Changes of class or VTOL state after the first HEARTBEAT.
    switches: u64,
}

impl KindTracker {
    /// A tracker; `forced` is the profile's `[vehicle] class`, when it sets one.
    pub fn new(forced: Option<VehicleClass>) -> Self {
        let mut t = Self {
            forced,
            ..Self::default()
        };
        if let Some(c) = forced {
            t.kind.class = c;
            t.kind.from_config = true;
            tracing::info!("vehicle class: {c} (from the vehicle profile's [vehicle] class)");
            t.say_unmodelled();
        }
        t
    }

    /// The kind now.
    pub fn kind(&self) -> VehicleKind {
        self.kind
    }

    /// Changes of class or VTOL state so far.
    pub fn switches(&self) -> u64 {
        self.switches
    }

    /// The air data at `t_us`: each value while younger than `stale_us`.
    pub fn air(&self, t_us: i64, stale_us: i64) -> AirData {
        let fresh = |v: Option<(f32, i64)>| v.filter(|(_, t)| t_us - t <= stale_us).map(|x| x.0);
        AirData {
            airspeed_m_s: fresh(self.airspeed),
            airspeed_sensor: self.sensor,
            wind_airspeed_m_s: fresh(self.wind_air),
            temperature_c: fresh(self.temperature),
            throttle_pct: fresh(self.throttle),
        }
    }

    /// Take what `msg` says (a message of the vehicle's own system; HEARTBEATs only from
    /// its autopilot). `t_us` its time; `stale_us` how long an EXTENDED_SYS_STATE holds.
    pub fn ingest(&mut self, t_us: i64, stale_us: i64, msg: &MavMessage) {
        match msg {
            MavMessage::HEARTBEAT(h) if crate::source::messages::fleet::is_vehicle_heartbeat(h) => {
                let mav_type = h.mavtype as u8;
                let q = h.autopilot as u8 == ARDUPILOT
                    && mav_type == 1
                    && arduplane_q_mode(h.custom_mode);
                self.vtol_seen |= q;
                self.q_mode = (h.autopilot as u8 == ARDUPILOT).then_some(q);
                let first = self.kind.mav_type.is_none();
                self.kind.mav_type = Some(mav_type);
                self.update(t_us, stale_us, first);
            }
            MavMessage::EXTENDED_SYS_STATE(e) => {
                let s = VtolState::from_mav(e.vtol_state as u8);
                if s != VtolState::Undefined {
                    self.vtol_seen = true;
                    self.ess = Some((s, t_us));
                    self.update(t_us, stale_us, false);
                }
            }
            MavMessage::VFR_HUD(h) => {
                if h.airspeed.is_finite() {
                    self.airspeed = Some((h.airspeed, t_us));
                }
                if h.throttle <= 100 {
                    self.throttle = Some((f32::from(h.throttle), t_us));
                }
            }
            MavMessage::SYS_STATUS(s) => {
                let bit = |f: u32| f & DIFF_PRESSURE != 0;
                self.sensor = bit(s.onboard_control_sensors_present.bits())
                    && bit(s.onboard_control_sensors_enabled.bits())
                    && bit(s.onboard_control_sensors_health.bits());
            }
            MavMessage::SCALED_PRESSURE(p)
                if p.temperature != 0 && (-6000..=6000).contains(&p.temperature) =>
            {
                self.temperature = Some((f32::from(p.temperature) * 0.01, t_us));
            }
            _ => {}
        }
    }

    /// The WIND message's airspeed: ground velocity (NED, m/s) minus the wind (NE, m/s).
    pub fn wind_airspeed(&mut self, t_us: i64, ground_ned: [f64; 3], wind_ne: [f64; 2]) {
        let a = (ground_ned[0] - wind_ne[0]).hypot(ground_ned[1] - wind_ne[1]);
        if a.is_finite() {
            self.wind_air = Some((a as f32, t_us));
        }
    }

    /// Settle class and VTOL state; `first`: on the vehicle's first HEARTBEAT.
    fn update(&mut self, t_us: i64, stale_us: i64, first: bool) {
        let before = self.kind;
        let heard = self.kind.mav_type.map(class_of_mav_type);
        let class = match (self.forced, heard) {
            (Some(c), _) => c,
            (None, Some(VehicleClass::FixedWing)) if self.vtol_seen => VehicleClass::Vtol,
            (None, Some(c)) => c,
            (None, None) => self.kind.class,
        };
        let ess = self
            .ess
            .filter(|(_, t)| t_us - t <= stale_us)
            .map(|(s, _)| s);
        self.kind.class = class;
        self.kind.vtol_state = match (class, ess, self.q_mode) {
            (VehicleClass::Vtol, Some(s), _) => s,
            (VehicleClass::Vtol, None, Some(true)) => VtolState::Mc,
            (VehicleClass::Vtol, None, Some(false)) => VtolState::Fw,
            (VehicleClass::Vtol, None, None) => before.vtol_state,
            _ => VtolState::Undefined,
        };
        let t = t_us as f64 * 1e-6;
        if first {
            tracing::info!(
                "vehicle class: {} (HEARTBEAT type {}) at t = {t:.1} s",
                self.kind.describe(),
                self.kind.mav_type_label().unwrap_or_default()
            );
        } else if self.kind.class != before.class || self.kind.vtol_state != before.vtol_state {
            self.switches += 1;
            tracing::info!(
                "vehicle class: {} → {} at t = {t:.1} s",
                before.describe(),
                self.kind.describe()
            );
        }
        self.say_unmodelled();
    }

    /// The one line for a vehicle dronewatt has no power model for.
    fn say_unmodelled(&mut self) {
        if self.kind.class == VehicleClass::Other && !self.said_unmodelled {
            self.said_unmodelled = true;
            let what = self
                .kind
                .mav_type
                .map(|t| match crate::features::class::mav_type_name(t) {
                    Some(n) => n.to_string(),
                    None => format!("vehicle of MAV_TYPE {t}"),
                })
                .unwrap_or_else(|| "vehicle of class other".to_string());
            tracing::warn!("no power model for a {what}: estimates from measured power only");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dialect as d;

    fn hb(t: d::MavType, mode: u32) -> MavMessage {
        MavMessage::HEARTBEAT(d::HEARTBEAT_DATA {
            custom_mode: mode,
            mavtype: t,
            autopilot: d::MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
            base_mode: d::MavModeFlag::empty(),
            system_status: d::MavState::MAV_STATE_ACTIVE,
            mavlink_version: 3,
        })
    }

    #[test]
    fn a_quadplane_saying_fixed_wing_is_followed_through_its_modes() {
        let mut k = KindTracker::new(None);
        k.ingest(0, 1_500_000, &hb(d::MavType::MAV_TYPE_FIXED_WING, 10));
        assert_eq!(k.kind().class, VehicleClass::FixedWing);
        // QHOVER: a quadplane on its rotors.
        k.ingest(
            1_000_000,
            1_500_000,
            &hb(d::MavType::MAV_TYPE_FIXED_WING, 18),
        );
        assert_eq!(k.kind().class, VehicleClass::Vtol);
        assert_eq!(k.kind().vtol_state, VtolState::Mc);
        // AUTO (10), no EXTENDED_SYS_STATE: forward flight.
        k.ingest(
            2_000_000,
            1_500_000,
            &hb(d::MavType::MAV_TYPE_FIXED_WING, 10),
        );
        assert_eq!(k.kind().vtol_state, VtolState::Fw);
        // EXTENDED_SYS_STATE wins while heard.
        let ess = MavMessage::EXTENDED_SYS_STATE(d::EXTENDED_SYS_STATE_DATA {
            vtol_state: d::MavVtolState::MAV_VTOL_STATE_TRANSITION_TO_MC,
            landed_state: d::MavLandedState::MAV_LANDED_STATE_IN_AIR,
        });
        k.ingest(2_100_000, 1_500_000, &ess);
        assert_eq!(k.kind().vtol_state, VtolState::TransitionToMc);
        assert_eq!(k.switches(), 3);
    }

    #[test]
    fn the_profile_wins_and_a_sub_is_other() {
        let mut k = KindTracker::new(Some(VehicleClass::FixedWing));
        k.ingest(0, 1, &hb(d::MavType::MAV_TYPE_QUADROTOR, 0));
        assert_eq!(k.kind().class, VehicleClass::FixedWing);
        assert!(k.kind().from_config);
        let mut k = KindTracker::new(None);
        k.ingest(0, 1, &hb(d::MavType::MAV_TYPE_SUBMARINE, 0));
        assert_eq!(k.kind().class, VehicleClass::Other);
        assert_eq!(k.kind().mav_type, Some(12));
    }
}
