//! What a fleet worker publishes of its reports to NATS, besides its own sinks: each
//! estimate and each alert event, as the `--json` sink writes it (one JSON object), on
//!
//! ```text
//!  dronewatt.estimates.<part>.<net>.<sys>    {"type":"estimate",…}
//!  dronewatt.alerts.<part>.<net>.<sys>       {"type":"alert",…}
//! ```
//!
//! (core NATS, not the stream: a viewer subscribes to `dronewatt.estimates.>`, one
//! partition's `dronewatt.*.<part>.>`, or one vehicle's). A worker publishes only for
//! vehicles of the partitions it holds a lease for: [`publish`] checks the lease set the
//! worker keeps (`set`), and a report of another vehicle is dropped and counted. The
//! pipeline formats the lines (`src/pipeline/nats_out.rs`); this module owns the client.

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::sync::{Arc, Mutex, OnceLock};

use crate::report::VehicleId;

/// Subject prefix of the estimates.
pub const ESTIMATES: &str = "dronewatt.estimates";
/// Subject prefix of the alert events.
pub const ALERTS: &str = "dronewatt.alerts";

/// The worker's client and the partitions it holds.
struct Out {
    client: async_nats::Client,
    held: Arc<Mutex<HashMap<u32, ()>>>,
}

static OUT: OnceLock<Out> = OnceLock::new();
/// Reports of vehicles whose partition this worker does not hold (not published).
pub static REFUSED: AtomicU64 = AtomicU64::new(0);

/// The worker's client and its held partitions (once, when it has connected).
pub(super) fn set(client: async_nats::Client, held: Arc<Mutex<HashMap<u32, ()>>>) {
    let _ = OUT.set(Out { client, held });
}

/// Whether this process is a worker that has connected.
pub fn ready() -> bool {
    OUT.get().is_some()
}

/// The subject of `kind` (`ESTIMATES`, `ALERTS`) for `vehicle`.
pub fn subject(kind: &str, vehicle: VehicleId) -> String {
    format!(
        "{kind}.{}.{}.{}",
        super::partition(vehicle.network, vehicle.system_id),
        vehicle.network,
        vehicle.system_id
    )
}

/// Publish `body` on `kind`'s subject for `vehicle`, when this worker holds its
/// partition; false (counted in [`REFUSED`]) when it does not, or is no worker.
pub async fn publish(kind: &str, vehicle: VehicleId, body: Vec<u8>) -> bool {
    let Some(out) = OUT.get() else { return false };
    let part = super::partition(vehicle.network, vehicle.system_id);
    let mine = out.held.lock().is_ok_and(|h| h.contains_key(&part));
    if !mine {
        REFUSED.fetch_add(1, Relaxed);
        return false;
    }
    if let Err(e) = out
        .client
        .publish(subject(kind, vehicle), body.into())
        .await
    {
        tracing::debug!("NATS: publish for vehicle {vehicle}: {e}");
        return false;
    }
    true
}
