//! The pack's loaded-voltage forecast for the rest of the flight: the lowest voltage, when
//! it comes, and the time to the low threshold (the circuit's path, and the measured
//! voltage's trend, whichever is sooner).

use super::*;

impl Pack {
    /// Recompute the loaded-voltage forecast for the rest of the flight.
    pub(super) fn forecast(&mut self, rest_of_flight: Option<Load>, facts: &BatteryFacts) {
        let Some(est) = self.est.as_ref() else { return };
        let low = low_v(facts);
        self.now.low_v = Some(low);
        let Some(Load {
            first_w: p,
            first_s: horizon,
            then_w,
        }) = rest_of_flight.filter(|l| l.first_w.is_finite() && l.first_w > 1.0)
        else {
            (
                self.now.v_min_forecast,
                self.now.time_to_low_v_s,
                self.now.usable_wh,
            ) = (None, None, None);
            return;
        };
        let e_now = est.energy_wh();
        let reserve_wh = self.reserve_frac * self.now.curve_wh.unwrap_or(0.0);
        let rest_s = horizon
            .unwrap_or(3600.0 * (e_now - reserve_wh) / p)
            .clamp(0.0, FORECAST_HORIZON_S);
        // The lowest loaded voltage over the rest of the flight, and when: the constant
        // power's path dipped by the transients it lacks (battery::forecast::dip).
        let frac = if self.flown {
            SAG_IN_FLIGHT
        } else {
            SAG_PREFLIGHT
        };
        let lowest = lowest_dip(est, constant(p, FORECAST_STEP_S, rest_s), frac);
        self.now.v_min_forecast = lowest.map(|(s, v)| (v, s.t_s));
        // Flying the rest at that power, then on at the flight's sustained power, stopping
        // where it crosses the low threshold.
        let first_s = horizon
            .unwrap_or(FORECAST_HORIZON_S)
            .clamp(0.0, FORECAST_HORIZON_S);
        let then_w = Some(then_w)
            .filter(|w| w.is_finite() && *w > 1.0)
            .unwrap_or(p);
        let profile = constant(p, FORECAST_STEP_S, first_s).chain(constant(
            then_w,
            FORECAST_STEP_S,
            FORECAST_HORIZON_S - first_s,
        ));
        let on = first_crossing(est, profile, low);
        // In flight, the sooner of the circuit's crossing and the measured voltage's own
        // trend's (battery::trend), where it shows one.
        let trend = self
            .trend
            .time_to(low, p)
            .filter(|s| *s <= FORECAST_HORIZON_S);
        self.now.time_to_low_v_s = match (trend, on.map(|s| s.t_s)) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        self.now.usable_wh = Some(match on {
            Some(s) => (e_now - s.energy).max(0.0),
            // Never crosses within the horizon: all of it down to the floor.
            None => e_now,
        });
    }
}
