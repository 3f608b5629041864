//! A fleet worker's reports to NATS ([`crate::source::nats::publish`]: the subjects, and
//! the lease check): each estimate and alert event as the `--json` sink writes it.

use crate::sink::ReportRx;
use crate::source::nats::publish::{self, ALERTS, ESTIMATES};

/// Publish every report from `rx` until it ends (the worker's connection comes a moment
/// after the pipeline starts: reports before it are not published).
pub(super) async fn run(mut rx: ReportRx) {
    while let Some(r) = rx.next().await {
        if !publish::ready() {
            continue;
        }
        let mut buf = Vec::new();
        if crate::sink::jsonl::write_estimate(&mut buf, &r).is_ok() {
            publish::publish(ESTIMATES, r.vehicle, line(buf)).await;
        }
        for a in &r.alerts {
            let mut buf = Vec::new();
            if crate::sink::jsonl::write_alert(&mut buf, r.vehicle, a).is_ok() {
                publish::publish(ALERTS, r.vehicle, line(buf)).await;
            }
        }
    }
    let refused = publish::REFUSED.load(std::sync::atomic::Ordering::Relaxed);
    if refused > 0 {
        tracing::info!(
            "NATS: {refused} reports of vehicles this worker does not hold were not published"
        );
    }
}

/// A JSON line without its newline.
fn line(mut buf: Vec<u8>) -> Vec<u8> {
    if buf.last() == Some(&b'\n') {
        buf.pop();
    }
    buf
}
