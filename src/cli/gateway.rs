//! `dronewatt gateway LINK… --nats URL`: MAVLink links in, the frame stream out, and what
//! workers address to a vehicle back out on its network's links.
//!
//! The links are read exactly as `monitor` reads them (the same addresses, `[[links]]` and
//! networks, the redundant-link merge, signing checked here). Each decoded message goes to
//! `dronewatt.frames.<part>.<net>.<sys>` ([`crate::source::nats::wire`]) with its arrival time; the
//! publish acknowledgements are awaited in a window of [`ACK_WINDOW`], so a slow server
//! holds the links back (their sockets buffer) rather than losing what it did not take.
//! Several gateways (one per radio) can feed one stream.
//!
//! Downlink: a frame on `dronewatt.to.<net>.<sys>` is sent on network `net`'s links (signed
//! with the link's key, which never leaves the gateway) only when the worker its
//! [`crate::source::nats::WORKER_HEADER`] names holds the lease of that vehicle's partition; anything
//! else is refused, counted and logged.

use std::collections::{HashMap, VecDeque};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result};
use futures_util::StreamExt;
use tokio::sync::mpsc;

use crate::report::status::{FrameSigner, IngestStats, LinkHandle};
use crate::source::nats::{self, lease, wire, NatsArgs};
use crate::source::{LinkSigning, SourceSpec, TimedMessage};

/// Publishes in flight before the gateway waits for the oldest acknowledgement.
pub const ACK_WINDOW: usize = 512;

/// Run a gateway on `source` (a link or links) until SIGINT/SIGTERM.
pub fn run(source: SourceSpec, config: crate::config::Config, nats: NatsArgs) -> Result<()> {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    rt.block_on(serve(source, config, nats))
}

async fn serve(source: SourceSpec, config: crate::config::Config, nats: NatsArgs) -> Result<()> {
    let client = nats::connect(&nats, "dronewatt gateway").await?;
    let js = async_nats::jetstream::new(client.clone());
    nats::frames_stream(&js).await?;
    let leases = nats::bucket(&js, nats::LEASES, nats::LEASE_TTL).await?;
    let signing = config
        .link
        .load()
        .map_err(anyhow::Error::msg)?
        .map(|s| Arc::new(LinkSigning::new(s)));
    let signer = signing.clone().map(|s| s as Arc<dyn FrameSigner>);
    let link = LinkHandle::with_signer(signer);
    let stats = Arc::new(IngestStats::default());
    let shutdown = crate::pipeline::shutdown_on_signal();
    let (tx, mut rx) = mpsc::channel::<TimedMessage>(crate::pipeline::CHANNEL_DEPTH);
    let src = tokio::spawn(crate::source::run(
        source,
        tx,
        stats.clone(),
        link.clone(),
        signing,
        shutdown.clone(),
    ));
    let down = tokio::spawn(downlink(client.clone(), leases, link));
    let mut acks = VecDeque::with_capacity(ACK_WINDOW);
    let (mut published, mut failed) = (0u64, 0u64);
    let start = Instant::now();
    let mut report = tokio::time::interval(Duration::from_secs(10));
    loop {
        tokio::select! {
            m = rx.recv() => {
                let Some(m) = m else { break };
                let arrived = wire::unix_now_s() - m.arrived.elapsed().as_secs_f64();
                let sys = u8::try_from(m.header.system_id).unwrap_or(u8::MAX);
                let body = wire::encode(m.network, &m.header, &m.msg, arrived);
                match js.publish(nats::frames_subject(m.network, sys), body.into()).await {
                    Ok(ack) => acks.push_back(ack),
                    Err(e) => {
                        failed += 1;
                        tracing::warn!("gateway: publish: {e}");
                    }
                }
                while acks.len() >= ACK_WINDOW {
                    if let Some(a) = acks.pop_front() {
                        match a.await {
                            Ok(_) => published += 1,
                            Err(e) => { failed += 1; tracing::warn!("gateway: not stored: {e}") }
                        }
                    }
                }
            }
            _ = report.tick() => {
                tracing::info!(
                    "gateway: {published} frames stored, {failed} not, {} in flight ({:.0} s)",
                    acks.len(), start.elapsed().as_secs_f64()
                );
            }
        }
    }
    for a in acks {
        match a.await {
            Ok(_) => published += 1,
            Err(_) => failed += 1,
        }
    }
    down.abort();
    tracing::info!("gateway: stopped; {published} frames stored, {failed} not");
    src.await.context("the links' task")??;
    Ok(())
}

/// Send what workers address to vehicles, when the sender holds the vehicle's lease.
async fn downlink(
    client: async_nats::Client,
    leases: async_nats::jetstream::kv::Store,
    link: LinkHandle,
) -> Result<()> {
    let mut sub = client
        .subscribe(format!("{}.>", nats::TO))
        .await
        .map_err(|e| anyhow::anyhow!("NATS: subscribe {}.>: {e}", nats::TO))?;
    // Who holds each partition, looked up at most once a second.
    let mut holders: HashMap<u32, (Option<String>, Instant)> = HashMap::new();
    let (mut sent, mut refused) = (0u64, 0u64);
    while let Some(m) = sub.next().await {
        let mut parts = m.subject.as_str().rsplit('.');
        let sys = parts.next().and_then(|s| s.parse::<u8>().ok());
        let net = parts.next().and_then(|s| s.parse::<u8>().ok());
        let (Some(net), Some(sys)) = (net, sys) else {
            refused += 1;
            tracing::warn!("gateway: {}: not a vehicle's subject; refused", m.subject);
            continue;
        };
        let worker = m
            .headers
            .as_ref()
            .and_then(|h| h.get(nats::WORKER_HEADER))
            .map(|v| v.as_str().to_string());
        let part = nats::partition(net, sys);
        let fresh = holders
            .get(&part)
            .is_some_and(|(_, at)| at.elapsed() < Duration::from_secs(1));
        if !fresh {
            let h = lease::holder(&leases, part).await;
            holders.insert(part, (h, Instant::now()));
        }
        let holder = holders.get(&part).and_then(|(h, _)| h.clone());
        if worker.is_none() || worker != holder {
            refused += 1;
            tracing::warn!(
                "gateway: refused a frame for vehicle {net}:{sys} from worker {:?}: partition \
                 {part} is held by {:?} ({refused} refused)",
                worker,
                holder
            );
            continue;
        }
        if link.network(net).try_send(m.payload.to_vec()) {
            sent += 1;
        }
        if sent > 0 && sent.is_multiple_of(1000) {
            tracing::debug!("gateway: {sent} frames sent to vehicles");
        }
    }
    Ok(())
}
