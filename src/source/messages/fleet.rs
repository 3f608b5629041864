//! Which senders on a link are vehicles, and which of them this instance watches: the
//! `[fleet]` table, the `--vehicles` filter, and what counts as a vehicle's heartbeat or
//! telemetry. Pure: no I/O, no clocks. [`crate::pipeline::Demux`] uses these to put one
//! vehicle chain per system id in front of a link.
//!
//! A vehicle appears with its first HEARTBEAT from a vehicle: not a ground station
//! (`MAV_TYPE_GCS`), not a companion or other onboard component (`MAV_TYPE_ONBOARD_CONTROLLER`,
//! `MAV_AUTOPILOT_INVALID`: dronewatt's own heartbeat is one). So that a log that begins
//! between two heartbeats loses nothing, a telemetry message the chain reads (ATTITUDE,
//! GLOBAL_POSITION_INT, BATTERY_STATUS … — never sent by a ground station) also opens a
//! vehicle, unless that system id has only ever sent a non-vehicle heartbeat.

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
        Self {
            lost_after_s: 10.0,
            drop_after_s: 60.0,
            vehicles: None,
            batch_wait_ms: 2.0,
            lstm_rate_hz: None,
        }
    }
}

impl FleetConfig {
    /// Range checks; each message names the key (several errors: one per line).
    pub fn validate(&self) -> Result<(), String> {
        use crate::validate::{above, above_to};
        let mut errs = crate::validate::Errors::new();
        errs.range("fleet.lost_after_s", self.lost_after_s, above(0.0), "s");
        if !(self.drop_after_s > self.lost_after_s && self.drop_after_s.is_finite()) {
            errs.push(format!(
                "fleet.drop_after_s = {}: must be longer than fleet.lost_after_s ({})",
                self.drop_after_s, self.lost_after_s
            ));
        }
        errs.range("fleet.batch_wait_ms", self.batch_wait_ms, 0.0..=100.0, "ms");
        if let Some(r) = self.lstm_rate_hz {
            errs.range("fleet.lstm_rate_hz", r, above_to(0.0, 100.0), "Hz");
        }
        if let Some(v) = &self.vehicles {
            if let Err(e) = VehicleFilter::parse(v) {
                errs.push(format!("fleet.vehicles = {v:?}: {e}"));
            }
        }
        errs.into_result()
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
            ids[usize::from(lo)..=usize::from(hi)]
                .iter_mut()
                .for_each(|b| *b = true);
        }
        Ok(Self { ids })
    }
    /// Whether `id` is in the set.
    pub fn contains(&self, id: u32) -> bool {
        usize::try_from(id)
            .ok()
            .and_then(|i| self.ids.get(i))
            .copied()
            .unwrap_or(false)
    }
}

/// Whether a HEARTBEAT comes from a vehicle's autopilot (not a ground station, a companion
/// computer or another onboard component).
pub fn is_vehicle_heartbeat(h: &crate::dialect::HEARTBEAT_DATA) -> bool {
    use crate::dialect::{MavAutopilot, MavType};
    h.autopilot != MavAutopilot::MAV_AUTOPILOT_INVALID
        && !matches!(
            h.mavtype,
            MavType::MAV_TYPE_GCS | MavType::MAV_TYPE_ONBOARD_CONTROLLER
        )
}

/// Telemetry only a vehicle sends (what the telemetry stage reads its signals from).
pub fn is_vehicle_telemetry(m: &MavMessage) -> bool {
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
