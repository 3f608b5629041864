//! Who holds each partition as the gateway judges it: its own reading of the lease bucket's
//! writes, in the order the server stored them and with the server's times, under the lease
//! rules ([`super::lease`]), not the bucket's last value taken on trust.
//!
//! The server lets every worker write every `p<part>` key, so the last value alone is the
//! word of whoever wrote last. The gateway follows every write ([`Holders::follow`]) and
//! keeps, for each partition, its **rightful holder**:
//! - a write naming a worker becomes the holder when nobody held the partition, when the
//!   holder's lease had run out at that write (its last write + [`super::LEASE_TTL`],
//!   server times), or when the holder had released it;
//! - a release counts only with the holder's own marker `r.<id>.p<part>` (its key's user
//!   is vouched for by the server's permissions); a bare deletion, which anyone may write,
//!   frees nothing;
//! - a write naming the holder renews it;
//! - a write naming another while the holder's lease still runs is a **takeover out of
//!   turn**: refused, said, and the holder stays. The worker that wrote it is not the
//!   holder, and its frames are refused, until the holder's lease runs out or is
//!   released; the holder, its renewal refused, writes its lease back.
//!
//! A gateway judges only what it saw: the writes before it started are read as their last
//! values, on trust.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use async_nats::jetstream::kv::{Operation, Store};
use futures_util::StreamExt;

use super::lease::written_s;

/// A partition's rightful holder.
#[derive(Clone, Debug)]
struct Lease {
    holder: String,
    /// Its last write, server unix seconds.
    last_s: f64,
    /// When its lease runs out here, by this machine's clock.
    until: Instant,
    /// It wrote its release marker.
    released: bool,
}

#[derive(Default)]
struct State {
    parts: HashMap<u32, Lease>,
    /// The last bucket revision judged.
    revision: u64,
    /// Takeovers out of turn refused.
    refused: u64,
}

/// The partitions' rightful holders, as the gateway judges them (cheap to clone).
#[derive(Clone, Default)]
pub struct Holders(Arc<Mutex<State>>);

impl Holders {
    /// Who holds `part` with a lease that runs now (not released).
    pub fn live(&self, part: u32) -> Option<String> {
        let g = self.0.lock().ok()?;
        g.parts
            .get(&part)
            .filter(|l| !l.released && Instant::now() < l.until)
            .map(|l| l.holder.clone())
    }

    /// How many writes took a lease out of turn (refused).
    pub fn refused(&self) -> u64 {
        self.0.lock().map_or(0, |g| g.refused)
    }

    /// Wait (up to `wait`) until every write the bucket holds now has been judged: what a
    /// frame from a worker not seen holding its partition waits for, so a lease written
    /// just before the frame counts.
    pub async fn catch_up(&self, kv: &Store, wait: Duration) {
        let Ok(info) = kv.stream.get_info().await else {
            return;
        };
        let last = info.state.last_sequence;
        let end = Instant::now() + wait;
        while self.0.lock().is_ok_and(|g| g.revision < last) && Instant::now() < end {
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    }

    /// Follow the bucket's writes (from their last values on) until dropped; a watch that
    /// ends or fails is made again after a second.
    pub async fn follow(self, kv: Store) {
        loop {
            match kv.watch_with_history(">").await {
                Ok(mut w) => {
                    while let Some(e) = w.next().await {
                        match e {
                            Ok(e) => self.judge(
                                &Write {
                                    key: &e.key,
                                    put: matches!(e.operation, Operation::Put),
                                    value: &e.value,
                                    revision: e.revision,
                                    at_s: written_s(&e),
                                },
                                super::wire::unix_now_s(),
                            ),
                            Err(e) => {
                                tracing::debug!("NATS: lease watch: {e}");
                                break;
                            }
                        }
                    }
                }
                Err(e) => tracing::warn!("NATS: cannot watch the leases ({e}); again in 1 s"),
            }
            tokio::time::sleep(Duration::from_secs(1)).await;
        }
    }

    /// Judge one write (`now_s`: this machine's unix time, for the expiry here).
    fn judge(&self, e: &Write, now_s: f64) {
        let Ok(mut guard) = self.0.lock() else { return };
        let g: &mut State = &mut guard;
        if e.revision <= g.revision {
            return; // seen before (a watch made again)
        }
        g.revision = e.revision;
        let at = e.at_s;
        if let Some((id, part)) = marker(e.key) {
            if let Some(l) = g.parts.get_mut(&part) {
                if l.holder == id && e.put {
                    l.released = true;
                }
            }
            return;
        }
        let Some(part) = e.key.strip_prefix('p').and_then(|p| p.parse::<u32>().ok()) else {
            return;
        };
        if !e.put {
            // A released lease is gone; a bare deletion frees nothing.
            if g.parts.get(&part).is_some_and(|l| l.released) {
                g.parts.remove(&part);
            }
            return;
        }
        let ttl = super::LEASE_TTL.as_secs_f64();
        let until = Instant::now() + Duration::from_secs_f64((at + ttl - now_s).clamp(0.0, ttl));
        let named = String::from_utf8_lossy(e.value).into_owned();
        let lease = Lease {
            holder: named.clone(),
            last_s: at,
            until,
            released: false,
        };
        match g.parts.get_mut(&part) {
            Some(l) if !l.released && at < l.last_s + ttl => {
                if l.holder == named {
                    l.last_s = at;
                    l.until = until;
                } else {
                    let held = l.holder.clone();
                    g.refused += 1;
                    tracing::warn!(
                        "gateway: refused a takeover of partition {part} by {named}: {held}'s \
                         lease still ran ({:.1} s left); {held} holds it",
                        l.last_s + ttl - at
                    );
                }
            }
            _ => {
                g.parts.insert(part, lease);
            }
        }
    }
}

/// One write to the lease bucket, as judged.
struct Write<'a> {
    key: &'a str,
    /// A value (else a deletion or purge).
    put: bool,
    value: &'a [u8],
    revision: u64,
    /// When the server stored it, unix seconds.
    at_s: f64,
}

/// `r.<user>.<instance>.p<part>`: the worker `<user>.<instance>` and the partition.
fn marker(key: &str) -> Option<(String, u32)> {
    let rest = key.strip_prefix("r.")?;
    let (id, part) = rest.rsplit_once(".p")?;
    Some((id.to_string(), part.parse().ok()?))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lease_is_not_taken_out_of_turn_and_a_release_needs_the_holders_marker() {
        let h = Holders::default();
        let now = 1000.0;
        let write = |key: &str, value: &str, put: bool, revision: u64, at_s: f64| {
            let w = Write {
                key,
                put,
                value: value.as_bytes(),
                revision,
                at_s,
            };
            h.judge(&w, now)
        };
        let put = |k: &str, v: &str, r: u64, at: f64| write(k, v, true, r, at);
        let delete = |k: &str, r: u64, at: f64| write(k, "", false, r, at);
        put("p3", "w2.a", 1, now - 1.0);
        assert_eq!(h.live(3).as_deref(), Some("w2.a"));
        // Out of turn: w1 overwrites, and deletes then creates; w2 stays.
        put("p3", "w1.b", 2, now - 0.9);
        delete("p3", 3, now - 0.8);
        put("p3", "w1.b", 4, now - 0.7);
        assert_eq!(h.live(3).as_deref(), Some("w2.a"));
        assert_eq!(h.refused(), 2);
        // Another's marker releases nothing; the holder's own does.
        put("r.w1.b.p3", "", 5, now - 0.6);
        delete("p3", 6, now - 0.6);
        assert_eq!(h.live(3).as_deref(), Some("w2.a"));
        put("p3", "w2.a", 7, now - 0.5); // the holder writes it back
        put("r.w2.a.p3", "", 8, now - 0.4);
        assert_eq!(h.live(3), None);
        delete("p3", 9, now - 0.4);
        put("p3", "w1.b", 10, now - 0.3);
        assert_eq!(h.live(3).as_deref(), Some("w1.b"));
        // A lease that ran out is anyone's (the write comes 6 s after the last).
        put("p5", "w1.b", 11, now - 7.0);
        put("p5", "w2.a", 12, now - 0.5);
        assert_eq!(h.live(5).as_deref(), Some("w2.a"));
        // A write seen again (a watch made again) is not judged twice.
        put("p5", "w1.b", 11, now - 7.0);
        assert_eq!(h.live(5).as_deref(), Some("w2.a"));
        assert_eq!(h.refused(), 2);
        assert_eq!(
            marker("r.worker1.123-ab.p12"),
            Some(("worker1.123-ab".into(), 12))
        );
    }
}
