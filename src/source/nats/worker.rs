//! `dronewatt monitor --nats URL`: a fleet worker. It is a source of the pipeline like a
//! link: the frames of the partitions it holds come off the stream as [`TimedMessage`]s,
//! and the chains, the models and the sinks run on them exactly as `monitor` runs them on
//! a link. What the chains send a vehicle goes back through NATS to the gateway.
//!
//! Every [`super::RENEW`]: register, renew the leases held (a lease lost stops its
//! partition), write each held partition's checkpoint (`c<part>`: the last stream sequence
//! handed on and its source time), give up what is over the fair share, take free
//! partitions up to it. A partition taken is read from its previous holder's checkpoint
//! (its vehicles' states restored: [`checkpoint`]), else from the stream's first frame of
//! it, or, when this worker held it before, from the frame after the last it handed on;
//! reports up to the previous holder's checkpoint are held back ([`super::set_quiet`]).
//! After the client reconnects, each partition is read again from its next sequence. On
//! shutdown the worker writes its checkpoints and releases its leases, so another takes
//! them at once.
//!
//! The source's clock (`t_s`) is the gateway's arrival time, in seconds since the stream was
//! created: one clock for every worker, so a report's time is the same whichever worker
//! made it.

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use anyhow::Result;
use async_nats::jetstream::{self, consumer, kv::Store, stream::Stream};
use futures_util::StreamExt;
use tokio::sync::mpsc;
use tokio_util::sync::CancellationToken;

use super::{checkpoint, lease, wire, NatsArgs, CHECKPOINTS, LEASES, LEASE_TTL, PARTITIONS, RENEW};
use crate::report::status::{IngestStats, LinkHandle};
use crate::source::links::link::LinkIo;
use crate::source::TimedMessage;

/// How far a partition's reading has gone: the last stream sequence handed on and its
/// source time (the checkpoint).
#[derive(Default)]
struct Progress {
    seq: AtomicU64,
    t_s: Mutex<f64>,
    /// The sequences passed, by source time: where a replay before a time starts.
    marks: Mutex<checkpoint::Marks>,
}

/// A partition this worker holds.
struct Held {
    revision: u64,
    /// When it was last written (taken or renewed), by this machine's clock.
    renewed: Instant,
    stop: CancellationToken,
}

/// A refused renewal is answered by writing the lease back ([`lease::reclaim`]) only while
/// this much at least of the lease is left (clocks and a slow answer aside).
const RECLAIM_MARGIN: std::time::Duration = std::time::Duration::from_millis(1500);

/// Run the worker until `io.shutdown`.
pub async fn run(args: NatsArgs, io: LinkIo) -> Result<()> {
    let principal = super::identity::principal(&args)?;
    let client = super::connect(&args, "dronewatt worker").await?;
    let js = jetstream::new(client.clone());
    let mut stream = super::frames_stream(&js).await?;
    // The workers' one clock: seconds since the stream was created.
    let epoch = stream
        .info()
        .await
        .map(|i| i.created.unix_timestamp_nanos() as f64 / 1e9)
        .map_err(|e| anyhow::anyhow!("NATS stream {}: {e}", super::STREAM))?;
    let leases = super::bucket(&js, LEASES, LEASE_TTL, lease::HISTORY).await?;
    let ckpts = super::bucket(&js, CHECKPOINTS, std::time::Duration::ZERO, 1).await?;
    let me = super::identity::worker_id(&principal);
    let held_set: Arc<Mutex<HashMap<u32, ()>>> = Arc::default();
    uplink(&client, &io.link, &me, held_set.clone());
    super::publish::set(client.clone(), held_set.clone());
    tracing::info!(
        "NATS worker {me}: sharing {PARTITIONS} partitions of {}",
        super::STREAM
    );
    let mut held: HashMap<u32, Held> = HashMap::new();
    let mut progress: HashMap<u32, Arc<Progress>> = HashMap::new();
    let mut tick = tokio::time::interval(RENEW);
    loop {
        tokio::select! {
            _ = io.shutdown.cancelled() => break,
            _ = tick.tick() => {}
        }
        if let Err(e) = lease::register(&leases, &me).await {
            tracing::warn!("{e}");
        }
        let mut lost = Vec::new();
        for (p, h) in held.iter_mut() {
            let renewed = match lease::renew(&leases, *p, &me, h.revision).await {
                Some(r) => Some(r),
                // Refused while the lease still ran: written out of turn; write it back.
                None if h.renewed.elapsed() + RECLAIM_MARGIN < LEASE_TTL => {
                    lease::reclaim(&leases, *p, &me).await
                }
                None => None,
            };
            match renewed {
                Some(r) => {
                    h.revision = r;
                    h.renewed = Instant::now();
                }
                None => lost.push(*p),
            }
        }
        for p in lost {
            if let Some(h) = held.remove(&p) {
                h.stop.cancel();
                tracing::warn!("NATS worker {me}: lost the lease of partition {p}; stopped it");
            }
        }
        for p in held.keys() {
            checkpoint(&ckpts, *p, &me, progress.get(p)).await;
        }
        let share = lease::share(PARTITIONS, lease::live_workers(&leases).await);
        while held.len() > share {
            let Some(&p) = held.keys().max() else { break };
            if let Some(h) = held.remove(&p) {
                h.stop.cancel();
                checkpoint(&ckpts, p, &me, progress.get(&p)).await;
                lease::release(&leases, p, &me).await;
                tracing::info!("NATS worker {me}: gave partition {p} up (share {share})");
            }
        }
        for p in 0..PARTITIONS {
            if held.len() >= share {
                break;
            }
            if held.contains_key(&p) {
                continue;
            }
            let Some(revision) = lease::take(&leases, p, &me).await else {
                continue;
            };
            let prog = progress.entry(p).or_default().clone();
            let stop = io.shutdown.child_token();
            let from = start_of(&ckpts, p, &me, &prog).await;
            let read = Reading {
                p,
                from,
                epoch,
                prog,
                stop: stop.clone(),
            };
            tokio::spawn(consume(
                read,
                stream.clone(),
                io.tx.clone(),
                io.stats.clone(),
            ));
            held.insert(
                p,
                Held {
                    revision,
                    renewed: Instant::now(),
                    stop,
                },
            );
        }
        if let Ok(mut g) = held_set.lock() {
            *g = held.keys().map(|p| (*p, ())).collect();
        }
    }
    lease::unregister(&leases, &me).await;
    for (p, h) in held.drain() {
        h.stop.cancel();
        checkpoint(&ckpts, p, &me, progress.get(&p)).await;
        lease::release(&leases, p, &me).await;
    }
    tracing::info!("NATS worker {me}: stopped; leases released");
    Ok(())
}

/// Write partition `p`'s checkpoint (nothing before its first frame): its vehicles'
/// states and how far its reading went ([`checkpoint::write`]).
async fn checkpoint(ckpts: &Store, p: u32, me: &str, prog: Option<&Arc<Progress>>) {
    let Some(prog) = prog else { return };
    let seq = prog.seq.load(Relaxed);
    if seq == 0 {
        return;
    }
    let t_s = prog.t_s.lock().map_or(0.0, |t| *t);
    let Ok(marks) = prog.marks.lock().map(|m| m.clone()) else {
        return;
    };
    checkpoint::write(ckpts, p, me, seq, t_s, &marks).await;
}

/// Where to start reading partition `p` just taken: after the last frame this worker
/// handed on; or, new to it, from its previous holder's checkpoint (its vehicles'
/// states restored: [`checkpoint::restore`]), else from the stream's first frame. Either
/// way the reports up to where the previous holder's went out are held back.
async fn start_of(ckpts: &Store, p: u32, me: &str, prog: &Progress) -> u64 {
    let ours = prog.seq.load(Relaxed);
    if ours > 0 {
        return ours + 1;
    }
    match checkpoint::header(ckpts, p).await {
        Some(c) if c.worker != me => {
            super::set_quiet(p, c.t_s);
            let from = checkpoint::restore(ckpts, p, &c).await;
            tracing::info!(
                "NATS worker {me}: took partition {p} from worker {} (checkpoint: stream \
                 sequence {}); {}, reports up to there held back",
                c.worker,
                c.seq,
                match from {
                    Some(s) => format!("its vehicles restored, replaying from sequence {s}"),
                    None => "rebuilding its vehicles from the stream".to_string(),
                }
            );
            from.unwrap_or(1)
        }
        _ => {
            tracing::info!("NATS worker {me}: took partition {p}");
            1
        }
    }
}

/// One partition's reading: from stream sequence `from`, on the clock that starts at
/// `epoch` (unix seconds), until `stop`.
struct Reading {
    p: u32,
    from: u64,
    epoch: f64,
    prog: Arc<Progress>,
    stop: CancellationToken,
}

/// Read a partition into the pipeline.
async fn consume(
    r: Reading,
    stream: Stream,
    tx: mpsc::Sender<TimedMessage>,
    stats: Arc<IngestStats>,
) {
    let Reading {
        p,
        from,
        epoch,
        prog,
        stop,
    } = r;
    // The next sequence to read; after the server came back, the consumer is made again
    // from it (the server's restart loses the consumer, not the stream).
    let mut next = from.max(1);
    let mut reconnects = super::reconnects();
    let mut delay = super::BACKOFF_MIN;
    'open: loop {
        let mut msgs = match open(&stream, p, next).await {
            Ok(m) => m,
            Err(e) => {
                tracing::warn!(
                    "NATS: partition {p}: cannot read the stream from sequence {next} ({e}); \
                     retry in {:.1} s",
                    delay.as_secs_f64()
                );
                tokio::select! {
                    _ = stop.cancelled() => return,
                    _ = tokio::time::sleep(delay) => {}
                }
                delay = (delay * 2).min(super::BACKOFF_MAX);
                continue;
            }
        };
        delay = super::BACKOFF_MIN;
        loop {
            let m = tokio::select! {
                _ = stop.cancelled() => return,
                _ = reconnects.changed() => {
                    tracing::info!(
                        "NATS: partition {p}: reading the stream again from sequence {next} \
                         after the reconnection"
                    );
                    continue 'open;
                }
                m = msgs.next() => m,
            };
            let m = match m {
                Some(Ok(m)) => m,
                Some(Err(e)) => {
                    tracing::warn!("NATS: partition {p}: {e}");
                    continue;
                }
                None => {
                    tracing::warn!(
                        "NATS: partition {p}: the stream's consumer ended; reading again from \
                         sequence {next}"
                    );
                    tokio::select! {
                        _ = stop.cancelled() => return,
                        _ = tokio::time::sleep(super::BACKOFF_MIN) => {}
                    }
                    continue 'open;
                }
            };
            let seq = m.info().map_or(0, |i| i.stream_sequence);
            next = next.max(seq + 1);
            let f = match wire::decode(&m.payload) {
                Ok(f) => f,
                Err(e) => {
                    IngestStats::add(&stats.frames_bad, 1);
                    tracing::debug!("NATS: partition {p}, sequence {seq}: {e}");
                    continue;
                }
            };
            let t_s = f.arrived_unix_s - epoch;
            let tm = TimedMessage {
                t_s,
                header: f.header,
                msg: f.msg,
                arrived: Instant::now(),
                network: f.network,
            };
            IngestStats::add(&stats.frames_ok, 1);
            let sent = tokio::select! {
                _ = stop.cancelled() => false,
                r = tx.send(tm) => r.is_ok(),
            };
            if !sent {
                return;
            }
            prog.seq.store(seq, Relaxed);
            if let Ok(mut t) = prog.t_s.lock() {
                *t = t_s;
            }
            if let Ok(mut m) = prog.marks.lock() {
                m.passed(seq, t_s);
            }
        }
    }
}

/// An ordered consumer of partition `p` from stream sequence `from`.
async fn open(stream: &Stream, p: u32, from: u64) -> Result<consumer::pull::Ordered> {
    let cfg = consumer::pull::OrderedConfig {
        filter_subject: format!("{}.{p}.>", super::FRAMES),
        deliver_policy: consumer::DeliverPolicy::ByStartSequence {
            start_sequence: from.max(1),
        },
        ..Default::default()
    };
    let c = stream
        .create_consumer(cfg)
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    c.messages().await.map_err(|e| anyhow::anyhow!("{e}"))
}

/// The vehicle a frame of dronewatt's is for: the message's `target_system` when it names
/// one, else the system id it is sent as (the MAVLink sink sends as the vehicle).
fn target_of(frame: &[u8]) -> Option<u8> {
    // MAVLink 2: STX, len, incompat, compat, seq, sys, comp, msgid (3), payload.
    if frame.len() < 12 || frame[0] != 0xFD {
        return None;
    }
    let len = usize::from(frame[1]);
    let id = u32::from_le_bytes([frame[7], frame[8], frame[9], 0]);
    let payload = frame.get(10..10 + len)?;
    let sent_as = frame[5];
    let target =
        <crate::MavMessage as mavlink::Message>::parse(mavlink::MavlinkVersion::V2, id, payload)
            .ok()
            .and_then(|m| serde_json::to_value(&m).ok())
            .and_then(|v| {
                // Internally or externally tagged: the field at the top, or one level down.
                let direct = v.get("target_system").cloned();
                direct
                    .or_else(|| {
                        v.as_object()?
                            .values()
                            .find_map(|i| i.get("target_system").cloned())
                    })
                    .and_then(|t| t.as_u64())
            })
            .and_then(|t| u8::try_from(t).ok())
            .filter(|&t| t != 0);
    Some(target.unwrap_or(sent_as))
}

/// Attach writers to `link` (and one per network): each frame the chains send goes to
/// `dronewatt.to.<user>.<instance>.<net>.<sys>` ([`super::identity`]), when this worker
/// holds the vehicle (the gateway checks that again: this is only the worker's restraint).
fn uplink(
    client: &async_nats::Client,
    link: &LinkHandle,
    me: &str,
    held: Arc<Mutex<HashMap<u32, ()>>>,
) {
    let mut handles = vec![link.clone()];
    for net in 0..=u8::MAX {
        let h = if net == 0 {
            link.clone()
        } else {
            LinkHandle::with_signer(None)
        };
        let (wtx, mut wrx) = mpsc::channel::<Vec<u8>>(256);
        h.attach(wtx);
        if net > 0 {
            handles.push(h);
        }
        let (client, me, held) = (client.clone(), me.to_string(), held.clone());
        tokio::spawn(async move {
            while let Some(frame) = wrx.recv().await {
                let Some(sys) = target_of(&frame) else {
                    continue;
                };
                let mine = held
                    .lock()
                    .is_ok_and(|h| h.contains_key(&super::partition(net, sys)));
                if !mine {
                    continue;
                }
                let subject = super::identity::to_subject(&me, net, sys);
                if let Err(e) = client.publish(subject, frame.into()).await {
                    tracing::debug!("NATS: to vehicle {net}:{sys}: {e}");
                }
            }
        });
    }
    link.set_networks(handles);
}
