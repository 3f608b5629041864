//! Leases on partitions in the JetStream key-value bucket [`super::LEASES`]: `p<part>` holds
//! the worker's id; `w.<id>` registers a live worker. Every entry expires
//! [`super::LEASE_TTL`] after its last write (the bucket's `max_age`), so a worker that
//! stops renewing (killed, cut off) loses its leases and its registration by itself.
//!
//! Taking a lease is `create` (fails while another holds it); renewing is `update` on the
//! revision held (fails when it expired and another took it: the lease is lost, and the
//! partition is stopped); releasing is `delete`.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Instant;

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

/// The partitions' holders as a watch on the bucket shows them, each with the moment its
/// lease runs out (its last write plus [`super::LEASE_TTL`]: the bucket expires entries
/// silently, so the watch does not say it). The gateway's fast path; a holder not seen
/// here is asked of the bucket itself.
#[derive(Clone, Default)]
pub struct Holders(Arc<Mutex<HashMap<u32, (String, Instant)>>>);

impl Holders {
    /// Who holds `part` with a lease that runs now, as last seen.
    pub fn live(&self, part: u32) -> Option<String> {
        let g = self.0.lock().ok()?;
        g.get(&part)
            .filter(|(_, until)| Instant::now() < *until)
            .map(|(h, _)| h.clone())
    }

    /// Follow the bucket's lease entries (from their last values on) until dropped; a watch
    /// that ends or fails is made again after a second.
    pub async fn follow(self, kv: Store) {
        loop {
            match kv.watch_with_history(">").await {
                Ok(mut w) => {
                    while let Some(e) = w.next().await {
                        match e {
                            Ok(e) => self.seen(&e),
                            Err(e) => {
                                tracing::debug!("NATS: lease watch: {e}");
                                break;
                            }
                        }
                    }
                }
                Err(e) => tracing::warn!("NATS: cannot watch the leases ({e}); again in 1 s"),
            }
            tokio::time::sleep(std::time::Duration::from_secs(1)).await;
        }
    }

    fn seen(&self, e: &async_nats::jetstream::kv::Entry) {
        let Some(part) = e.key.strip_prefix('p').and_then(|p| p.parse::<u32>().ok()) else {
            return;
        };
        let Ok(mut g) = self.0.lock() else { return };
        if matches!(e.operation, async_nats::jetstream::kv::Operation::Put) {
            let age = super::wire::unix_now_s() - e.created.unix_timestamp_nanos() as f64 / 1e9;
            let ttl = super::LEASE_TTL.as_secs_f64();
            let left = std::time::Duration::from_secs_f64((ttl - age.max(0.0)).clamp(0.0, ttl));
            let holder = String::from_utf8_lossy(&e.value).into_owned();
            g.insert(part, (holder, Instant::now() + left));
        } else {
            g.remove(&part);
        }
    }
}
