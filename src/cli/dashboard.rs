//! `dronewatt dashboard --nats URL`: the web dashboard of the whole fleet, read off NATS as
//! a viewer. It subscribes to the workers' `dronewatt.estimates.>` and `dronewatt.alerts.>`
//! (what the shipped server config lets the `viewer` user read, and nothing more: no lease,
//! no stream), reads each line back ([`crate::sink::jsonl_read`]) and serves the very page
//! and `/api/state` a monitor's `[sinks.web]` serves ([`crate::sink::web::feed`]), with its
//! guards (a token beyond loopback, read only, the connection limits). Every vehicle of
//! the fleet is there, whichever worker holds it; after a takeover the new holder's
//! estimates go on under the same vehicle (its replay of what the old holder already
//! published is held back, so nothing is shown twice).

use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

use anyhow::{Context as _, Result};
use futures_util::StreamExt;
use tokio::sync::mpsc;

use crate::sink::jsonl_read::{self, Line};
use crate::sink::web::feed::Feed;
use crate::sink::web::WebSinkConfig;
use crate::source::nats::publish::{ALERTS, ESTIMATES};
use crate::source::nats::NatsArgs;

/// Lines that did not read (counted, the first few said).
static BAD: AtomicU64 = AtomicU64::new(0);

/// Serve the fleet's dashboard on `cfg.bind` from `a.nats` until SIGINT/SIGTERM.
pub fn run(a: &NatsArgs, cfg: WebSinkConfig) -> Result<()> {
    cfg.validate().map_err(anyhow::Error::msg)?;
    // Before binding: a public dashboard without a token never listens at all.
    cfg.token().map_err(anyhow::Error::msg)?;
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
    rt.block_on(serve(a, cfg))
}

async fn serve(a: &NatsArgs, cfg: WebSinkConfig) -> Result<()> {
    let bind_err = || format!("dashboard: cannot listen on {} (--bind)", cfg.bind);
    let listener = tokio::net::TcpListener::bind(&cfg.bind)
        .await
        .with_context(bind_err)?;
    let client = crate::source::nats::connect(a, "dronewatt dashboard").await?;
    let mut subs = Vec::new();
    for kind in [ESTIMATES, ALERTS] {
        let subject = format!("{kind}.>");
        subs.push(
            client
                .subscribe(subject.clone())
                .await
                .with_context(|| format!("NATS: subscribe {subject}"))?,
        );
    }
    client
        .flush()
        .await
        .map_err(|e| anyhow::anyhow!("NATS: {e}"))?;
    tracing::info!(
        "web dashboard on http://{}/: the fleet on NATS ({ESTIMATES}.>, {ALERTS}.>)",
        listener
            .local_addr()
            .map_or(cfg.bind.clone(), |a| a.to_string())
    );
    let shutdown = crate::pipeline::shutdown_on_signal();
    let (tx, rx) = mpsc::channel::<Feed>(crate::pipeline::CHANNEL_DEPTH);
    let stop = shutdown.clone();
    let reader = tokio::spawn(async move {
        let mut all = futures_util::stream::select_all(subs);
        loop {
            let m = tokio::select! {
                m = all.next() => m,
                _ = stop.cancelled() => None,
            };
            let Some(m) = m else { break };
            let Some(f) = feed(&m.subject, &m.payload) else {
                continue;
            };
            if tx.send(f).await.is_err() {
                break;
            }
        }
    });
    let served = crate::sink::web::feed::serve(cfg, listener, rx, shutdown).await;
    reader.abort();
    let bad = BAD.load(Relaxed);
    if bad > 0 {
        tracing::warn!("dashboard: {bad} lines from NATS did not read and were skipped");
    }
    served
}

/// A message off NATS as the dashboard takes it; a line that does not read is counted and
/// skipped (the first 10 said).
fn feed(subject: &str, payload: &[u8]) -> Option<Feed> {
    match jsonl_read::read(payload) {
        Ok(Line::Estimate(r)) => Some(Feed::Report(r)),
        Ok(Line::Alert(v, a)) => Some(Feed::Alert(v, a)),
        Err(e) => {
            let n = BAD.fetch_add(1, Relaxed) + 1;
            if n <= 10 {
                tracing::warn!("dashboard: {subject}: {e}; skipped ({n} so far)");
            }
            None
        }
    }
}
