//! MAVLink back to the ground station: alerts as STATUSTEXT (QGroundControl and Mission
//! Planner show and speak them), estimates as NAMED_VALUE_FLOAT (graphable in QGC's
//! MAVLink Inspector and Mission Planner's Quick tab), and a 1 Hz HEARTBEAT so the ground
//! station lists dronewatt as its own component.
//!
//! ## Names sent as NAMED_VALUE_FLOAT (≤ 10 characters, MAVLink's limit)
//!
//! | name | value | unit |
//! |---|---|---|
//! | `dw_meas_w` | measured electrical power V·I | W |
//! | `dw_pred_w` | the forecast model's prediction (`[energy] model`, else `lstm`; adapted to measured power when adaptation runs; absent when the forecast follows measured power) | W |
//! | `dw_lstm_w` | the LSTM's prediction, when the LSTM runs | W |
//! | `dw_fcst_w` | smoothed forecast power the energy figures assume | W |
//! | `dw_used_wh` | energy used since the start | Wh |
//! | `dw_rem_wh` | remaining energy | Wh |
//! | `dw_rem_pct` | remaining energy, % of capacity | % |
//! | `dw_tte_s` | time to empty at the forecast power | s |
//! | `dw_home_wh` | energy to fly home, descend and land | Wh |
//! | `dw_marg_wh` | remaining − energy home − reserve | Wh |
//! | `dw_mis_wh` | energy of the rest of the mission, its return and landing (P50; while a mission is known) | Wh |
//! | `dw_mis_mrg` | remaining − mission energy − reserve | Wh |
//! | `dw_mis_pct` | progress along the planned mission | % |
//!
//! A value that is not known yet (no measured power, no home) is not sent.
//!
//! ## Its own BATTERY_STATUS
//!
//! With the NAMED_VALUE_FLOATs, a BATTERY_STATUS of dronewatt's own (`battery_id`, default
//! 9, so it is not taken for the autopilot's battery 0): `battery_remaining` the remaining
//! energy in % of the capacity, `time_remaining` dronewatt's time to empty (s),
//! `energy_consumed` the energy used (hJ), voltages and currents "unknown". A time to empty
//! not known yet is sent as 0, MAVLink's "not provided"; a known one is never below 1 s,
//! so a 0 never reads as a real estimate. `battery_id = 255` turns it off.
//!
//! ## Who it says it is
//!
//! System id: that of the vehicle each report is about (every vehicle of a fleet gets its
//! own messages and its own 1 Hz heartbeat, from its first report on); component id
//! 191 (`MAV_COMP_ID_ONBOARD_COMPUTER`). Ground stations file STATUSTEXT under the
//! *vehicle* whose system id sent it (QGroundControl drops messages from a system id it has
//! no vehicle for); the component id is what tells the ground station this is not the
//! autopilot (component 1), so it never takes dronewatt's heartbeat for the autopilot's.
//! Setting `system_id` sends everything as that one id instead.
//! The heartbeat says `MAV_TYPE_ONBOARD_CONTROLLER`, `MAV_AUTOPILOT_INVALID`.
//!
//! ## Where it sends
//!
//! With no `address`, on the link `monitor` reads (udpin answers whoever sent last, the
//! usual ground-station arrangement); or to `udpout:HOST:PORT` / `tcpout:HOST:PORT`.
//! Sending never blocks the pipeline: a full or absent link drops the frame and counts it.
//! With a `[link] signing_key_file`, every frame is MAVLink 2 signed
//! ([`crate::source::links::signing`]), whichever way it goes out.

use std::time::{Duration, Instant};

use anyhow::{bail, Result};

use crate::dialect::{self, MavSeverity};
use crate::report::status::LinkHandle;
use crate::report::{Report, VehicleId};
use crate::MavMessage;

/// The `[sinks.mavlink]` table.
#[derive(Debug, Clone, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct MavlinkSinkConfig {
    /// On or off. Default: on when `monitor` watches a live link, off for a replay unless
    /// `address` is set.
    pub enabled: Option<bool>,
    /// A link address of its own (`udpout:HOST:PORT`, `tcpout:HOST:PORT`, or any form
    /// `monitor` takes: the grammar is one, see `crate::source::links::address`); absent: the link
    /// `monitor` reads.
    pub address: Option<String>,
    /// System id dronewatt sends with. Default: the id of the vehicle each report is about
    /// (see the module docs).
    pub system_id: Option<u8>,
    /// Component id dronewatt sends with. Default 191, MAV_COMP_ID_ONBOARD_COMPUTER.
    pub component_id: u8,
    /// NAMED_VALUE_FLOAT sets per second (wall clock). Default 2. Alerts are never held back.
    pub rate_hz: f64,
    /// Battery id of dronewatt's own BATTERY_STATUS (sent with the values; see the module
    /// docs). Default 9; 255 sends none.
    pub battery_id: u8,
}

impl Default for MavlinkSinkConfig {
    fn default() -> Self {
        Self {
            enabled: None,
            address: None,
            system_id: None,
            component_id: 191,
            rate_hz: 2.0,
            battery_id: 9,
        }
    }
}

impl MavlinkSinkConfig {
    /// Range checks; each message names the key (several errors: one per line).
    pub fn validate(&self) -> Result<(), String> {
        let mut errs = crate::validate::Errors::new();
        errs.range(
            "sinks.mavlink.rate_hz",
            self.rate_hz,
            crate::validate::above_to(0.0, 50.0),
            "per second",
        );
        if self.system_id == Some(0) {
            errs.push("sinks.mavlink.system_id = 0: 0 is the broadcast id; use 1..=255".into());
        }
        if self.component_id == 0 || self.component_id == 1 {
            errs.push(format!(
                "sinks.mavlink.component_id = {}: 0 is broadcast and 1 is the autopilot's; use e.g. 191 (MAV_COMP_ID_ONBOARD_COMPUTER)",
                self.component_id
            ));
        }
        if let Some(a) = &self.address {
            if let Err(e) = a.parse::<crate::source::links::address::LinkAddress>() {
                errs.push(format!("sinks.mavlink.address: {e}"));
            }
        }
        errs.into_result()
    }
}

/// Composes dronewatt's messages for one identity (system id, component). The link
/// numbers and frames them ([`LinkHandle::send_as`]: one sequence per identity on a link,
/// shared with the parameter reader and the mission client).
pub struct Encoder {
    system_id: u8,
    component_id: u8,
    start: Instant,
}

impl Encoder {
    /// An encoder sending as this system and component.
    pub fn new(system_id: u8, component_id: u8) -> Self {
        Self {
            system_id,
            component_id,
            start: Instant::now(),
        }
    }

    /// The identity its messages go out as: (system id, component id).
    pub fn identity(&self) -> (u8, u8) {
        (self.system_id, self.component_id)
    }

    fn boot_ms(&self) -> u32 {
        u32::try_from(self.start.elapsed().as_millis()).unwrap_or(u32::MAX)
    }

    /// The heartbeat of an onboard computer that is not an autopilot.
    pub fn heartbeat(&mut self) -> MavMessage {
        MavMessage::HEARTBEAT(dialect::HEARTBEAT_DATA {
            custom_mode: 0,
            mavtype: dialect::MavType::MAV_TYPE_ONBOARD_CONTROLLER,
            autopilot: dialect::MavAutopilot::MAV_AUTOPILOT_INVALID,
            base_mode: dialect::MavModeFlag::empty(),
            system_status: dialect::MavState::MAV_STATE_ACTIVE,
            mavlink_version: 3,
        })
    }

    /// A STATUSTEXT, cut to MAVLink's 50 bytes on a character boundary.
    pub fn statustext(&mut self, severity: MavSeverity, text: &str) -> MavMessage {
        MavMessage::STATUSTEXT(dialect::STATUSTEXT_DATA {
            severity,
            text: truncate_bytes(text, 50).into(),
            id: 0,
            chunk_seq: 0,
        })
    }

    /// A NAMED_VALUE_FLOAT (`name` ≤ 10 bytes).
    pub fn named_value(&mut self, name: &str, value: f32) -> MavMessage {
        let time_boot_ms = self.boot_ms();
        MavMessage::NAMED_VALUE_FLOAT(dialect::NAMED_VALUE_FLOAT_DATA {
            time_boot_ms,
            value,
            name: truncate_bytes(name, 10).into(),
        })
    }

    /// Every NAMED_VALUE_FLOAT of one report (see the module's table).
    pub fn estimates(&mut self, r: &Report) -> Vec<MavMessage> {
        let e = &r.energy;
        let model = |n: &str| {
            r.estimate
                .models
                .iter()
                .find(|m| m.name == n)
                .map(|m| f64::from(m.power_w))
        };
        let adapted = |n: &str| {
            r.estimate
                .models
                .iter()
                .find(|m| m.name == n)
                .map(|m| f64::from(m.adapted_w.unwrap_or(m.power_w)))
        };
        let values = [
            ("dw_meas_w", r.estimate.sample.measured_w.map(f64::from)),
            ("dw_pred_w", e.forecast_model.as_deref().and_then(adapted)),
            ("dw_lstm_w", model("lstm")),
            ("dw_fcst_w", e.forecast_w),
            ("dw_used_wh", Some(e.energy_used_wh)),
            ("dw_rem_wh", e.remaining_wh),
            ("dw_rem_pct", e.remaining_pct),
            ("dw_tte_s", e.time_to_empty_s),
            ("dw_home_wh", e.home_energy_wh),
            ("dw_marg_wh", e.home_margin_wh),
            ("dw_mis_wh", e.mission_energy_wh),
            ("dw_mis_mrg", e.mission_margin_wh),
            ("dw_mis_pct", e.mission.as_ref().map(|m| m.progress_pct)),
        ];
        values
            .into_iter()
            .filter_map(|(n, v)| {
                v.filter(|v| v.is_finite())
                    .map(|v| self.named_value(n, v as f32))
            })
            .collect()
    }

    /// dronewatt's own BATTERY_STATUS for one report (see the module docs).
    pub fn battery_status(&mut self, battery_id: u8, r: &Report) -> MavMessage {
        let e = &r.energy;
        let pct = e
            .remaining_pct
            .filter(|p| p.is_finite())
            .map_or(-1, |p| p.round().clamp(0.0, 100.0) as i8);
        let time_remaining = e
            .time_to_empty_s
            .filter(|t| t.is_finite() && *t >= 0.0)
            .map_or(0, |t| t.round().clamp(1.0, f64::from(i32::MAX)) as i32);
        let energy_consumed = if e.energy_used_wh.is_finite() {
            (e.energy_used_wh * 36.0)
                .round()
                .clamp(0.0, f64::from(i32::MAX)) as i32
        } else {
            -1
        };
        MavMessage::BATTERY_STATUS(dialect::BATTERY_STATUS_DATA {
            id: battery_id,
            battery_remaining: pct,
            time_remaining,
            energy_consumed,
            current_consumed: -1,
            current_battery: -1,
            temperature: i16::MAX,
            voltages: [u16::MAX; 10],
            voltages_ext: [0; 4],
            ..Default::default()
        })
    }

    /// The STATUSTEXTs of one report's alerts: raised ones at the rule's severity, cleared
    /// ones at INFO (news, not a warning).
    pub fn alerts(&mut self, r: &Report) -> Vec<MavMessage> {
        r.alerts
            .iter()
            .map(|a| {
                let sev = match a.state {
                    crate::report::AlertState::Raised => mav_severity(a.severity),
                    crate::report::AlertState::Cleared => MavSeverity::MAV_SEVERITY_INFO,
                };
                self.statustext(sev, &a.message)
            })
            .collect()
    }
}

/// A rule's severity as MAVLink's enum (same scale, same order).
fn mav_severity(s: crate::report::Severity) -> MavSeverity {
    use crate::report::Severity as S;
    match s {
        S::Emergency => MavSeverity::MAV_SEVERITY_EMERGENCY,
        S::Alert => MavSeverity::MAV_SEVERITY_ALERT,
        S::Critical => MavSeverity::MAV_SEVERITY_CRITICAL,
        S::Error => MavSeverity::MAV_SEVERITY_ERROR,
        S::Warning => MavSeverity::MAV_SEVERITY_WARNING,
        S::Notice => MavSeverity::MAV_SEVERITY_NOTICE,
        S::Info => MavSeverity::MAV_SEVERITY_INFO,
        S::Debug => MavSeverity::MAV_SEVERITY_DEBUG,
    }
}

fn truncate_bytes(s: &str, max: usize) -> &str {
    if s.len() <= max {
        return s;
    }
    let mut end = max;
    while !s.is_char_boundary(end) {
        end -= 1;
    }
    &s[..end]
}

/// Run the sink until the report channel closes.
/// Frames go out through `link`: the monitored link, or the uplink the pipeline opened
/// for `address` (both run by `source::links::link`, so one set of transports serves both).
pub async fn run(cfg: MavlinkSinkConfig, mut rx: super::ReportRx, link: LinkHandle) -> Result<()> {
    if let Err(e) = cfg.validate() {
        bail!("{e}");
    }
    // One encoder and one estimate clock per vehicle sent as (the link numbers frames);
    // each vehicle's frames go out on its own network's links.
    type Encs = std::collections::BTreeMap<VehicleId, (Encoder, Instant)>;
    let mut encs: Encs = Default::default();
    let period = Duration::from_secs_f64(1.0 / cfg.rate_hz);
    let mut heartbeat = tokio::time::interval(Duration::from_secs(1));
    heartbeat.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut dropped = 0u64;
    let enc_for = |encs: &mut Encs, v: VehicleId| {
        let id = VehicleId {
            system_id: cfg.system_id.unwrap_or(v.system_id),
            ..v
        };
        encs.entry(id)
            .or_insert_with(|| (Encoder::new(id.system_id, cfg.component_id), Instant::now()));
        id
    };
    loop {
        let frames = tokio::select! {
            // One per vehicle heard (none before the first: which id would it be?), or the
            // configured id's from the start.
            _ = heartbeat.tick() => {
                if let Some(id) = cfg.system_id {
                    if encs.is_empty() {
                        enc_for(&mut encs, VehicleId::single(id));
                    }
                }
                encs.iter_mut().map(|(v, (e, _))| (v.network, e.identity(), e.heartbeat())).collect::<Vec<_>>()
            }
            r = rx.next() => match r {
                Some(report) => {
                    let id = enc_for(&mut encs, report.vehicle);
                    let Some((enc, next_values)) = encs.get_mut(&id) else { continue };
                    let mut f = enc.alerts(&report);
                    let now = Instant::now();
                    if now >= *next_values {
                        *next_values = (*next_values + period).max(now);
                        f.extend(enc.estimates(&report));
                        if cfg.battery_id != 255 {
                            f.push(enc.battery_status(cfg.battery_id, &report));
                        }
                    }
                    // A dropped vehicle gets no more heartbeats.
                    if report.alerts.iter().any(|a| a.rule == "vehicle_dropped") && cfg.system_id.is_none() {
                        encs.remove(&id);
                    }
                    let who = (id.system_id, cfg.component_id);
                    f.into_iter().map(|m| (id.network, who, m)).collect()
                }
                None => break,
            },
        };
        for (network, (sys, comp), m) in frames {
            if !link.network(network).send_as(sys, comp, &m) {
                dropped += 1;
            }
        }
    }
    if dropped > 0 {
        tracing::debug!("MAVLink sink: {dropped} frames not sent (no link or link full)");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn addresses_and_ids_are_checked() {
        for ok in [
            "udpout:127.0.0.1:14550",
            "tcpout:gcs.local:5760",
            "udpin:0.0.0.0:14550",
        ] {
            let c = MavlinkSinkConfig {
                address: Some(ok.into()),
                ..Default::default()
            };
            assert_eq!(c.validate(), Ok(()), "{ok}");
        }
        for bad in ["udpout:nohost", "quic:host:1"] {
            let c = MavlinkSinkConfig {
                address: Some(bad.into()),
                ..Default::default()
            };
            let e = c.validate().unwrap_err();
            assert!(
                e.contains("sinks.mavlink.address") && e.contains(bad),
                "{e}"
            );
        }
        let bad = MavlinkSinkConfig {
            component_id: 1,
            ..Default::default()
        };
        assert!(bad.validate().unwrap_err().contains("component_id"));
    }

    #[test]
    fn statustext_is_cut_on_a_char_boundary() {
        let long = "é".repeat(40); // 80 bytes
        assert_eq!(truncate_bytes(&long, 50).len(), 50);
        assert_eq!(truncate_bytes("abc", 50), "abc");
        assert_eq!(truncate_bytes("aé", 2), "a");
    }
}
