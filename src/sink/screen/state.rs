//! What the screen knows between two frames: each vehicle's newest report, its power
//! history (measured, the forecast model's estimate, the forecast) over the last minutes,
//! the alerts standing, the alerts as they fired, which vehicle is selected, and the link's
//! rate. Kept apart from the drawing so it can be tested without a terminal.

use std::collections::{BTreeMap, VecDeque};
use std::sync::Arc;

use crate::report::{AlertEvent, AlertState, Report, Severity, VehicleId};

/// Seconds of power history the chart shows (source clock).
pub const HISTORY_S: f64 = 300.0;
/// Most points of history kept per vehicle (a 10 Hz chain fills 5 minutes with 3000).
const HISTORY_POINTS: usize = 4000;
/// Alerts kept in the scrolling list.
const ALERTS_KEPT: usize = 200;

/// One point of a vehicle's power history, W (absent where not known at that moment).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PowerPoint {
    pub t_s: f64,
    pub measured_w: Option<f64>,
    /// The forecast model's estimate (adapted when the forecast follows the adapted one).
    pub model_w: Option<f64>,
    /// The smoothed power the forecast assumes.
    pub forecast_w: Option<f64>,
}

/// One vehicle as the screen shows it.
#[derive(Debug, Clone)]
pub struct VehicleView {
    pub report: Arc<Report>,
    /// Alerts raised and not yet cleared: rule → severity.
    pub active: BTreeMap<String, Severity>,
    /// Their messages and times as raised: rule → (message, t).
    pub messages: BTreeMap<String, (String, f64)>,
    pub history: VecDeque<PowerPoint>,
}

impl VehicleView {
    /// The most severe alert standing.
    pub fn worst(&self) -> Option<(&str, Severity)> {
        self.active
            .iter()
            .min_by_key(|(_, &s)| s)
            .map(|(r, &s)| (r.as_str(), s))
    }

    /// The most severe alert standing, with its message (the banner).
    pub fn worst_alert(&self) -> Option<crate::sink::pilot::WorstAlert> {
        crate::sink::pilot::worst_of(&self.active, |rule| self.messages.get(rule).cloned())
    }
}

/// An alert as it fired, with the vehicle it is about.
#[derive(Debug, Clone)]
pub struct FiredAlert {
    pub vehicle: VehicleId,
    pub event: AlertEvent,
}

/// Everything the screen draws from.
#[derive(Debug, Default)]
pub struct ScreenState {
    pub vehicles: BTreeMap<VehicleId, VehicleView>,
    /// Newest first.
    pub alerts: VecDeque<FiredAlert>,
    /// The selected vehicle (the first one until a key picks another).
    selected: Option<VehicleId>,
    /// Link messages a second, from the ingest counters.
    pub rate: f64,
    /// The newest log lines (stderr while the screen is up), newest last.
    pub log: VecDeque<String>,
    /// The reports have ended (a replay's last): the screen holds the final state until a
    /// key.
    pub ended: bool,
}

/// The forecast model's estimate in a report: its adapted value when the forecast follows
/// the adapted one, else its raw value.
pub fn forecast_model_w(r: &Report) -> Option<f64> {
    let name = r.energy.forecast_model.as_deref()?;
    let m = r.estimate.models.iter().find(|m| m.name == name)?;
    let w = if r.energy.forecast_adapted {
        m.adapted_w.unwrap_or(m.power_w)
    } else {
        m.power_w
    };
    Some(f64::from(w)).filter(|w| w.is_finite())
}

impl ScreenState {
    /// Take one report in: alerts first (a dropped vehicle leaves the list), then the
    /// vehicle's newest state and a point of its history.
    pub fn push(&mut self, r: Arc<Report>) {
        for a in &r.alerts {
            self.alerts.push_front(FiredAlert {
                vehicle: r.vehicle,
                event: a.clone(),
            });
        }
        self.alerts.truncate(ALERTS_KEPT);
        if r.alerts
            .iter()
            .any(|a| a.rule == "vehicle_dropped" && a.state == AlertState::Raised)
        {
            self.vehicles.remove(&r.vehicle);
            return;
        }
        let point = PowerPoint {
            t_s: r.estimate.t_s,
            measured_w: r
                .estimate
                .sample
                .measured_w
                .map(f64::from)
                .filter(|w| w.is_finite()),
            model_w: forecast_model_w(&r),
            forecast_w: r.energy.forecast_w.filter(|w| w.is_finite()),
        };
        let v = self
            .vehicles
            .entry(r.vehicle)
            .or_insert_with(|| VehicleView {
                report: r.clone(),
                active: BTreeMap::new(),
                messages: BTreeMap::new(),
                history: VecDeque::new(),
            });
        for a in &r.alerts {
            match a.state {
                AlertState::Raised => {
                    v.active.insert(a.rule.clone(), a.severity);
                    v.messages.insert(a.rule.clone(), (a.message.clone(), a.t));
                }
                AlertState::Cleared => {
                    v.active.remove(&a.rule);
                    v.messages.remove(&a.rule);
                }
            };
        }
        // A silent tick (nothing heard: no model ran) adds no point; a clock that went
        // backwards (a new log) starts the history again.
        if !r.estimate.models.is_empty() || point.measured_w.is_some() {
            if v.history.back().is_some_and(|p| p.t_s > point.t_s) {
                v.history.clear();
            }
            v.history.push_back(point);
        }
        while v.history.len() > HISTORY_POINTS
            || v.history
                .front()
                .is_some_and(|p| p.t_s < point.t_s - HISTORY_S)
        {
            v.history.pop_front();
        }
        v.report = r;
    }

    /// The selected vehicle's system id (the first vehicle when none was picked, or the
    /// picked one is gone).
    pub fn selected_id(&self) -> Option<VehicleId> {
        match self.selected {
            Some(id) if self.vehicles.contains_key(&id) => Some(id),
            _ => self.vehicles.keys().next().copied(),
        }
    }

    /// The selected vehicle.
    pub fn selected(&self) -> Option<&VehicleView> {
        self.selected_id().and_then(|id| self.vehicles.get(&id))
    }

    /// The selected vehicle's row in the list.
    pub fn selected_index(&self) -> Option<usize> {
        let id = self.selected_id()?;
        self.vehicles.keys().position(|&k| k == id)
    }

    /// Move the selection `by` rows (arrow keys), staying within the list.
    pub fn move_selection(&mut self, by: isize) {
        let Some(i) = self.selected_index() else {
            return;
        };
        let n = self.vehicles.len() as isize;
        let j = (i as isize + by).clamp(0, n - 1) as usize;
        self.selected = self.vehicles.keys().nth(j).copied();
    }

    /// Whether there are several vehicles (the vehicle list shows).
    pub fn is_fleet(&self) -> bool {
        self.vehicles.len() > 1
    }

    /// Keep one log line (newest last, a few kept).
    pub fn log_line(&mut self, line: String) {
        self.log.push_back(line);
        while self.log.len() > 50 {
            self.log.pop_front();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::Sample;
    use crate::report::{EnergyState, Estimate, ModelEstimate};

    fn report(id: u8, t_s: f64, measured: f32, alerts: Vec<AlertEvent>) -> Arc<Report> {
        let mut lstm = ModelEstimate::new("lstm", 200.0, None);
        lstm.adapted_w = Some(230.0);
        Arc::new(Report {
            estimate: Estimate {
                t_s,
                sample: Sample::new(t_s, [0.0; crate::features::N_FEATURES], Some(measured)),
                models: vec![ModelEstimate::new("dandrea", 180.0, None), lstm],
                arrived: None,
            },
            energy: EnergyState {
                forecast_model: Some("lstm".into()),
                forecast_adapted: true,
                forecast_w: Some(225.0),
                ..Default::default()
            },
            alerts,
            vehicle: id.into(),
        })
    }

    fn alert(rule: &str, state: AlertState) -> AlertEvent {
        AlertEvent {
            t: 1.0,
            rule: rule.into(),
            severity: Severity::Critical,
            state,
            message: "m".into(),
        }
    }

    #[test]
    fn history_follows_the_forecast_model_and_forgets_old_minutes() {
        let mut s = ScreenState::default();
        for i in 0..700 {
            s.push(report(1, f64::from(i), 250.0, vec![]));
        }
        let v = s.selected().unwrap();
        let (first, last) = (v.history.front().unwrap(), v.history.back().unwrap());
        assert_eq!(last.model_w, Some(230.0), "adapted lstm");
        assert_eq!(last.measured_w, Some(250.0));
        assert!(last.t_s - first.t_s <= HISTORY_S, "{first:?} {last:?}");
        // A new log (the clock went back) starts again.
        s.push(report(1, 3.0, 250.0, vec![]));
        assert_eq!(s.selected().unwrap().history.len(), 1);
    }

    #[test]
    fn selection_moves_within_the_fleet_and_alerts_stand_until_cleared() {
        let mut s = ScreenState::default();
        s.push(report(3, 1.0, 1.0, vec![]));
        s.push(report(
            1,
            1.0,
            1.0,
            vec![alert("home_margin", AlertState::Raised)],
        ));
        s.push(report(2, 1.0, 1.0, vec![]));
        assert!(s.is_fleet());
        assert_eq!(s.selected_id(), Some(VehicleId::single(1)));
        s.move_selection(1);
        assert_eq!(s.selected_id(), Some(VehicleId::single(2)));
        s.move_selection(5);
        assert_eq!(s.selected_id(), Some(VehicleId::single(3)));
        s.move_selection(-9);
        assert_eq!(s.selected_id(), Some(VehicleId::single(1)));
        assert_eq!(
            s.selected().unwrap().worst(),
            Some(("home_margin", Severity::Critical))
        );
        s.push(report(
            1,
            2.0,
            1.0,
            vec![alert("home_margin", AlertState::Cleared)],
        ));
        assert_eq!(s.selected().unwrap().worst(), None);
        assert_eq!(s.alerts.len(), 2);
        assert_eq!(s.alerts[0].event.state, AlertState::Cleared, "newest first");
        // A dropped vehicle leaves the list; the selection falls back to the first.
        s.move_selection(2);
        s.push(report(
            3,
            2.0,
            1.0,
            vec![alert("vehicle_dropped", AlertState::Raised)],
        ));
        assert_eq!(s.vehicles.len(), 2);
        assert_eq!(s.selected_id(), Some(VehicleId::single(1)));
    }
}
