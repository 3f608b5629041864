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
//! Downlink: a frame on `dronewatt.to.<user>.<instance>.<net>.<sys>` is sent on network
//! `net`'s links (signed with the link's key, which never leaves the gateway) only when
//! worker `<user>.<instance>` holds the lease of that vehicle's partition at that moment;
//! anything else is refused, counted and logged. The sender is the subject's, which the
//! server's per-user publish permissions vouch for ([`crate::source::nats::identity`],
//! `config/nats-server.conf`); the holder is the lease bucket's, followed by a watch
//! ([`lease::Holders`]) and asked of the bucket itself when the watch does not show the
//! sender holding it.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result};
use futures_util::StreamExt;
use tokio::sync::mpsc;

use crate::report::status::{FrameSigner, IngestStats, LinkHandle};
use crate::source::nats::{self, holders::Holders, identity, lease, wire, NatsArgs};
use crate::source::{LinkSigning, SourceSpec, TimedMessage};

/// Longest wait for the lease watch to judge the bucket's writes before a frame from a
/// worker not seen holding its vehicle's partition is refused.
const CATCH_UP: Duration = Duration::from_secs(1);

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
    let leases = nats::bucket(&js, nats::LEASES, nats::LEASE_TTL, lease::HISTORY).await?;
    let signing = config
        .link
        .load()
        .map_err(anyhow::Error::msg)?
        .map(|s| Arc::new(LinkSigning::new(s)));
    let signer = signing.clone().map(|s| s as Arc<dyn FrameSigner>);
    let link = LinkHandle::with_signer(signer);
    let stats = Arc::new(IngestStats::default());
    let shutdown = crate::pipeline::shutdown_on_signal();
    // The workers' downlink is subscribed (and the server has it) before any link opens: a
    // frame a worker sends once a vehicle is heard is never lost to a subscription not yet
    // made.
    let sub = client
        .subscribe(format!("{}.>", nats::TO))
        .await
        .map_err(|e| anyhow::anyhow!("NATS: subscribe {}.>: {e}", nats::TO))?;
    client
        .flush()
        .await
        .map_err(|e| anyhow::anyhow!("NATS: {e}"))?;
    let (tx, mut rx) = mpsc::channel::<TimedMessage>(crate::pipeline::CHANNEL_DEPTH);
    let src = tokio::spawn(crate::source::run(
        source,
        tx,
        stats.clone(),
        link.clone(),
        signing,
        shutdown.clone(),
    ));
    let count = Arc::new(Downlink::default());
    let holders = Holders::default();
    let down = tokio::spawn(downlink(sub, leases, link, count.clone(), holders.clone()));
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
                    "gateway: {published} frames stored, {failed} not, {} in flight; to the \
                     vehicles {} sent, {} refused; {} lease takeovers out of turn refused ({:.0} s)",
                    acks.len(), count.sent.load(Relaxed), count.refused.load(Relaxed),
                    holders.refused(),
                    start.elapsed().as_secs_f64()
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
    tracing::info!(
        "gateway: stopped; {published} frames stored, {failed} not; to the vehicles {} sent, {} \
         refused; {} lease takeovers out of turn refused",
        count.sent.load(Relaxed),
        count.refused.load(Relaxed),
        holders.refused()
    );
    src.await.context("the links' task")??;
    Ok(())
}

/// What the downlink did: frames sent to vehicles, and refused.
#[derive(Default)]
struct Downlink {
    sent: AtomicU64,
    refused: AtomicU64,
}

/// Send what workers address to vehicles, when the sender holds the vehicle's lease now.
async fn downlink(
    mut sub: async_nats::Subscriber,
    leases: async_nats::jetstream::kv::Store,
    link: LinkHandle,
    count: Arc<Downlink>,
    holders: Holders,
) -> Result<()> {
    let follow = tokio::spawn(holders.clone().follow(leases.clone()));
    while let Some(m) = sub.next().await {
        let Some((sender, net, sys)) = identity::parse_to(m.subject.as_str()) else {
            refused(
                &count,
                format_args!("{}: not a worker's frame for a vehicle", m.subject),
            );
            continue;
        };
        let part = nats::partition(net, sys);
        // The holder judged from the watch; when it is not the sender, once every write the
        // bucket holds now is judged (a lease taken just before the frame counts).
        let holder = match holders.live(part) {
            Some(h) if h == sender => Some(h),
            _ => {
                holders.catch_up(&leases, CATCH_UP).await;
                holders.live(part)
            }
        };
        if holder.as_deref() != Some(sender.as_str()) {
            refused(
                &count,
                format_args!(
                    "a frame for vehicle {net}:{sys} from worker {sender}: partition {part} is \
                     held by {}",
                    holder.as_deref().unwrap_or("nobody")
                ),
            );
            continue;
        }
        if link.network(net).try_send(m.payload.to_vec()) {
            count.sent.fetch_add(1, Relaxed);
        }
    }
    follow.abort();
    Ok(())
}

/// Count a refused downlink frame and say why: each of the first 20, then one in 1,000.
fn refused(count: &Downlink, why: std::fmt::Arguments) {
    let n = count.refused.fetch_add(1, Relaxed) + 1;
    if n <= 20 || n.is_multiple_of(1000) {
        tracing::warn!("gateway: refused {why} ({n} refused)");
    }
}
