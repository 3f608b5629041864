//! Leases on partitions in the JetStream key-value bucket [`super::LEASES`]: `p<part>` holds
//! the worker's id; `w.<id>` registers a live worker. Every entry expires
//! [`super::LEASE_TTL`] after its last write (the bucket's `max_age`), so a worker that
//! stops renewing (killed, cut off) loses its leases and its registration by itself.
//!
//! Taking a lease is `create` (fails while another holds it); renewing is `update` on the
//! revision held (fails when it expired and another took it: the lease is lost, and the
//! partition is stopped); releasing is `delete`.

use anyhow::Result;
use async_nats::jetstream::kv::Store;
use futures_util::StreamExt;

/// The key of partition `part`'s lease.
pub fn key(part: u32) -> String {
    format!("p{part}")
}

/// Who holds partition `part` now (`None`: nobody, or the bucket cannot be read).
pub async fn holder(kv: &Store, part: u32) -> Option<String> {
    match kv.entry(key(part)).await {
        Ok(Some(e)) if matches!(e.operation, async_nats::jetstream::kv::Operation::Put) => {
            Some(String::from_utf8_lossy(&e.value).into_owned())
        }
        _ => None,
    }
}

/// Take partition `part` for `me`: its lease's revision, or `None` when another holds it.
pub async fn take(kv: &Store, part: u32, me: &str) -> Option<u64> {
    kv.create(key(part), me.to_string().into()).await.ok()
}

/// Renew `me`'s lease of `part` held at `revision`: the new revision, or `None` when it
/// was lost (expired, and maybe taken).
pub async fn renew(kv: &Store, part: u32, me: &str, revision: u64) -> Option<u64> {
    kv.update(key(part), me.to_string().into(), revision)
        .await
        .ok()
}

/// Give `part` up (another worker may take it at once).
pub async fn release(kv: &Store, part: u32) {
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
