//! The web dashboard: one self-contained page (`web/index.html`, inline JS and CSS, charts
//! drawn on a canvas, nothing fetched from anywhere else) that polls a JSON endpoint.
//!
//! - `GET /` — the page, led by what the pilot must act on: a banner for the most severe
//!   alert standing (red for critical), then the time left (to the first of empty and low
//!   voltage), the state of charge with its source, the voltage and its forecast minimum,
//!   the mission margin and the power, the alert log and measured power against the
//!   forecast. Behind the "every model" toggle: each model's power (table and chart),
//!   remaining energy and time to empty over time, the home margin, the pack model, the
//!   mission (energy left, item, progress, margin, and a map of the planned route with the
//!   part flown) when one is known.
//! - `GET /api/state?since=N&vehicle=V` — `{"vehicle", "seq", "models", "latest", "points",
//!   "alerts", "fleet"}`: for vehicle `V` (MAVLink system id; default the lowest heard),
//!   the points with sequence number above `N` (so a poll sends only what is new), the
//!   last report's numbers (`latest`, with `latest.pilot`: [`super::pilot::PilotView`])
//!   and its whole alert log; and `fleet`, one row per vehicle
//!   (`system_id`, `t`, `measured_w`, `forecast_w`, `remaining_wh`, `time_to_empty_s`,
//!   `home_margin_wh`, `worst`: the most severe alert standing). With more than one
//!   vehicle the page shows that table above the charts; a click selects the vehicle.
//!   Where the links are separate networks a vehicle is `"N:SYSID"` (a string) in
//!   `vehicle`, `system_id` and the `vehicle=` parameter ([`crate::report::VehicleId`]).
//!   `links`: each link's health when the source reads several (the summary's `links`
//!   objects; empty otherwise), shown as a small table of links.
//!
//! Bound to `127.0.0.1:8787` unless `[sinks.web] bind` says otherwise: a dashboard of the
//! vehicle's battery is nobody else's business until you choose so. The history keeps one
//! point per `min_step_s` of flight time, at most `history` points, so memory stays flat on
//! a long flight.
//!
//! ## Guarded ([`guard`])
//!
//! - **A token beyond loopback.** Bound to anything but a loopback address, the dashboard
//!   refuses to start without an access token: `DRONEWATT_WEB_TOKEN` from the environment,
//!   else the file `[sinks.web] token_file` names (mode 600, whitespace trimmed; never the
//!   command line, where `ps` shows it to every user). At least [`MIN_TOKEN_LEN`]
//!   characters. With a token (on loopback too, if one is set) `/api/*` answers 401 unless
//!   the request carries `Authorization: Bearer TOKEN`; the page itself holds no data. Open
//!   the dashboard as `http://HOST:PORT/#token=TOKEN`: the fragment never leaves the
//!   browser, and the page sends it as that header.
//! - **Read only.** There is no write endpoint: every route is GET (HEAD), anything else is
//!   405, and a request with a body is 413.
//! - **Headers.** Every response: a Content-Security-Policy that allows only this page's own
//!   script and style (by SHA-256 hash) and fetches from its own origin, no framing,
//!   `X-Content-Type-Options: nosniff`, `Referrer-Policy: no-referrer`, `Cache-Control:
//!   no-store`.
//! - **Limits.** At most `max_connections` open connections (more wait in the kernel's
//!   backlog until one closes); a connection idle (nothing read or written) for
//!   [`IDLE_TIMEOUT`] is closed; request line plus headers over `max_request_bytes` is 431.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

use anyhow::{Context, Result};
use axum::extract::{Query, State};
use axum::response::{Html, IntoResponse};
use axum::routing::get;
use axum::{Json, Router};
use tokio_util::sync::CancellationToken;

pub mod feed;
pub mod guard;

use crate::report::AlertEvent;
use crate::report::{EnergyState, Report};

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
    /// File holding the access token (mode 600; a relative path is resolved against the
    /// config file's folder). `DRONEWATT_WEB_TOKEN` in the environment takes precedence.
    /// Required when `bind` is not a loopback address. Default: none.
    pub token_file: Option<std::path::PathBuf>,
    /// Most connections open at once. Default 16.
    pub max_connections: usize,
    /// Largest request line plus headers, bytes. Default 8192.
    pub max_request_bytes: usize,
}

impl Default for WebSinkConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            bind: "127.0.0.1:8787".into(),
            history: 3600,
            min_step_s: 0.5,
            linger_s: 0.0,
            token_file: None,
            max_connections: 16,
            max_request_bytes: 8192,
        }
    }
}

impl WebSinkConfig {
    /// Range checks; each message names the key (several errors: one per line).
    pub fn validate(&self) -> Result<(), String> {
        let mut errs = crate::validate::Errors::new();
        if self.bind.parse::<std::net::SocketAddr>().is_err() {
            errs.push(format!(
                "sinks.web.bind = '{}': expected IP:PORT, e.g. 127.0.0.1:8787",
                self.bind
            ));
        }
        errs.range("sinks.web.history", self.history, 10..=1_000_000, "points");
        errs.range("sinks.web.min_step_s", self.min_step_s, 0.0.., "s");
        errs.range("sinks.web.linger_s", self.linger_s, 0.0.., "s");
        errs.range(
            "sinks.web.max_connections",
            self.max_connections,
            1..=10_000,
            "",
        );
        errs.range(
            "sinks.web.max_request_bytes",
            self.max_request_bytes,
            1024..=1_048_576,
            "bytes",
        );
        errs.into_result()
    }

    /// The access token: `DRONEWATT_WEB_TOKEN`, else `token_file`, else none. Refuses to
    /// go without one when `bind` is beyond loopback. Errors name the variable or key.
    pub fn token(&self) -> Result<Option<String>, String> {
        let token = match std::env::var(TOKEN_ENV) {
            Ok(t) if !t.trim().is_empty() => Some((t.trim().to_string(), TOKEN_ENV.to_string())),
            _ => match &self.token_file {
                Some(p) => {
                    let key = format!("sinks.web.token_file = '{}'", p.display());
                    Some((
                        guard::read_private(p).map_err(|e| format!("{key}: {e}"))?,
                        key,
                    ))
                }
                None => None,
            },
        };
        if let Some((t, from)) = &token {
            if t.chars().count() < MIN_TOKEN_LEN || t.chars().any(|c| c.is_control() || c == ' ') {
                return Err(format!("{from}: the dashboard token must be at least {MIN_TOKEN_LEN} characters, no spaces"));
            }
        }
        let loopback = self
            .bind
            .parse::<std::net::SocketAddr>()
            .is_ok_and(|a| a.ip().is_loopback());
        if token.is_none() && !loopback {
            return Err(format!(
                "sinks.web.bind = '{}' is beyond loopback: the dashboard needs an access token ({TOKEN_ENV} in the environment, or sinks.web.token_file)",
                self.bind
            ));
        }
        Ok(token.map(|(t, _)| t))
    }
}

/// Environment variable holding the dashboard's access token.
pub const TOKEN_ENV: &str = "DRONEWATT_WEB_TOKEN";
/// Shortest token accepted, characters.
pub const MIN_TOKEN_LEN: usize = 16;
/// A connection with nothing read or written for this long is closed.
pub const IDLE_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(10);

/// One chart point.
#[derive(Debug, Clone, serde::Serialize)]
struct Point {
    seq: u64,
    t: f64,
    measured_w: Option<f32>,
    /// The smoothed power the forecast assumes, W.
    forecast_w: Option<f64>,
    /// Watts per model, in the order of `models`.
    models: Vec<Option<f32>>,
    remaining_wh: Option<f64>,
    time_to_empty_s: Option<f64>,
    home_margin_wh: Option<f64>,
    /// Remaining − rest of the mission − reserve, while a mission is known.
    mission_margin_wh: Option<f64>,
    /// The pack (the voltage plot): measured and modelled loaded voltage, the lowest
    /// forecast loaded voltage and the low threshold, V.
    battery_v: Option<f64>,
    battery_v_model: Option<f64>,
    v_min_forecast_v: Option<f64>,
    low_threshold_v: Option<f64>,
}

#[derive(Debug, Default)]
struct Dash {
    seq: u64,
    models: Vec<String>,
    points: VecDeque<Point>,
    alerts: VecDeque<AlertEvent>,
    latest: Option<Latest>,
    /// Alerts raised and not cleared: rule → severity.
    active: std::collections::BTreeMap<String, crate::report::Severity>,
    /// Their messages and times as raised: rule → (message, t) (the banner's words).
    messages: std::collections::BTreeMap<String, (String, f64)>,
}

/// One vehicle's row of the fleet table.
#[derive(Debug, Clone, serde::Serialize)]
struct FleetRow {
    /// The vehicle: its system id, or `"2:7"` on network 2 of separate networks.
    system_id: crate::report::VehicleId,
    t: f64,
    /// The vehicle's kind in words (`multirotor`, `vtol (fw)`, …).
    vehicle: String,
    measured_w: Option<f32>,
    forecast_w: Option<f64>,
    remaining_wh: Option<f64>,
    time_to_empty_s: Option<f64>,
    home_margin_wh: Option<f64>,
    /// The most severe alert standing: (rule, severity).
    worst: Option<(String, crate::report::Severity)>,
}

/// Every vehicle's dashboard, by system id.
#[derive(Debug, Default)]
struct Fleet {
    vehicles: std::collections::BTreeMap<crate::report::VehicleId, Dash>,
}

impl Fleet {
    fn add(&mut self, r: &Report, cfg: &WebSinkConfig) {
        let dropped = r
            .alerts
            .iter()
            .any(|a| a.rule == "vehicle_dropped" && a.state == crate::report::AlertState::Raised);
        if dropped {
            self.vehicles.remove(&r.vehicle);
        } else {
            self.vehicles.entry(r.vehicle).or_default().add(r, cfg);
        }
    }

    fn rows(&self) -> Vec<FleetRow> {
        self.vehicles
            .iter()
            .filter_map(|(&system_id, d)| {
                let l = d.latest.as_ref()?;
                Some(FleetRow {
                    system_id,
                    t: l.t,
                    vehicle: l.vehicle.clone(),
                    measured_w: l.measured_w,
                    forecast_w: l.energy.forecast_w,
                    remaining_wh: l.energy.remaining_wh,
                    time_to_empty_s: l.energy.time_to_empty_s,
                    home_margin_wh: l.energy.home_margin_wh,
                    // Severity orders most severe first.
                    worst: d
                        .active
                        .iter()
                        .min_by_key(|(_, &s)| s)
                        .map(|(r, &s)| (r.clone(), s)),
                })
            })
            .collect()
    }
}

#[derive(Debug, Clone, serde::Serialize)]
struct Latest {
    t: f64,
    /// The vehicle class (`multirotor`, `fixed_wing`, `vtol`, `other`) and, in words, the
    /// kind (`vtol (fw)`, `other: SUBMARINE (12)`).
    vehicle_class: crate::features::VehicleClass,
    vehicle: String,
    measured_w: Option<f32>,
    models: Vec<crate::report::ModelEstimate>,
    energy: EnergyState,
    /// The planned route (east/north of home, m) and the point the vehicle is at, while a
    /// mission is known.
    route: Option<RouteView>,
    /// What the pilot must act on (the banner and the first cards): the same figures as
    /// the terminal's line and the screen's tiles ([`super::pilot`]).
    pilot: super::pilot::PilotView,
}

#[derive(Debug, Clone, serde::Serialize)]
struct RouteView {
    points: Vec<[f32; 2]>,
    at: usize,
}

const MAX_ALERTS: usize = 500;

impl Dash {
    /// Log an alert event and keep the alerts standing.
    fn record(&mut self, a: &AlertEvent) {
        if self.alerts.len() == MAX_ALERTS {
            self.alerts.pop_front();
        }
        self.alerts.push_back(a.clone());
        match a.state {
            crate::report::AlertState::Raised => {
                self.active.insert(a.rule.clone(), a.severity);
                self.messages
                    .insert(a.rule.clone(), (a.message.clone(), a.t));
            }
            crate::report::AlertState::Cleared => {
                self.active.remove(&a.rule);
                self.messages.remove(&a.rule);
            }
        };
    }

    /// The most severe alert standing, for the banner.
    fn worst(&self) -> Option<super::pilot::WorstAlert> {
        super::pilot::worst_of(&self.active, |rule| self.messages.get(rule).cloned())
    }

    fn add(&mut self, r: &Report, cfg: &WebSinkConfig) {
        for a in &r.alerts {
            self.record(a);
        }
        let worst = self.worst();
        let est = &r.estimate;
        self.latest = Some(Latest {
            t: est.t_s,
            vehicle_class: est.sample.vehicle.class,
            vehicle: est.sample.vehicle.describe(),
            measured_w: est.sample.measured_w,
            models: est.models.clone(),
            energy: r.energy.clone(),
            route: r.energy.mission.as_ref().map(|m| RouteView {
                points: m.route_en_m.to_vec(),
                at: m.route_at,
            }),
            pilot: super::pilot::PilotView::of(r, worst),
        });
        let due = self
            .points
            .back()
            .is_none_or(|p| est.t_s - p.t >= cfg.min_step_s || est.t_s < p.t);
        if !due && r.alerts.is_empty() {
            return;
        }
        for m in &est.models {
            if !self.models.contains(&m.name) {
                self.models.push(m.name.clone());
            }
        }
        self.seq += 1;
        let models = self
            .models
            .iter()
            .map(|n| est.models.iter().find(|m| &m.name == n).map(|m| m.power_w))
            .collect();
        if self.points.len() >= cfg.history {
            self.points.pop_front();
        }
        self.points.push_back(Point {
            seq: self.seq,
            t: est.t_s,
            measured_w: est.sample.measured_w,
            forecast_w: r.energy.forecast_w,
            models,
            remaining_wh: r.energy.remaining_wh,
            time_to_empty_s: r.energy.time_to_empty_s,
            home_margin_wh: r.energy.home_margin_wh,
            mission_margin_wh: r.energy.mission_margin_wh,
            battery_v: r.energy.pack.battery_v,
            battery_v_model: r.energy.pack.battery_v_model,
            v_min_forecast_v: r.energy.pack.v_min_forecast_v,
            low_threshold_v: r.energy.pack.low_threshold_v,
        });
    }
}

type Shared = Arc<Mutex<Fleet>>;

/// What the state endpoint reads: the dashboards, and the source's counters (each link's
/// health), when the run has a source.
#[derive(Clone)]
struct Served {
    dash: Shared,
    stats: Option<Arc<crate::report::status::IngestStats>>,
}

#[derive(serde::Deserialize)]
struct Since {
    since: Option<u64>,
    /// `7`, or `2:7` on network 2 (a vehicle that does not parse: the default).
    vehicle: Option<String>,
}

async fn index() -> impl IntoResponse {
    Html(include_str!("index.html"))
}

async fn state(State(served): State<Served>, Query(q): Query<Since>) -> impl IntoResponse {
    let since = q.since.unwrap_or(0);
    let links = served.stats.as_ref().map(|s| s.links()).unwrap_or_default();
    let dash = served.dash;
    let empty = Dash::default();
    let body = match dash.lock() {
        Ok(f) => {
            // The vehicle asked for, else the lowest heard (a dropped one: the lowest left).
            let (vehicle, d) = q
                .vehicle
                .and_then(|v| v.parse::<crate::report::VehicleId>().ok())
                .and_then(|v| f.vehicles.get_key_value(&v))
                .or_else(|| f.vehicles.iter().next())
                .map_or((None, &empty), |(&v, d)| (Some(v), d));
            serde_json::json!({
                "vehicle": vehicle,
                "seq": d.seq,
                "models": d.models,
                "latest": d.latest,
                "points": d.points.iter().filter(|p| p.seq > since).collect::<Vec<_>>(),
                "alerts": d.alerts,
                "fleet": f.rows(),
                "links": links,
            })
        }
        Err(_) => serde_json::json!({"error": "dashboard state unavailable"}),
    };
    Json(body)
}

/// Bind the configured address now (so a taken port fails the run before it starts),
/// then serve on a task (see [`serve`]).
pub fn spawn(
    cfg: WebSinkConfig,
    rx: super::ReportRx,
    shutdown: CancellationToken,
    stats: Arc<crate::report::status::IngestStats>,
) -> Result<tokio::task::JoinHandle<Result<()>>> {
    cfg.validate().map_err(anyhow::Error::msg)?;
    // Before binding: a public dashboard without a token never listens at all.
    cfg.token().map_err(anyhow::Error::msg)?;
    let bind_err = || {
        format!(
            "web dashboard: cannot listen on {} (sinks.web.bind)",
            cfg.bind
        )
    };
    let std_listener = std::net::TcpListener::bind(&cfg.bind).with_context(bind_err)?;
    std_listener.set_nonblocking(true).with_context(bind_err)?;
    let listener = tokio::net::TcpListener::from_std(std_listener).with_context(bind_err)?;
    tracing::info!(
        "web dashboard on http://{}/",
        listener
            .local_addr()
            .map_or(cfg.bind.clone(), |a| a.to_string())
    );
    Ok(tokio::spawn(serve_with_links(
        cfg,
        listener,
        rx,
        shutdown,
        Some(stats),
    )))
}

/// Serve the dashboard on `listener`, fed by `rx`, until the report channel closes and
/// `linger_s` has passed, or the run's `shutdown` (Ctrl-C, SIGTERM) ends the lingering.
pub async fn serve(
    cfg: WebSinkConfig,
    listener: tokio::net::TcpListener,
    rx: super::ReportRx,
    shutdown: CancellationToken,
) -> Result<()> {
    serve_with_links(cfg, listener, rx, shutdown, None).await
}

/// [`serve`], with each link's health from `stats` (the source's counters) on the page.
pub async fn serve_with_links(
    cfg: WebSinkConfig,
    listener: tokio::net::TcpListener,
    mut rx: super::ReportRx,
    shutdown: CancellationToken,
    stats: Option<Arc<crate::report::status::IngestStats>>,
) -> Result<()> {
    let fed = cfg.clone();
    serve_fed(
        cfg,
        listener,
        shutdown,
        stats,
        move |dash: Shared| async move {
            while let Some(r) = rx.next().await {
                if let Ok(mut d) = dash.lock() {
                    d.add(&r, &fed);
                }
            }
        },
    )
    .await
}

/// Serve the dashboard on `listener` while `feed` fills it, then `linger_s` more (or until
/// `shutdown`).
async fn serve_fed<F: std::future::Future<Output = ()>>(
    cfg: WebSinkConfig,
    listener: tokio::net::TcpListener,
    shutdown: CancellationToken,
    stats: Option<Arc<crate::report::status::IngestStats>>,
    feed: impl FnOnce(Shared) -> F,
) -> Result<()> {
    let token = cfg.token().map_err(anyhow::Error::msg)?;
    let dash: Shared = Arc::default();
    let rules = Arc::new(guard::Rules::new(
        token,
        cfg.max_request_bytes,
        include_str!("index.html"),
    ));
    let app = Router::new()
        .route("/", get(index))
        .route("/api/state", get(state))
        .with_state(Served {
            dash: dash.clone(),
            stats,
        })
        .layer(axum::middleware::from_fn_with_state(rules, guard::check));
    let listener = guard::Limited::new(listener, cfg.max_connections);
    let done = tokio_util::sync::CancellationToken::new();
    let stop = done.clone();
    let server = tokio::spawn(async move {
        axum::serve(listener, app)
            .with_graceful_shutdown(async move { stop.cancelled().await })
            .await
    });
    feed(dash).await;
    if cfg.linger_s > 0.0 {
        tracing::info!(
            "web dashboard: source ended; serving {} s more (Ctrl-C ends it)",
            cfg.linger_s
        );
        tokio::select! {
            _ = tokio::time::sleep(std::time::Duration::from_secs_f64(cfg.linger_s)) => {}
            _ = shutdown.cancelled() => {}
        }
    }
    done.cancel();
    // A browser holding a connection open must not keep the run from ending.
    match tokio::time::timeout(std::time::Duration::from_secs(2), server).await {
        Ok(r) => r
            .context("web dashboard task")?
            .context("web dashboard server")?,
        Err(_) => tracing::debug!("web dashboard: connections still open at shutdown; closed"),
    }
    Ok(())
}
