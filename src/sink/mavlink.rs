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
//!
//! A value that is not known yet (no measured power, no home) is not sent.
//!
//! ## Who it says it is
//!
//! Default system id 1, component id 191 (`MAV_COMP_ID_ONBOARD_COMPUTER`). Ground stations
//! file STATUSTEXT under the *vehicle* whose system id sent it (QGroundControl drops
//! messages from a system id it has no vehicle for), and 1 is the id ArduPilot and PX4 use
//! out of the box; the component id is what tells the ground station this is not the
//! autopilot (component 1), so it never takes dronewatt's heartbeat for the autopilot's.
//! Set `system_id` to your vehicle's `SYSID_THISMAV` / `MAV_SYS_ID` when that is not 1.
//! The heartbeat says `MAV_TYPE_ONBOARD_CONTROLLER`, `MAV_AUTOPILOT_INVALID`.
//!
//! ## Where it sends
//!
//! With no `address`, on the link `monitor` reads (udpin answers whoever sent last, the
//! usual ground-station arrangement); or to `udpout:HOST:PORT` / `tcpout:HOST:PORT`.
//! Sending never blocks the pipeline: a full or absent link drops the frame and counts it.

use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use ::mavlink::{MavHeader, MavlinkVersion};
use tokio::io::AsyncWriteExt;
use tokio::sync::broadcast;

use crate::dialect::{self, MavSeverity};
use crate::energy::Report;
use crate::source::LinkHandle;
use crate::MavMessage;

/// The `[sinks.mavlink]` table.
#[derive(Debug, Clone, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct MavlinkSinkConfig {
    /// On or off. Default: on when `monitor` watches a live link, off for a replay unless
    /// `address` is set.
    pub enabled: Option<bool>,
    /// `udpout:HOST:PORT` or `tcpout:HOST:PORT`; absent: the link `monitor` reads.
    pub address: Option<String>,
    /// System id dronewatt sends with. Default 1 (the vehicle's; see the module docs).
    pub system_id: u8,
    /// Component id dronewatt sends with. Default 191, MAV_COMP_ID_ONBOARD_COMPUTER.
    pub component_id: u8,
    /// NAMED_VALUE_FLOAT sets per second (wall clock). Default 2. Alerts are never held back.
    pub rate_hz: f64,
}

impl Default for MavlinkSinkConfig {
    fn default() -> Self {
        Self { enabled: None, address: None, system_id: 1, component_id: 191, rate_hz: 2.0 }
    }
}

impl MavlinkSinkConfig {
    /// Range checks; the message names the key.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.rate_hz > 0.0 && self.rate_hz <= 50.0) {
            return Err(format!("sinks.mavlink.rate_hz = {}: must be in (0, 50] per second", self.rate_hz));
        }
        if self.system_id == 0 {
            return Err("sinks.mavlink.system_id = 0: 0 is the broadcast id; use 1..=255".into());
        }
        if self.component_id == 0 || self.component_id == 1 {
            return Err(format!(
                "sinks.mavlink.component_id = {}: 0 is broadcast and 1 is the autopilot's; use e.g. 191 (MAV_COMP_ID_ONBOARD_COMPUTER)",
                self.component_id
            ));
        }
        if let Some(a) = &self.address {
            Target::parse(a).map_err(|e| format!("sinks.mavlink.address = '{a}': {e}"))?;
        }
        Ok(())
    }
}

/// A parsed `address`.
#[derive(Debug, Clone, PartialEq)]
enum Target {
    Udp(String),
    Tcp(String),
}

impl Target {
    fn parse(a: &str) -> Result<Self, String> {
        let (scheme, rest) = a.split_once(':').ok_or("expected udpout:HOST:PORT or tcpout:HOST:PORT")?;
        let port_ok = rest.rsplit_once(':').is_some_and(|(h, p)| !h.is_empty() && p.parse::<u16>().is_ok());
        if !port_ok {
            return Err("expected HOST:PORT after the scheme".into());
        }
        match scheme {
            "udpout" | "udp" => Ok(Target::Udp(rest.to_string())),
            "tcpout" | "tcp" => Ok(Target::Tcp(rest.to_string())),
            _ => Err(format!("scheme '{scheme}': expected udpout or tcpout")),
        }
    }
}

/// Frames dronewatt's messages with its ids and a running sequence number.
pub struct Encoder {
    system_id: u32,
    component_id: u8,
    seq: u8,
    start: Instant,
}

impl Encoder {
    /// An encoder sending as this system and component.
    pub fn new(system_id: u8, component_id: u8) -> Self {
        Self { system_id: u32::from(system_id), component_id, seq: 0, start: Instant::now() }
    }

    /// One MAVLink 2 frame.
    pub fn frame(&mut self, msg: &MavMessage) -> Vec<u8> {
        let header = MavHeader { system_id: self.system_id, component_id: self.component_id, sequence: self.seq };
        self.seq = self.seq.wrapping_add(1);
        let mut buf = Vec::with_capacity(64);
        // Writing into a Vec cannot fail.
        let _ = ::mavlink::write_versioned_msg(&mut buf, MavlinkVersion::V2, header, msg);
        buf
    }

    fn boot_ms(&self) -> u32 {
        u32::try_from(self.start.elapsed().as_millis()).unwrap_or(u32::MAX)
    }

    /// The heartbeat of an onboard computer that is not an autopilot.
    pub fn heartbeat(&mut self) -> Vec<u8> {
        self.frame(&MavMessage::HEARTBEAT(dialect::HEARTBEAT_DATA {
            custom_mode: 0,
            mavtype: dialect::MavType::MAV_TYPE_ONBOARD_CONTROLLER,
            autopilot: dialect::MavAutopilot::MAV_AUTOPILOT_INVALID,
            base_mode: dialect::MavModeFlag::empty(),
            system_status: dialect::MavState::MAV_STATE_ACTIVE,
            mavlink_version: 3,
        }))
    }

    /// A STATUSTEXT, cut to MAVLink's 50 bytes on a character boundary.
    pub fn statustext(&mut self, severity: MavSeverity, text: &str) -> Vec<u8> {
        self.frame(&MavMessage::STATUSTEXT(dialect::STATUSTEXT_DATA {
            severity,
            text: truncate_bytes(text, 50).into(),
            id: 0,
            chunk_seq: 0,
        }))
    }

    /// A NAMED_VALUE_FLOAT (`name` ≤ 10 bytes).
    pub fn named_value(&mut self, name: &str, value: f32) -> Vec<u8> {
        let time_boot_ms = self.boot_ms();
        self.frame(&MavMessage::NAMED_VALUE_FLOAT(dialect::NAMED_VALUE_FLOAT_DATA {
            time_boot_ms,
            value,
            name: truncate_bytes(name, 10).into(),
        }))
    }

    /// Every NAMED_VALUE_FLOAT of one report (see the module's table).
    pub fn estimates(&mut self, r: &Report) -> Vec<Vec<u8>> {
        let e = &r.energy;
        let model = |n: &str| r.estimate.models.iter().find(|m| m.name == n).map(|m| f64::from(m.power_w));
        let adapted = |n: &str| r.estimate.models.iter().find(|m| m.name == n).map(|m| f64::from(m.adapted_w.unwrap_or(m.power_w)));
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
        ];
        values
            .into_iter()
            .filter_map(|(n, v)| v.filter(|v| v.is_finite()).map(|v| self.named_value(n, v as f32)))
            .collect()
    }

    /// The STATUSTEXTs of one report's alerts: raised ones at the rule's severity, cleared
    /// ones at INFO (news, not a warning).
    pub fn alerts(&mut self, r: &Report) -> Vec<Vec<u8>> {
        r.alerts
            .iter()
            .map(|a| {
                let sev = match a.state {
                    crate::alert::AlertState::Raised => {
                        a.severity.parse::<crate::alert::Severity>().map_or(MavSeverity::MAV_SEVERITY_WARNING, |s| s.to_mav())
                    }
                    crate::alert::AlertState::Cleared => MavSeverity::MAV_SEVERITY_INFO,
                };
                self.statustext(sev, &a.message)
            })
            .collect()
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

/// Where frames go.
enum Out {
    Link(LinkHandle),
    Udp(tokio::net::UdpSocket),
    Tcp { addr: String, stream: Option<tokio::net::TcpStream>, retry_at: Instant },
}

impl Out {
    async fn open(cfg: &MavlinkSinkConfig, link: LinkHandle) -> Result<Self> {
        Ok(match cfg.address.as_deref() {
            None => Out::Link(link),
            Some(a) => match Target::parse(a).map_err(anyhow::Error::msg).with_context(|| format!("sinks.mavlink.address = '{a}'"))? {
                Target::Udp(hp) => {
                    let sock = tokio::net::UdpSocket::bind(if hp.starts_with('[') { "[::]:0" } else { "0.0.0.0:0" })
                        .await
                        .context("MAVLink sink: cannot open a UDP socket")?;
                    sock.connect(&hp).await.with_context(|| format!("MAVLink sink: cannot resolve udpout:{hp}"))?;
                    Out::Udp(sock)
                }
                Target::Tcp(hp) => Out::Tcp { addr: hp, stream: None, retry_at: Instant::now() },
            },
        })
    }

    /// Send one frame; false when it had to be dropped.
    async fn send(&mut self, frame: Vec<u8>) -> bool {
        match self {
            Out::Link(l) => l.try_send(frame),
            // ECONNREFUSED on a connected UDP socket only means nobody listens yet.
            Out::Udp(s) => s.send(&frame).await.is_ok(),
            Out::Tcp { addr, stream, retry_at } => {
                if stream.is_none() && Instant::now() >= *retry_at {
                    match tokio::time::timeout(Duration::from_secs(1), tokio::net::TcpStream::connect(&*addr)).await {
                        Ok(Ok(s)) => *stream = Some(s),
                        _ => *retry_at = Instant::now() + Duration::from_secs(2),
                    }
                }
                let Some(s) = stream else { return false };
                if s.write_all(&frame).await.is_err() {
                    *stream = None;
                    return false;
                }
                true
            }
        }
    }
}

/// Run the sink until the report channel closes.
pub async fn run(cfg: MavlinkSinkConfig, mut rx: broadcast::Receiver<std::sync::Arc<Report>>, link: LinkHandle) -> Result<()> {
    if let Err(e) = cfg.validate() {
        bail!("{e}");
    }
    let mut out = Out::open(&cfg, link).await?;
    let mut enc = Encoder::new(cfg.system_id, cfg.component_id);
    let period = Duration::from_secs_f64(1.0 / cfg.rate_hz);
    let mut next_values = Instant::now();
    let mut heartbeat = tokio::time::interval(Duration::from_secs(1));
    heartbeat.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let (mut dropped, mut missed) = (0u64, 0u64);
    loop {
        let frames = tokio::select! {
            _ = heartbeat.tick() => vec![enc.heartbeat()],
            r = super::next_report(&mut rx, &mut missed) => match r {
                Some(report) => {
                    let mut f = enc.alerts(&report);
                    let now = Instant::now();
                    if now >= next_values {
                        next_values = (next_values + period).max(now);
                        f.extend(enc.estimates(&report));
                    }
                    f
                }
                None => break,
            },
        };
        for f in frames {
            if !out.send(f).await {
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
        assert_eq!(Target::parse("udpout:127.0.0.1:14550"), Ok(Target::Udp("127.0.0.1:14550".into())));
        assert_eq!(Target::parse("tcpout:gcs.local:5760"), Ok(Target::Tcp("gcs.local:5760".into())));
        assert!(Target::parse("udpin:0.0.0.0:14550").is_err());
        assert!(Target::parse("udpout:nohost").is_err());
        let bad = MavlinkSinkConfig { component_id: 1, ..Default::default() };
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
