//! The demultiplexer's batches of one vehicle's messages, and their way back: the vehicle's
//! telemetry stage hands each batch it has read back (emptied), and the demultiplexer fills
//! it again, so that routing a message allocates nothing. A fresh `Vec` per vehicle per
//! burst, grown from empty on the demultiplexer's thread and freed on another, cost ~7 % of
//! a flat-out fleet replay's CPU, most of it the kernel zeroing the allocator's fresh pages
//! (issue 47's profile, docs/src/fleet.md).

use std::sync::{Arc, Mutex};

use tokio::sync::mpsc;

use crate::source::TimedMessage;

/// One vehicle's messages of one burst, in order.
pub(super) type Batch = Vec<TimedMessage>;

/// At most this many empty batches wait to be filled again per vehicle (one is in the
/// demultiplexer's hands, one or two in flight in steady state).
const KEEP: usize = 4;
/// A batch that grew past this many messages (a one-vehicle flat-out replay's burst) is
/// freed rather than kept: what a vehicle holds idle, and what a queued batch of one
/// message holds, stays small at 3,000 vehicles.
const KEEP_CAPACITY: usize = 64;
/// A new batch's room: a live vehicle's burst share is a message or two (as `Vec`'s own
/// first growth: more room here showed as peak RSS while a live monitor fell behind, its
/// queues holding many batches of one message each).
const FIRST_CAPACITY: usize = 4;

/// The empty batches one vehicle's chain handed back (its demultiplexer entry and its
/// telemetry stage share it; an uncontended lock, twice a burst).
#[derive(Clone, Default)]
pub(super) struct Spares(Arc<Mutex<Vec<Batch>>>);

impl Spares {
    /// An empty batch to fill: one handed back, else a new one.
    pub(super) fn take(&self) -> Batch {
        self.0
            .lock()
            .ok()
            .and_then(|mut s| s.pop())
            .unwrap_or_else(|| Vec::with_capacity(FIRST_CAPACITY))
    }

    /// Hand a batch that was read back, emptied (freed instead when enough wait, or it is big).
    pub(super) fn give(&self, mut batch: Batch) {
        if batch.capacity() > KEEP_CAPACITY {
            return;
        }
        batch.clear();
        if let Ok(mut s) = self.0.lock() {
            if s.len() < KEEP {
                s.push(batch);
            }
        }
    }
}

/// A chain's input: the demultiplexer's batches, and the way back for each one read.
pub struct BatchRx {
    rx: mpsc::Receiver<Batch>,
    spares: Spares,
}

impl BatchRx {
    /// The next batch; `None` when the demultiplexer is done with this vehicle.
    pub(super) async fn recv(&mut self) -> Option<Batch> {
        self.rx.recv().await
    }

    /// Hand a batch read back to be filled again.
    pub(super) fn give(&self, batch: Batch) {
        self.spares.give(batch);
    }
}

/// A vehicle's batch channel, `depth` batches deep: the demultiplexer's end (with the spares
/// it fills) and the chain's.
pub(super) fn channel(depth: usize) -> (mpsc::Sender<Batch>, Spares, BatchRx) {
    let (tx, rx) = mpsc::channel(depth);
    let spares = Spares::default();
    (tx, spares.clone(), BatchRx { rx, spares })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn message(t_s: f64) -> TimedMessage {
        TimedMessage::new(
            t_s,
            mavlink::MavHeader::default(),
            crate::MavMessage::HEARTBEAT(Default::default()),
        )
    }

    #[tokio::test]
    async fn a_batch_read_comes_back_empty_with_its_room() {
        let (tx, spares, mut rx) = channel(4);
        let mut b = spares.take();
        b.extend((0..10).map(|i| message(i as f64)));
        let room = b.capacity();
        tx.send(b).await.unwrap();
        let got = rx.recv().await.unwrap();
        assert_eq!(got.iter().map(|m| m.t_s).collect::<Vec<_>>()[9], 9.0);
        rx.give(got);
        let again = spares.take();
        assert!(again.is_empty());
        assert_eq!(again.capacity(), room, "the same buffer, not a new one");
    }

    #[test]
    fn spares_are_bounded_and_big_batches_freed() {
        let s = Spares::default();
        for _ in 0..10 {
            s.give(Vec::with_capacity(8));
        }
        assert_eq!(s.0.lock().unwrap().len(), KEEP);
        let s = Spares::default();
        s.give(Vec::with_capacity(KEEP_CAPACITY + 1));
        assert!(s.0.lock().unwrap().is_empty());
        assert_eq!(s.take().capacity(), FIRST_CAPACITY);
    }
}
