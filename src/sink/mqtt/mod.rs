//! MQTT (`[sinks.mqtt]`): every report to a broker, where a fleet's dashboards, rule engines
//! and databases already listen. Any MQTT 3.1.1 broker (Mosquitto, EMQX, HiveMQ, VerneMQ …);
//! the client is rumqttc (pure Rust, on tokio).
//!
//! Topics, under `prefix` (default `dronewatt`); `<vehicle>` is the vehicle's MAVLink
//! system id, or `network:system id` where the links are separate networks
//! ([`crate::report::VehicleId`]), so several instances watching different vehicles can
//! share one broker:
//!
//! | topic | payload | QoS | retained | when |
//! |---|---|---|---|---|
//! | `<prefix>/<vehicle>/estimate` | the JSON-lines `estimate` object | 0 | no | every report (the window rate, 10 Hz) |
//! | `<prefix>/<vehicle>/state` | the `state` object: energy, margins, raised alerts | 1 | yes | at most once per `state_interval_s` of flight time; at once when an alert is raised or cleared; the last one at the end |
//! | `<prefix>/<vehicle>/alert` | the JSON-lines `alert` object | 1 | no | each raised or cleared event |
//! | `<prefix>/status/<instance>` | `online` / `offline` | 1 | yes | `online` on every (re)connect; `offline` on a clean exit, and as the Last Will when the process dies or its connection drops |
//! | `<prefix>/links/<link>/health` | one link's health (the summary's `links` object: `name`, `frames`, `duplicates`, `rate_hz`, `loss_pct`, `latency_ms`, `last_heard_s`, `live`, and `network` with separate networks) | 1 | yes | with several links (`monitor ADDR ADDR …`, `[[links]]`), every second and once at the end; `<link>` is the address with `/`, `+` and `#` as `_` (`udpin:0.0.0.0:14550`, `serial:_dev_ttyUSB0:57600`) |
//!
//! Payloads are one JSON object each, serialised by [`super::jsonl`] (the same bytes as the
//! `--json` lines, without the newline).
//!
//! **Never a stalled pipeline.** Messages go into rumqttc's bounded request queue (`queue`
//! messages). While the broker is connected and merely slower than the reports, the sink
//! waits up to [`CONNECTED_PATIENCE`] for room (back-pressure, like a slow disk: a
//! flat-out replay loses nothing); while it is not connected, a full queue drops the
//! message at once. Either way a dropped message is counted. The connection is retried
//! with exponential back-off, [`RECONNECT_MIN`] doubling to `reconnect_max_s`. At the end
//! of a run the sink publishes the last state and `offline`, waits for the broker to
//! acknowledge `offline` (so it has read everything before it), disconnects cleanly, and
//! logs its summary: messages published, dropped, and undelivered at exit.
//!
//! Credentials: `username`, and the password from the environment (`password_env` names
//! the variable) or a file (`password_file`, first line), never the command line or the
//! configuration itself. TLS (`tls = true`): rustls with the `ca_file` roots (PEM; default
//! the system bundle), port 8883 unless set.

mod config;
pub use config::MqttSinkConfig;

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result};
use rumqttc::{
    AsyncClient, ConnectionError, Event, EventLoop, LastWill, MqttOptions, Outgoing, Packet, QoS,
    Transport,
};
use tokio::task::JoinHandle;

use crate::features::VehicleClass;
use crate::report::status::IngestStats;
use crate::report::AlertState;

/// First wait before reconnecting; doubles per failure up to `reconnect_max_s`.
pub const RECONNECT_MIN: Duration = Duration::from_millis(500);
/// Longest wait for room in a full queue while the broker is connected.
pub const CONNECTED_PATIENCE: Duration = Duration::from_secs(1);
/// Longest wait at the end of a run for the queue to drain and the clean disconnect.
pub const FLUSH_TIMEOUT: Duration = Duration::from_secs(10);
/// The system-wide CA bundle (Debian, Ubuntu, Alpine): TLS roots when `ca_file` is unset.
pub const SYSTEM_CA_FILE: &str = "/etc/ssl/certs/ca-certificates.crt";
/// `<prefix>/status/<instance>`.
pub fn status_topic(prefix: &str, instance: &str) -> String {
    format!("{prefix}/status/{instance}")
}

/// `<prefix>/links/<link>/health`: `link` as its address reads, with the characters a topic
/// level cannot hold (`/`, `+`, `#`, NUL) as `_`.
pub fn link_topic(prefix: &str, link: &str) -> String {
    let level: String = link
        .chars()
        .map(|c| {
            if matches!(c, '/' | '+' | '#' | '\0') {
                '_'
            } else {
                c
            }
        })
        .collect();
    format!("{prefix}/links/{level}/health")
}

/// `<prefix>/<vehicle>/<kind>`, kind one of `estimate`, `state`, `alert`; the vehicle as
/// [`crate::report::VehicleId`] reads (`7`, or `2:7` on network 2 of separate networks).
pub fn vehicle_topic(prefix: &str, vehicle: crate::report::VehicleId, kind: &str) -> String {
    format!("{prefix}/{vehicle}/{kind}")
}

/// What the sink counted, shared with its connection task.
#[derive(Debug, Default)]
struct Counters {
    /// Messages handed to the queue.
    queued: AtomicU64,
    /// Of those, QoS 1 (acknowledged by the broker).
    queued_qos1: AtomicU64,
    /// Acknowledgements received (PUBACK).
    acked: AtomicU64,
    /// Messages written to the broker's connection.
    published: AtomicU64,
    /// Messages dropped at a full queue.
    dropped: AtomicU64,
    /// `online` announcements queued by the connection task (one per connect).
    announced: AtomicU64,
    /// The broker is connected now.
    connected: AtomicBool,
}

/// Check the configuration, read credentials and TLS roots now (so a bad file fails the
/// run before it starts), then publish on a task until the report channel closes.
pub fn spawn(cfg: MqttSinkConfig, rx: super::ReportRx) -> Result<JoinHandle<Result<()>>> {
    spawn_with_links(cfg, rx, None)
}

/// [`spawn`], also publishing each link's health from `links` (the source's counters:
/// [`IngestStats::links`], filled when it reads several links).
pub fn spawn_with_links(
    cfg: MqttSinkConfig,
    rx: super::ReportRx,
    links: Option<Arc<IngestStats>>,
) -> Result<JoinHandle<Result<()>>> {
    cfg.validate().map_err(anyhow::Error::msg)?;
    let instance = cfg.instance();
    let options = cfg.options(&instance)?;
    let (client, events) = AsyncClient::new(options, cfg.queue);
    let counters = Arc::new(Counters::default());
    let connection = tokio::spawn(drive(
        events,
        client.clone(),
        cfg.clone(),
        instance.clone(),
        counters.clone(),
    ));
    tracing::info!(
        "mqtt: publishing to {}:{} under {}/ as instance {instance}",
        cfg.host,
        cfg.port(),
        cfg.prefix
    );
    Ok(tokio::spawn(publish(
        cfg, instance, client, connection, counters, rx, links,
    )))
}

/// Per vehicle: what the state topic last said and which alerts are raised.
#[derive(Default)]
struct VehicleState {
    last_state_t: Option<f64>,
    active: Vec<String>,
    /// The latest report's state was not published yet.
    pending: Option<((f64, VehicleClass), crate::report::EnergyState)>,
}

/// The report loop: turn each report into messages and queue them.
async fn publish(
    cfg: MqttSinkConfig,
    instance: String,
    client: AsyncClient,
    connection: JoinHandle<()>,
    counters: Arc<Counters>,
    mut rx: super::ReportRx,
    links: Option<Arc<IngestStats>>,
) -> Result<()> {
    let queue = Queue {
        client: client.clone(),
        counters: counters.clone(),
    };
    let mut vehicles: std::collections::BTreeMap<crate::report::VehicleId, VehicleState> =
        Default::default();
    let mut buf = Vec::with_capacity(1024);
    let mut health = tokio::time::interval(Duration::from_secs(1));
    health.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        let r = tokio::select! {
            r = rx.next() => match r {
                Some(r) => r,
                None => break,
            },
            _ = health.tick() => {
                put_links(&queue, &cfg.prefix, links.as_deref()).await?;
                continue;
            }
        };
        let v = vehicles.entry(r.vehicle).or_default();
        buf.clear();
        super::jsonl::write_estimate(&mut buf, &r)?;
        queue
            .put(
                vehicle_topic(&cfg.prefix, r.vehicle, "estimate"),
                QoS::AtMostOnce,
                false,
                line(&buf),
            )
            .await;
        for a in &r.alerts {
            buf.clear();
            super::jsonl::write_alert(&mut buf, r.vehicle, a)?;
            queue
                .put(
                    vehicle_topic(&cfg.prefix, r.vehicle, "alert"),
                    QoS::AtLeastOnce,
                    false,
                    line(&buf),
                )
                .await;
            v.active.retain(|rule| rule != &a.rule);
            if a.state == AlertState::Raised {
                v.active.push(a.rule.clone());
            }
        }
        let t = r.estimate.t_s;
        let class = r.estimate.sample.vehicle.class;
        let due = match v.last_state_t {
            None => true,
            Some(last) => !r.alerts.is_empty() || t - last >= cfg.state_interval_s || t < last,
        };
        if due {
            v.last_state_t = Some(t);
            v.pending = None;
            put_state(
                &queue,
                &cfg.prefix,
                r.vehicle,
                (t, class),
                &r.energy,
                &v.active,
                &mut buf,
            )
            .await?;
        } else {
            v.pending = Some(((t, class), r.energy.clone()));
        }
    }
    // The run is over: the last state of every vehicle and link, then `offline`, then a
    // clean disconnect (after everything queued before it).
    for (id, v) in &vehicles {
        if let Some((t, energy)) = &v.pending {
            put_state(&queue, &cfg.prefix, *id, *t, energy, &v.active, &mut buf).await?;
        }
    }
    put_links(&queue, &cfg.prefix, links.as_deref()).await?;
    queue
        .put(
            status_topic(&cfg.prefix, &instance),
            QoS::AtLeastOnce,
            true,
            b"offline".to_vec(),
        )
        .await;
    // Disconnect only once the broker has acknowledged the last QoS 1 message (`offline`,
    // so everything before it too): closing a socket with acknowledgements still unread
    // resets the connection, and the broker then discards what it had not yet read.
    let load = |c: &AtomicU64| c.load(Ordering::Relaxed);
    let flushed = tokio::time::timeout(FLUSH_TIMEOUT, async {
        while load(&counters.acked) < load(&counters.queued_qos1) + load(&counters.announced) {
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
        let _ = client.disconnect().await;
        connection.await
    })
    .await;
    if flushed.is_err() {
        tracing::warn!("mqtt: {}:{}: could not deliver everything within {FLUSH_TIMEOUT:?} of the end; giving up", cfg.host, cfg.port());
    }
    let (published, dropped) = (load(&counters.published), load(&counters.dropped));
    let undelivered =
        (load(&counters.queued) + load(&counters.announced)).saturating_sub(published);
    tracing::info!(
        "mqtt summary: {published} messages published, {dropped} dropped (queue full), {undelivered} undelivered at exit, {} reports missed",
        rx.missed()
    );
    Ok(())
}

/// A payload: a JSON line without its newline.
fn line(buf: &[u8]) -> Vec<u8> {
    buf.strip_suffix(b"\n").unwrap_or(buf).to_vec()
}

/// Every link's health, retained (nothing with one link).
async fn put_links(queue: &Queue, prefix: &str, stats: Option<&IngestStats>) -> Result<()> {
    for l in stats.map(IngestStats::links).unwrap_or_default() {
        queue
            .put(
                link_topic(prefix, &l.name),
                QoS::AtLeastOnce,
                true,
                serde_json::to_vec(&l)?,
            )
            .await;
    }
    Ok(())
}

async fn put_state(
    queue: &Queue,
    prefix: &str,
    id: crate::report::VehicleId,
    (t, class): (f64, VehicleClass),
    energy: &crate::report::EnergyState,
    active: &[String],
    buf: &mut Vec<u8>,
) -> Result<()> {
    buf.clear();
    super::jsonl::write_state(buf, t, class, energy, active)?;
    queue
        .put(
            vehicle_topic(prefix, id, "state"),
            QoS::AtLeastOnce,
            true,
            line(buf),
        )
        .await;
    Ok(())
}

/// The bounded queue to the broker, with the drop rule of the module docs.
struct Queue {
    client: AsyncClient,
    counters: Arc<Counters>,
}

impl Queue {
    async fn put(&self, topic: String, qos: QoS, retain: bool, payload: Vec<u8>) {
        let c = &self.counters;
        let sent = match self
            .client
            .try_publish(topic.clone(), qos, retain, payload.clone())
        {
            Ok(()) => true,
            // Full while connected: the broker is draining it, wait a little for room.
            Err(rumqttc::ClientError::TryRequest(_)) if c.connected.load(Ordering::Relaxed) => {
                matches!(
                    tokio::time::timeout(
                        CONNECTED_PATIENCE,
                        self.client.publish(topic, qos, retain, payload)
                    )
                    .await,
                    Ok(Ok(()))
                )
            }
            Err(_) => false,
        };
        if sent {
            c.queued.fetch_add(1, Ordering::Relaxed);
            if qos == QoS::AtLeastOnce {
                c.queued_qos1.fetch_add(1, Ordering::Relaxed);
            }
        } else {
            let n = c.dropped.fetch_add(1, Ordering::Relaxed) + 1;
            if n.is_power_of_two() {
                tracing::warn!("mqtt: queue full, message dropped ({n} so far)");
            }
        }
    }
}

/// The connection task: polls rumqttc's event loop (which connects, reconnects on the
/// next poll after an error, and writes the queue out), announces `online` on every
/// connect, counts what it writes, and backs off between failed attempts. Ends after the
/// clean disconnect, or when every client handle is gone.
async fn drive(
    mut events: EventLoop,
    client: AsyncClient,
    cfg: MqttSinkConfig,
    instance: String,
    counters: Arc<Counters>,
) {
    let status = status_topic(&cfg.prefix, &instance);
    let max = Duration::from_secs_f64(cfg.reconnect_max_s);
    let mut backoff = RECONNECT_MIN;
    let mut failures = 0u64;
    loop {
        match events.poll().await {
            Ok(Event::Incoming(Packet::ConnAck(_))) => {
                counters.connected.store(true, Ordering::Relaxed);
                if failures > 0 {
                    tracing::info!(
                        "mqtt: reconnected to {}:{} after {failures} failed attempt(s)",
                        cfg.host,
                        cfg.port()
                    );
                }
                backoff = RECONNECT_MIN;
                failures = 0;
                // After every (re)connect: a dropped connection set it `offline` (the Will).
                if client
                    .try_publish(status.clone(), QoS::AtLeastOnce, true, "online")
                    .is_ok()
                {
                    counters.announced.fetch_add(1, Ordering::Relaxed);
                } else {
                    // The queue is full: announce as soon as there is room.
                    let (c, s, n) = (client.clone(), status.clone(), counters.clone());
                    tokio::spawn(async move {
                        if c.publish(s, QoS::AtLeastOnce, true, "online").await.is_ok() {
                            n.announced.fetch_add(1, Ordering::Relaxed);
                        }
                    });
                }
            }
            Ok(Event::Outgoing(Outgoing::Publish(_))) => {
                counters.published.fetch_add(1, Ordering::Relaxed);
            }
            Ok(Event::Incoming(Packet::PubAck(_))) => {
                counters.acked.fetch_add(1, Ordering::Relaxed);
            }
            Ok(Event::Outgoing(Outgoing::Disconnect)) => break,
            Ok(_) => {}
            Err(ConnectionError::RequestsDone) => break,
            Err(e) => {
                counters.connected.store(false, Ordering::Relaxed);
                failures += 1;
                // The first failure and then every tenth: a broker down for an hour should
                // not fill the log.
                if failures == 1 || failures.is_multiple_of(10) {
                    tracing::warn!(
                        "mqtt: {}:{}: {e} (attempt {failures}); retrying in {backoff:?}",
                        cfg.host,
                        cfg.port()
                    );
                }
                tokio::time::sleep(backoff).await;
                backoff = (backoff * 2).min(max);
            }
        }
    }
    counters.connected.store(false, Ordering::Relaxed);
}

#[cfg(test)]
mod tests;
