//! The sinks' side of a run: one task per sink, the relay that hands each vehicle's reports
//! (and the fleet's lost/dropped news) on to them, and the wait for them to flush.

use std::sync::Arc;

use anyhow::Result;
use tokio::sync::mpsc;
use tokio::task::JoinHandle;
use tokio::time::Instant;
use tokio_util::sync::CancellationToken;

use super::{FleetEvent, UPLINK_FLUSH};
use crate::report::status::{ChainStatus, LinkHandle};
use crate::report::{AlertEvent, AlertState, Report, Severity};
use crate::sink::mavlink::MavlinkSinkConfig;
use crate::sink::{Fanout, ReportRx, SinkSpec};

/// Start every sink: each gets its own queue on the returned [`Fanout`] and the chain's
/// status. A MAVLink sink with an `address` of its own writes through an uplink opened
/// here (the same transports as the monitored link, `source::links::link`). Fails before anything
/// runs when a sink cannot start.
pub fn start_sinks(specs: Vec<SinkSpec>, status: &ChainStatus) -> Result<(Fanout, SinkTasks)> {
    let mut fanout = Fanout::default().gauged(status.stats.clone());
    let mut tasks = SinkTasks {
        sinks: Vec::with_capacity(specs.len()),
        uplinks: Vec::new(),
        uplink_stop: status.shutdown.child_token(),
    };
    for spec in specs {
        let mut sink_status = status.clone();
        if let SinkSpec::Mavlink(MavlinkSinkConfig {
            address: Some(a), ..
        }) = &spec
        {
            let (link, task) = crate::source::links::link::spawn_uplink(
                a.parse()?,
                &status.link,
                tasks.uplink_stop.clone(),
            );
            sink_status.link = link.clone();
            tasks.uplinks.push((link, task));
        }
        tasks
            .sinks
            .push(crate::sink::spawn(spec, fanout.subscribe(), sink_status)?);
    }
    Ok((fanout, tasks))
}

/// The running sinks (and the uplinks they write to).
pub struct SinkTasks {
    sinks: Vec<JoinHandle<Result<()>>>,
    uplinks: Vec<(LinkHandle, JoinHandle<Result<()>>)>,
    uplink_stop: CancellationToken,
}

impl SinkTasks {
    /// Wait for every sink to finish (after the [`Fanout`] was dropped), let the uplinks
    /// write what the sinks queued last (a final alert), then close them.
    pub async fn join(self) -> Result<()> {
        for t in self.sinks {
            t.await??;
        }
        for (link, _) in &self.uplinks {
            let flush_by = Instant::now() + UPLINK_FLUSH;
            while link.pending() > 0 && Instant::now() < flush_by {
                tokio::time::sleep(std::time::Duration::from_millis(5)).await;
            }
        }
        self.uplink_stop.cancel();
        for (_, t) in self.uplinks {
            t.await??;
        }
        Ok(())
    }
}

/// One vehicle's reports on to every sink, and what the demultiplexer says about it in
/// between: lost (alert `vehicle_lost` raised; cleared when the vehicle is heard again) and dropped (alert `vehicle_dropped`, after the
/// vehicle's last report). Each is reported on the vehicle's last estimate and energy; a
/// vehicle that never produced a report has nothing to report it on (it is logged).
/// Each report's message → estimate latency is counted in `latency` as it goes to the sinks.
pub(super) async fn relay(
    mut reports: ReportRx,
    mut events: mpsc::UnboundedReceiver<FleetEvent>,
    mut fanout: Fanout,
    latency: Arc<crate::report::status::LatencyHistogram>,
) {
    let mut last: Option<Arc<Report>> = None;
    let mut dropped = None;
    let mut open = true;
    let event =
        |last: &Option<Arc<Report>>, rule: &str, state, severity, t_s: f64, message: String| {
            last.as_ref().map(|r| Report {
                estimate: r.estimate.silent(t_s.max(r.estimate.t_s)),
                energy: r.energy.clone(),
                alerts: vec![AlertEvent {
                    t: t_s,
                    rule: rule.into(),
                    severity,
                    state,
                    message,
                }],
                vehicle: r.vehicle,
            })
        };
    loop {
        tokio::select! {
            biased;
            r = reports.next() => match r {
                // A fleet worker's replay after a takeover: already sent by the
                // partition's previous holder (crate::source::nats::quiet).
                Some(r) if crate::source::nats::quiet(r.vehicle, r.estimate.t_s) => {}
                Some(r) => {
                    if let Some(at) = r.estimate.arrived {
                        latency.record(at.elapsed());
                    }
                    last = Some(r.clone());
                    fanout.send_shared(r).await;
                }
                None => break,
            },
            e = events.recv(), if open => {
                let report = match e {
                    None => { open = false; None }
                    Some(FleetEvent::Lost { id, t_s, silent_s }) => {
                        event(&last, "vehicle_lost", AlertState::Raised, Severity::Warning, t_s, format!("vehicle {id}: nothing heard for {silent_s:.0} s"))
                    }
                    Some(FleetEvent::Back { id, t_s }) => {
                        event(&last, "vehicle_lost", AlertState::Cleared, Severity::Warning, t_s, format!("vehicle {id} heard again"))
                    }
                    Some(d @ FleetEvent::Dropped { .. }) => { dropped = Some(d); None }
                };
                if let Some(r) = report {
                    fanout.send(r).await;
                }
            }
        }
    }
    // The drop is told before the chain's input closes, so it is queued by now even if
    // the reports ended before the loop above read it.
    while let Ok(e) = events.try_recv() {
        if matches!(e, FleetEvent::Dropped { .. }) {
            dropped = Some(e);
        }
    }
    if let Some(FleetEvent::Dropped { id, t_s, silent_s }) = dropped {
        let msg = format!("vehicle {id} dropped: nothing heard for {silent_s:.0} s");
        if let Some(r) = event(
            &last,
            "vehicle_dropped",
            AlertState::Raised,
            Severity::Info,
            t_s,
            msg,
        ) {
            fanout.send(r).await;
        }
    }
}
