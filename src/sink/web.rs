//! The web dashboard: one self-contained page (`web/index.html`, inline JS and CSS, charts
//! drawn on a canvas, nothing fetched from anywhere else) that polls a JSON endpoint.
//!
//! - `GET /` — the page: measured power against every model, remaining energy and time to
//!   empty, the home margin, and the alert log.
//! - `GET /api/state?since=N` — `{"seq", "models", "latest", "points", "alerts"}`: the
//!   points with sequence number above `N` (so a poll sends only what is new), the last
//!   report's numbers and the whole alert log.
//!
//! Bound to `127.0.0.1:8787` unless `[sinks.web] bind` says otherwise: a dashboard of the
//! vehicle's battery is nobody else's business until you choose so. The history keeps one
//! point per `min_step_s` of flight time, at most `history` points, so memory stays flat on
//! a long flight.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

use anyhow::{Context, Result};
use axum::extract::{Query, State};
use axum::response::{Html, IntoResponse};
use axum::routing::get;
use axum::{Json, Router};
use tokio::sync::broadcast;

use crate::alert::AlertEvent;
use crate::energy::{EnergyState, Report};

/// The `[sinks.web]` table.
#[derive(Debug, Clone, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct WebSinkConfig {
    /// On or off. Default off.
    pub enabled: bool,
    /// Address to listen on. Default `127.0.0.1:8787` (loopback only).
    pub bind: String,
    /// Most points kept for the charts. Default 3600.
    pub history: usize,
    /// Least flight time between two kept points, s. Default 0.5.
    pub min_step_s: f64,
    /// Keep serving this long after the source ends (a replay), s, so the page can still
    /// be read. Default 0.
    pub linger_s: f64,
}

impl Default for WebSinkConfig {
    fn default() -> Self {
        Self { enabled: false, bind: "127.0.0.1:8787".into(), history: 3600, min_step_s: 0.5, linger_s: 0.0 }
    }
}

impl WebSinkConfig {
    /// Range checks; each message names the key (several errors: one per line).
    pub fn validate(&self) -> Result<(), String> {
        let mut errs = Vec::new();
        if self.bind.parse::<std::net::SocketAddr>().is_err() {
            errs.push(format!("sinks.web.bind = '{}': expected IP:PORT, e.g. 127.0.0.1:8787", self.bind));
        }
        if !(10..=1_000_000).contains(&self.history) {
            errs.push(format!("sinks.web.history = {}: must be 10..=1000000 points", self.history));
        }
        if !(self.min_step_s.is_finite() && self.min_step_s >= 0.0) {
            errs.push(format!("sinks.web.min_step_s = {}: must be ≥ 0", self.min_step_s));
        }
        if !(self.linger_s.is_finite() && self.linger_s >= 0.0) {
            errs.push(format!("sinks.web.linger_s = {}: must be ≥ 0", self.linger_s));
        }
        if errs.is_empty() { Ok(()) } else { Err(errs.join("\n")) }
    }
}

/// One chart point.
#[derive(Debug, Clone, serde::Serialize)]
struct Point {
    seq: u64,
    t: f64,
    measured_w: Option<f32>,
    /// Watts per model, in the order of `models`.
    models: Vec<Option<f32>>,
    remaining_wh: Option<f64>,
    time_to_empty_s: Option<f64>,
    home_margin_wh: Option<f64>,
}

#[derive(Debug, Default)]
struct Dash {
    seq: u64,
    models: Vec<String>,
    points: VecDeque<Point>,
    alerts: VecDeque<AlertEvent>,
    latest: Option<Latest>,
}

#[derive(Debug, Clone, serde::Serialize)]
struct Latest {
    t: f64,
    measured_w: Option<f32>,
    models: Vec<crate::model::ModelEstimate>,
    energy: EnergyState,
}

const MAX_ALERTS: usize = 500;

impl Dash {
    fn add(&mut self, r: &Report, cfg: &WebSinkConfig) {
        for a in &r.alerts {
            if self.alerts.len() == MAX_ALERTS {
                self.alerts.pop_front();
            }
            self.alerts.push_back(a.clone());
        }
        let est = &r.estimate;
        self.latest = Some(Latest {
            t: est.t_s,
            measured_w: est.sample.measured_w,
            models: est.models.clone(),
            energy: r.energy.clone(),
        });
        let due = self.points.back().is_none_or(|p| est.t_s - p.t >= cfg.min_step_s || est.t_s < p.t);
        if !due && r.alerts.is_empty() {
            return;
        }
        for m in &est.models {
            if !self.models.contains(&m.name) {
                self.models.push(m.name.clone());
            }
        }
        self.seq += 1;
        let models = self.models.iter().map(|n| est.models.iter().find(|m| &m.name == n).map(|m| m.power_w)).collect();
        if self.points.len() >= cfg.history {
            self.points.pop_front();
        }
        self.points.push_back(Point {
            seq: self.seq,
            t: est.t_s,
            measured_w: est.sample.measured_w,
            models,
            remaining_wh: r.energy.remaining_wh,
            time_to_empty_s: r.energy.time_to_empty_s,
            home_margin_wh: r.energy.home_margin_wh,
        });
    }
}

type Shared = Arc<Mutex<Dash>>;

#[derive(serde::Deserialize)]
struct Since {
    since: Option<u64>,
}

async fn index() -> impl IntoResponse {
    Html(include_str!("web/index.html"))
}

async fn state(State(dash): State<Shared>, Query(q): Query<Since>) -> impl IntoResponse {
    let since = q.since.unwrap_or(0);
    let body = match dash.lock() {
        Ok(d) => serde_json::json!({
            "seq": d.seq,
            "models": d.models,
            "latest": d.latest,
            "points": d.points.iter().filter(|p| p.seq > since).collect::<Vec<_>>(),
            "alerts": d.alerts,
        }),
        Err(_) => serde_json::json!({"error": "dashboard state unavailable"}),
    };
    Json(body)
}

/// Bind the configured address now (so a taken port fails the run before it starts),
/// then serve on a task (see [`serve`]).
pub fn spawn(cfg: WebSinkConfig, rx: broadcast::Receiver<Arc<Report>>) -> Result<tokio::task::JoinHandle<Result<()>>> {
    cfg.validate().map_err(anyhow::Error::msg)?;
    let bind_err = || format!("web dashboard: cannot listen on {} (sinks.web.bind)", cfg.bind);
    let std_listener = std::net::TcpListener::bind(&cfg.bind).with_context(bind_err)?;
    std_listener.set_nonblocking(true).with_context(bind_err)?;
    let listener = tokio::net::TcpListener::from_std(std_listener).with_context(bind_err)?;
    tracing::info!("web dashboard on http://{}/", listener.local_addr().map_or(cfg.bind.clone(), |a| a.to_string()));
    Ok(tokio::spawn(serve(cfg, listener, rx)))
}

/// Ctrl-C or SIGTERM: what ends a lingering dashboard early.
async fn stop_signal() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{signal, SignalKind};
        if let Ok(mut term) = signal(SignalKind::terminate()) {
            tokio::select! {
                _ = tokio::signal::ctrl_c() => {}
                _ = term.recv() => {}
            }
            return;
        }
    }
    let _ = tokio::signal::ctrl_c().await;
}

/// Serve the dashboard on `listener`, fed by `rx`, until the report channel closes and
/// `linger_s` has passed.
pub async fn serve(cfg: WebSinkConfig, listener: tokio::net::TcpListener, mut rx: broadcast::Receiver<Arc<Report>>) -> Result<()> {
    let dash: Shared = Arc::default();
    let app = Router::new().route("/", get(index)).route("/api/state", get(state)).with_state(dash.clone());
    let done = tokio_util::sync::CancellationToken::new();
    let stop = done.clone();
    let server = tokio::spawn(async move {
        axum::serve(listener, app).with_graceful_shutdown(async move { stop.cancelled().await }).await
    });
    let mut missed = 0;
    while let Some(r) = super::next_report(&mut rx, &mut missed).await {
        if let Ok(mut d) = dash.lock() {
            d.add(&r, &cfg);
        }
    }
    if cfg.linger_s > 0.0 {
        tracing::info!("web dashboard: source ended; serving {} s more (Ctrl-C ends it)", cfg.linger_s);
        tokio::select! {
            _ = tokio::time::sleep(std::time::Duration::from_secs_f64(cfg.linger_s)) => {}
            _ = stop_signal() => {}
        }
    }
    done.cancel();
    // A browser holding a connection open must not keep the run from ending.
    match tokio::time::timeout(std::time::Duration::from_secs(2), server).await {
        Ok(r) => r.context("web dashboard task")?.context("web dashboard server")?,
        Err(_) => tracing::debug!("web dashboard: connections still open at shutdown; closed"),
    }
    Ok(())
}
