//! The dashboard fed by lines rather than by a chain's reports: `dronewatt dashboard --nats`
//! reads the fleet's workers' `estimate` and `alert` lines off NATS
//! ([`crate::sink::jsonl_read`]) and hands each here as a [`Feed`]. An estimate goes
//! through the very path a monitor's report takes; an alert event, which comes on a line
//! of its own, is logged against its vehicle at once (the banner and the fleet table's
//! worst alert follow it), as a monitor logs the alerts its report carries.

use anyhow::Result;
use tokio::sync::mpsc;
use tokio_util::sync::CancellationToken;

use super::{Dash, Fleet, Shared, WebSinkConfig};
use crate::report::{AlertEvent, AlertState, Report, VehicleId};

/// One thing the dashboard is told.
#[derive(Debug)]
pub enum Feed {
    /// A vehicle's report (its estimate; the alerts it carries, if any).
    Report(Box<Report>),
    /// An alert event about a vehicle.
    Alert(VehicleId, AlertEvent),
}

/// Serve the dashboard on `listener` ([`super::serve`]'s guards, routes and page) fed by
/// `rx` until it closes, then `cfg.linger_s` more or until `shutdown`.
pub async fn serve(
    cfg: WebSinkConfig,
    listener: tokio::net::TcpListener,
    mut rx: mpsc::Receiver<Feed>,
    shutdown: CancellationToken,
) -> Result<()> {
    let fed = cfg.clone();
    super::serve_fed(
        cfg,
        listener,
        shutdown,
        None,
        move |dash: Shared| async move {
            while let Some(f) = rx.recv().await {
                if let Ok(mut d) = dash.lock() {
                    d.feed(f, &fed);
                }
            }
        },
    )
    .await
}

impl Fleet {
    fn feed(&mut self, f: Feed, cfg: &WebSinkConfig) {
        match f {
            Feed::Report(r) => self.add(&r, cfg),
            Feed::Alert(v, a) => {
                if a.rule == "vehicle_dropped" && a.state == AlertState::Raised {
                    self.vehicles.remove(&v);
                } else {
                    self.vehicles.entry(v).or_default().alert(&a);
                }
            }
        }
    }
}

impl Dash {
    /// An alert event on a line of its own: logged, and the banner's worst alert follows.
    fn alert(&mut self, a: &AlertEvent) {
        self.record(a);
        let worst = self.worst();
        if let Some(l) = self.latest.as_mut() {
            l.pilot.worst = worst;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sink::jsonl_read::{read, Line};

    fn feed_of(line: &str) -> Feed {
        match read(line.as_bytes()).unwrap() {
            Line::Estimate(r) => Feed::Report(r),
            Line::Alert(v, a) => Feed::Alert(v, a),
        }
    }

    #[test]
    fn lines_fill_the_fleet_table_and_an_alert_line_sets_the_banner() {
        let est = |sys: u8, t: f64| {
            format!(
                r#"{{"type":"estimate","system_id":{sys},"t":{t},"vehicle_class":"multirotor","measured_w":300.0,"models":{{"lstm":310.0}},"energy_used_wh":1.5,"remaining_wh":80.0,"remaining_pct":60.0,"remaining_source":"battery","time_to_empty_s":900.0,"home_margin_wh":50.0,"forecast_adapted":false,"forecast_model":"lstm","forecast_why":"default","capacity_wh":133.0,"capacity_source":"config","cell_count":4,"cell_count_source":"config","chemistry":"lipo","chemistry_source":"config","battery_v":15.2}}"#
            )
        };
        let cfg = WebSinkConfig::default();
        let mut f = Fleet::default();
        f.feed(feed_of(&est(1, 10.0)), &cfg);
        f.feed(feed_of(&est(2, 10.5)), &cfg);
        f.feed(
            feed_of(r#"{"type":"alert","system_id":2,"t":10.5,"rule":"low_margin","severity":"critical","state":"raised","message":"margin 2 Wh"}"#),
            &cfg,
        );
        let rows = f.rows();
        assert_eq!(rows.len(), 2);
        assert_eq!(rows[0].remaining_wh, Some(80.0));
        assert!(rows[0].worst.is_none());
        assert_eq!(
            rows[1].worst.as_ref().map(|w| w.0.as_str()),
            Some("low_margin")
        );
        let d = &f.vehicles[&VehicleId::single(2)];
        let worst = d.latest.as_ref().and_then(|l| l.pilot.worst.as_ref());
        assert_eq!(worst.map(|w| w.message.as_str()), Some("margin 2 Wh"));
        f.feed(
            feed_of(r#"{"type":"alert","system_id":1,"t":11,"rule":"vehicle_dropped","severity":"warning","state":"raised","message":"gone"}"#),
            &cfg,
        );
        assert_eq!(f.rows().len(), 1);
    }
}
