//! Where reports go: terminal, JSON lines, MAVLink back to the ground station, web, MQTT.
//! Each sink is its own task fed by one broadcast of [`crate::energy::Report`]s.
//!
//! A broadcast never waits for a slow receiver: one that falls more than the channel's
//! depth behind loses the oldest reports. The energy stage holds back while a sink is
//! far behind (see [`crate::pipeline`]), so this only happens to a sink that is stuck;
//! every sink counts what it missed ([`next_report`]) and says so, never silently.

pub mod jsonl;
pub mod terminal;

pub mod mavlink;
pub mod mqtt;
pub mod web;

/// Publishers (the `[sinks]` table).
#[derive(Debug, Clone, Default, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SinksConfig {
    /// MAVLink back to the ground station (`[sinks.mavlink]`).
    pub mavlink: mavlink::MavlinkSinkConfig,
    /// The web dashboard (`[sinks.web]`).
    pub web: web::WebSinkConfig,
    /// An MQTT broker (`[sinks.mqtt]`).
    pub mqtt: mqtt::MqttSinkConfig,
}

use std::sync::Arc;

use tokio::sync::broadcast;
use tokio::task::JoinHandle;

use crate::energy::Report;
use crate::source::{IngestStats, LinkHandle};

/// Where `--json` writes.
#[derive(Debug, Clone)]
pub enum JsonTarget {
    Stdout,
    File(std::path::PathBuf),
}

/// One publisher a run feeds.
#[derive(Debug, Clone)]
pub enum SinkSpec {
    /// The compact live terminal view.
    Terminal,
    /// JSON lines.
    Json(JsonTarget),
    /// STATUSTEXT and NAMED_VALUE_FLOAT back to the ground station.
    Mavlink(mavlink::MavlinkSinkConfig),
    /// The web dashboard.
    Web(web::WebSinkConfig),
    /// An MQTT broker.
    Mqtt(mqtt::MqttSinkConfig),
}

/// Start one sink as its own task. The task ends when the report channel closes, after
/// flushing (and, for JSON, writing the summary line). Fails before anything runs when
/// the sink cannot start (a JSON file that cannot be created).
pub fn spawn(
    spec: SinkSpec,
    rx: broadcast::Receiver<Arc<Report>>,
    stats: Arc<IngestStats>,
    health: crate::telemetry::HealthHandle,
    link: LinkHandle,
) -> anyhow::Result<JoinHandle<anyhow::Result<()>>> {
    match spec {
        SinkSpec::Terminal => Ok(tokio::spawn(terminal::run(rx, stats, health))),
        SinkSpec::Json(target) => jsonl::spawn(target, rx, stats),
        SinkSpec::Mavlink(c) => Ok(tokio::spawn(mavlink::run(c, rx, link))),
        SinkSpec::Web(c) => web::spawn(c, rx),
        SinkSpec::Mqtt(c) => mqtt::spawn(c, rx),
    }
}

/// The next report for a sink, adding to `missed` the reports it lost by lagging (and
/// logging it). `None` when the channel has closed: the run is over.
pub async fn next_report(rx: &mut broadcast::Receiver<Arc<Report>>, missed: &mut u64) -> Option<Arc<Report>> {
    loop {
        match rx.recv().await {
            Ok(r) => return Some(r),
            Err(broadcast::error::RecvError::Lagged(n)) => lagged(missed, n),
            Err(broadcast::error::RecvError::Closed) => return None,
        }
    }
}

/// [`next_report`] for a sink that runs on its own thread.
pub fn next_report_blocking(rx: &mut broadcast::Receiver<Arc<Report>>, missed: &mut u64) -> Option<Arc<Report>> {
    loop {
        match rx.blocking_recv() {
            Ok(r) => return Some(r),
            Err(broadcast::error::RecvError::Lagged(n)) => lagged(missed, n),
            Err(broadcast::error::RecvError::Closed) => return None,
        }
    }
}

fn lagged(missed: &mut u64, n: u64) {
    *missed += n;
    tracing::warn!("a sink fell behind and missed {n} reports ({missed} so far)");
}
