//! Leases on partitions in the JetStream key-value bucket [`super::LEASES`]: `p<part>` holds
//! the worker's id; `w.<id>` registers a live worker; `r.<id>.p<part>` says that worker
//! released the partition. Every entry expires [`super::LEASE_TTL`] after its last write
//! (the bucket's `max_age`), so a worker that stops renewing (killed, cut off) loses its
//! leases and its registration by itself. The bucket keeps [`HISTORY`] values a key.
//!
//! Taking a lease is `create` (fails while another holds it); renewing is `update` on the
//! revision held (fails when it expired and another took it: the lease is lost, and the
//! partition is stopped); releasing is the marker `r.<id>.p<part>` then `delete`.
//!
//! **A lease is not taken from a live holder.** The server lets every worker write every
//! `p<part>` (NATS 2.9 has no per-key permissions that follow the leases), so the rules are
//! kept by the workers and checked by the gateway ([`super::holders`]):
//! - the release marker's key carries the releasing worker's NATS user, which the server's
//!   permissions vouch for (`$KV.dronewatt_leases.r.<user>.>`): a worker cannot release
//!   another's lease;
//! - an honest worker takes a deleted `p<part>` only when its previous holder wrote the
//!   marker, or that holder's lease has run out ([`free`]);
//! - a holder whose renewal is refused while its lease still runs (someone wrote its key
//!   before it expired) writes it back ([`reclaim`]) instead of giving the partition up.

use std::time::Duration;

use anyhow::Result;
use async_nats::jetstream::kv::{Entry, Operation, Store};
use futures_util::StreamExt;

/// Values kept per key: a deleted lease's previous holder stays readable.
pub const HISTORY: i64 = 2;

/// The key of partition `part`'s lease.
pub fn key(part: u32) -> String {
    format!("p{part}")
}

/// The key of worker `id`'s release marker for `part`.
pub fn released_key(id: &str, part: u32) -> String {
    format!("r.{id}.p{part}")
}

/// An entry's write time, unix seconds (the server's clock, not the writer's word).
pub fn written_s(e: &Entry) -> f64 {
    e.created.unix_timestamp_nanos() as f64 / 1e9
}

/// Whether an honest worker may take `part` now: nobody's lease is there, or the last was
/// deleted by its holder's own release (its marker written after its last renewal), or
/// that holder's lease has run out. A deletion by anyone else (the server cannot tell
/// who deleted) does not free a lease that still runs.
pub async fn free(kv: &Store, part: u32) -> bool {
    let Ok(Some(last)) = kv.entry(key(part)).await else {
        return true;
    };
    if matches!(last.operation, Operation::Put) {
        return false;
    }
    let Some(prev) = previous_put(kv, part, last.revision).await else {
        return true;
    };
    if super::wire::unix_now_s() >= written_s(&prev) + super::LEASE_TTL.as_secs_f64() {
        return true;
    }
    let holder = String::from_utf8_lossy(&prev.value).into_owned();
    matches!(
        kv.entry(released_key(&holder, part)).await,
        Ok(Some(m)) if matches!(m.operation, Operation::Put)
            && m.revision > prev.revision && m.revision < last.revision
    )
}

/// The last `Put` of `part`'s lease before revision `before`.
async fn previous_put(kv: &Store, part: u32, before: u64) -> Option<Entry> {
    let mut h = kv.history(key(part)).await.ok()?;
    let mut prev = None;
    let end = tokio::time::Instant::now() + Duration::from_secs(2);
    while let Ok(Some(Ok(e))) = tokio::time::timeout_at(end, h.next()).await {
        if e.revision < before && matches!(e.operation, Operation::Put) {
            prev = Some(e.clone());
        }
        if e.delta == 0 {
            break;
        }
    }
    prev
}

/// Take partition `part` for `me`: its lease's revision, or `None` when another holds it.
pub async fn take(kv: &Store, part: u32, me: &str) -> Option<u64> {
    if !free(kv, part).await {
        return None;
    }
    kv.create(key(part), me.to_string().into()).await.ok()
}

/// Renew `me`'s lease of `part` held at `revision`: the new revision, or `None` when it
/// was lost (expired, and maybe taken).
pub async fn renew(kv: &Store, part: u32, me: &str, revision: u64) -> Option<u64> {
    kv.update(key(part), me.to_string().into(), revision)
        .await
        .ok()
}

/// `me`'s renewal of `part` was refused while its lease still ran (so nobody could take it
/// by the rules): whoever wrote the key did so out of turn. Write it back over that entry
/// (its revision) and say so: the new revision, or `None` when that fails too.
pub async fn reclaim(kv: &Store, part: u32, me: &str) -> Option<u64> {
    let e = kv.entry(key(part)).await.ok()??;
    let by = match e.operation {
        Operation::Put => String::from_utf8_lossy(&e.value).into_owned(),
        _ => "a deletion".into(),
    };
    if by == me {
        return Some(e.revision);
    }
    let r = kv
        .update(key(part), me.to_string().into(), e.revision)
        .await
        .ok()?;
    tracing::warn!(
        "NATS worker {me}: partition {part}'s lease was overwritten ({by}) before it ran out; \
         written back"
    );
    Some(r)
}

/// Give `part` up (another worker may take it at once): the marker, then the deletion.
pub async fn release(kv: &Store, part: u32, me: &str) {
    if let Err(e) = kv
        .put(released_key(me, part), Vec::<u8>::new().into())
        .await
    {
        tracing::debug!("NATS: release marker of partition {part}: {e}");
    }
    if let Err(e) = kv.delete(key(part)).await {
        tracing::debug!("NATS: release partition {part}: {e}");
    }
}

/// Register `me` as live (renewed with the leases).
pub async fn register(kv: &Store, me: &str) -> Result<()> {
    kv.put(format!("w.{me}"), Vec::<u8>::new().into())
        .await
        .map_err(|e| anyhow::anyhow!("NATS: register worker {me}: {e}"))?;
    Ok(())
}

/// Say `me` is gone (its shutdown): the others' fair share grows at their next renewal,
/// not when the registration expires.
pub async fn unregister(kv: &Store, me: &str) {
    if let Err(e) = kv.delete(format!("w.{me}")).await {
        tracing::debug!("NATS: unregister worker {me}: {e}");
    }
}

/// How many workers are live (registered within the TTL), at least 1.
pub async fn live_workers(kv: &Store) -> usize {
    let Ok(mut keys) = kv.keys().await else {
        return 1;
    };
    let mut n = 0;
    while let Some(k) = keys.next().await {
        if k.is_ok_and(|k| k.starts_with("w.")) {
            n += 1;
        }
    }
    n.max(1)
}

/// A worker's fair share of `partitions` among `workers`: rounded up.
pub fn share(partitions: u32, workers: usize) -> usize {
    let w = workers.max(1);
    (partitions as usize).div_ceil(w)
}
