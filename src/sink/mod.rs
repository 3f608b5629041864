//! Where reports go: terminal (the line view or the full screen), JSON lines, MAVLink back to the ground station, web, MQTT.
//! Each sink is its own task with its own bounded queue of [`Report`]s ([`Fanout`],
//! [`ReportRx`]), and one typed handle, [`ChainStatus`], for what the chain says about
//! itself beside the reports (ingest counters, signal health, the uplink). Sinks read
//! reports, never sources.
//!
//! The energy stage waits for a sink whose queue is full, so a flat-out replay loses
//! nothing; only a sink stuck for longer than [`SINK_PATIENCE`] misses reports, and it
//! counts them ([`ReportRx::missed`]) and says so, never silently.

pub mod jsonl;
mod jsonl_estimate;
pub mod jsonl_read;
mod jsonl_window;
pub mod pilot;
pub mod screen;
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

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use tokio::sync::mpsc;
use tokio::task::JoinHandle;

use crate::report::status::ChainStatus;
use crate::report::Report;

/// Reports a sink's queue holds before the energy stage waits for it.
pub const SINK_DEPTH: usize = 1024;
/// How long the energy stage waits for a sink whose queue is full before it gives up on
/// that sink: from then on the sink misses reports (counted) until it has drained half its
/// queue, and the rest of the chain goes on.
pub const SINK_PATIENCE: Duration = Duration::from_secs(1);

/// Where `--json` writes.
#[derive(Debug, Clone)]
pub enum JsonTarget {
    Stdout,
    File(std::path::PathBuf),
}

/// One publisher a run feeds.
#[derive(Debug, Clone)]
pub enum SinkSpec {
    /// The compact live terminal view (lines on stderr); `detail`: the engineer's line
    /// (every model's figures) instead of the pilot's.
    Terminal { detail: bool },
    /// The full live screen on a terminal stdout ([`screen`]); `detail`: every model's
    /// figures in the power tile.
    Screen { detail: bool },
    /// JSON lines.
    Json(JsonTarget),
    /// STATUSTEXT and NAMED_VALUE_FLOAT back to the ground station.
    Mavlink(mavlink::MavlinkSinkConfig),
    /// The web dashboard.
    Web(web::WebSinkConfig),
    /// An MQTT broker.
    Mqtt(mqtt::MqttSinkConfig),
}

/// Start one sink as its own task, reading `rx`. The task ends when the chain closes its
/// queue, after flushing (and, for JSON, writing the summary line). Fails before anything
/// runs when the sink cannot start (a JSON file that cannot be created, a port in use).
pub fn spawn(
    spec: SinkSpec,
    rx: ReportRx,
    status: ChainStatus,
) -> anyhow::Result<JoinHandle<anyhow::Result<()>>> {
    match spec {
        SinkSpec::Terminal { detail } => Ok(tokio::spawn(terminal::run(rx, status, detail))),
        SinkSpec::Screen { detail } => Ok(tokio::spawn(screen::run(rx, status, detail))),
        SinkSpec::Json(target) => jsonl::spawn(target, rx, status),
        SinkSpec::Mavlink(c) => Ok(tokio::spawn(mavlink::run(c, rx, status.link))),
        SinkSpec::Web(c) => web::spawn(c, rx, status.shutdown, status.stats),
        SinkSpec::Mqtt(c) => mqtt::spawn_with_links(c, rx, Some(status.stats)),
    }
}

/// One sink's inbox: the reports in order, and a count of those it missed.
pub struct ReportRx {
    rx: mpsc::Receiver<Arc<Report>>,
    missed: Arc<AtomicU64>,
}

impl ReportRx {
    /// The next report; `None` once the chain has ended (every report before that came).
    pub async fn next(&mut self) -> Option<Arc<Report>> {
        self.rx.recv().await
    }
    /// [`ReportRx::next`] for a sink that runs on its own thread.
    pub fn blocking_next(&mut self) -> Option<Arc<Report>> {
        self.rx.blocking_recv()
    }
    /// Whether no report waits right now (a writer flushes then: live, each report shows
    /// up as it happens).
    pub fn is_empty(&self) -> bool {
        self.rx.is_empty()
    }
    /// Reports this sink missed because it was stuck for longer than [`SINK_PATIENCE`].
    pub fn missed(&self) -> u64 {
        self.missed.load(Ordering::Relaxed)
    }
}

/// The energy stage's side of the sinks: one bounded queue per sink. A full queue holds
/// the chain back (a flat-out replay loses nothing to a slower sink); a sink stuck for
/// longer than [`SINK_PATIENCE`] loses reports instead, and counts them, until it catches up.
/// A clone feeds the same sinks (each vehicle's chain holds one); a sink's queue closes
/// when every clone is gone.
#[derive(Default, Clone)]
pub struct Fanout {
    outs: Vec<Outlet>,
    /// Where the queues' depth is watched ([`crate::report::status::QueueGauge`]).
    stats: Option<Arc<crate::report::status::IngestStats>>,
}

#[derive(Clone)]
struct Outlet {
    tx: mpsc::Sender<Arc<Report>>,
    missed: Arc<AtomicU64>,
    stuck: bool,
}

impl Fanout {
    /// Watch the depth of every queue of this fanout in `stats`.
    pub fn gauged(self, stats: Arc<crate::report::status::IngestStats>) -> Self {
        Self {
            stats: Some(stats),
            ..self
        }
    }

    /// A new sink's queue.
    pub fn subscribe(&mut self) -> ReportRx {
        let (tx, rx) = mpsc::channel(SINK_DEPTH);
        let missed = Arc::new(AtomicU64::new(0));
        self.outs.push(Outlet {
            tx,
            missed: missed.clone(),
            stuck: false,
        });
        ReportRx { rx, missed }
    }

    /// Hand one report to every sink (see [`Fanout`] for who waits and who misses it).
    pub async fn send(&mut self, report: Report) {
        self.send_shared(Arc::new(report)).await
    }

    /// [`Fanout::send`] for a report already shared (passed on from another fanout).
    pub async fn send_shared(&mut self, report: Arc<Report>) {
        for o in &mut self.outs {
            if o.stuck && o.tx.capacity() >= SINK_DEPTH / 2 {
                o.stuck = false;
                tracing::info!(
                    "a sink caught up after missing {} reports",
                    o.missed.load(Ordering::Relaxed)
                );
            }
            match o.tx.try_send(report.clone()) {
                Ok(()) | Err(mpsc::error::TrySendError::Closed(_)) => {}
                Err(mpsc::error::TrySendError::Full(r)) if !o.stuck => {
                    if tokio::time::timeout(SINK_PATIENCE, o.tx.send(r))
                        .await
                        .is_err()
                    {
                        o.stuck = true;
                        o.missed.fetch_add(1, Ordering::Relaxed);
                        tracing::warn!("a sink is stuck (no room for {} s): it misses reports until it catches up", SINK_PATIENCE.as_secs_f64());
                    }
                }
                Err(mpsc::error::TrySendError::Full(_)) => {
                    o.missed.fetch_add(1, Ordering::Relaxed);
                }
            }
            if let Some(s) = &self.stats {
                s.queues.observe(&o.tx);
            }
        }
    }
}
