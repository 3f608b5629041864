//! Energy along a flown-on-paper plan: every power model on the trajectory's windows,
//! energy per leg, a P50 and a P90, and the cheap live re-forecast of what is left.
//!
//! ## Formulas
//!
//! - Each model `m` predicts power `P_m(t)` (W) on windows of T samples built from the
//!   trajectory (the window ending `target_lag` samples after t, as the model was trained).
//!   Models run on every `stride`-th sample and the power is held in between: a plan flies
//!   minutes of steady motion, and 500 waypoints must forecast in milliseconds.
//! - **P50 power** `P50(t) = k · P_f(t)`: the *forecast model* `f` (the `[forecast.calibration]`
//!   `model` key) times its correction `k` (`scale`), both fitted on training flights by
//!   `dronewatt plan-eval` as the median of measured ∫V·I over the model's forecast of the
//!   flight's plan: what the model misses systematically (the plan's own simplifications —
//!   stop-and-go legs, the rotors' spin-up — and the model's bias) is removed, by flight.
//!   The power is also weighted by phase (`phase_scale`: vertical climb, vertical
//!   descent, the rest), fitted on the training flights' halves, so that what is left at
//!   any point of the plan, not only the whole, is right.
//! - **P90 energy** `E90 = r90 · E50` with `r90` (`p90_ratio`) the 90th percentile of
//!   measured/forecast over the same training flights after the correction: the by-flight
//!   residual spread, which holds the day-to-day wind, battery temperature and pilot
//!   variation the plan does not know. A `--wind` shifts the P50 through the models (the
//!   airspeed and headwind they read); the spread covers what wind forecasts miss.
//! - Energy `E = Σ P·Δt / 3600` (Wh), rectangle rule on the sample grid, per leg and in all.
//! - **Live re-forecast**: the remaining energy from trajectory sample `k` is
//!   `E50(end) − E50(k)`, read off the cumulative energy; finding `k` from MISSION_CURRENT
//!   and the vehicle's position is a bounded nearest-point search
//!   ([`super::trajectory::Trajectory::locate`]). Optionally scaled by what the flight has
//!   shown so far: `s = clamp(E_measured(0..k) / E50(0..k), 0.8, 1.25)` blended as
//!   `1 + w·(s − 1)` with `w = live_weight`.
//!
//! Pure: no I/O.

use super::trajectory::Trajectory;
use crate::telemetry::idx;
use crate::model::{PowerModel, Prediction};
use crate::window::Window;

/// The fitted correction of the forecast (`[forecast.calibration]`).
#[derive(Debug, Clone, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Calibration {
    /// The model whose power, corrected, is the P50 (a name from `dronewatt eval`'s
    /// table). Default: the one `plan-eval` picked on the training flights.
    pub model: String,
    /// Multiplier on that model's power (measured over forecast energy, median over the
    /// training flights). Default: `plan-eval`'s fit.
    pub scale: f64,
    /// P90 energy over P50 energy (90th percentile of measured over corrected forecast on
    /// the training flights). Default: `plan-eval`'s fit.
    pub p90_ratio: f64,
    /// Weight of the flight's own measured/forecast ratio in a live re-forecast, 0..1.
    /// Default: `plan-eval`'s choice on the training flights.
    pub live_weight: f64,
    /// How many recent training flights `plan-eval` fits `scale` on, before each flight
    /// (0 = all); informational here, `scale` is what the forecast uses.
    pub recent_flights: usize,
    /// Weights on the forecast model's power by phase: vertical climb, vertical descent,
    /// anything else ([`phase_of`]), fitted by `plan-eval` on the training flights' two
    /// halves. Default: `plan-eval`'s fit.
    pub phase_scale: [f64; 3],
}

impl Calibration {
    /// No correction: the model's own power (what `plan-eval` fits from).
    pub fn uncorrected() -> Self {
        Self { model: String::new(), scale: 1.0, p90_ratio: 1.0, live_weight: 0.0, recent_flights: 0, phase_scale: [1.0; 3] }
    }
}

/// Phase of a trajectory sample for [`Calibration::phase_scale`]: 0 vertical climb, 1
/// vertical descent (|v_z| > 0.5 m/s with under 1 m/s horizontal), 2 anything else.
pub fn phase_of(s: &crate::telemetry::Sample) -> usize {
    let f = &s.features;
    let vh = f[idx::VX].hypot(f[idx::VY]);
    if vh < 1.0 && f[idx::VZ] > 0.5 {
        0
    } else if vh < 1.0 && f[idx::VZ] < -0.5 {
        1
    } else {
        2
    }
}

impl Default for Calibration {
    fn default() -> Self {
        // Fitted by `dronewatt plan-eval` on the M100 training flights (178 route flights, test
        // flights excluded), with the calibrated profile's physics models.
        Self {
            model: "tseng_solo_cal".into(),
            scale: 0.9992,
            p90_ratio: 1.0288,
            live_weight: 0.00,
            recent_flights: 20,
            phase_scale: [1.3111, 0.9514, 0.9654],
        }
    }
}

impl Calibration {
    /// Range checks; the message names the key.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.scale.is_finite() && self.scale > 0.0) {
            return Err(format!("forecast.calibration.scale = {}: must be > 0", self.scale));
        }
        if !(self.p90_ratio.is_finite() && self.p90_ratio >= 1.0) {
            return Err(format!("forecast.calibration.p90_ratio = {}: must be ≥ 1", self.p90_ratio));
        }
        if !(0.0..=1.0).contains(&self.live_weight) {
            return Err(format!("forecast.calibration.live_weight = {}: must be in [0, 1]", self.live_weight));
        }
        Ok(())
    }
}

/// One leg's forecast.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LegForecast {
    /// Plan item served.
    pub item: usize,
    /// `takeoff`, `waypoint`, …
    pub label: String,
    /// Start, from take-off, s.
    pub t_start_s: f64,
    /// Duration, s.
    pub duration_s: f64,
    /// Horizontal distance, m.
    pub distance_m: f64,
    /// P50 energy, Wh.
    pub energy_p50_wh: f64,
    /// P90 energy, Wh.
    pub energy_p90_wh: f64,
}

/// A plan's energy forecast.
#[derive(Debug, Clone, serde::Serialize)]
pub struct MissionForecast {
    /// The forecast model (P50 = its power × `scale`).
    pub model: String,
    /// Every model that ran, with its own uncorrected energy for the whole plan, Wh.
    pub models_raw_wh: Vec<(String, f64)>,
    /// Per leg.
    pub legs: Vec<LegForecast>,
    /// Whole plan, s.
    pub duration_s: f64,
    /// Whole plan, m.
    pub distance_m: f64,
    /// Whole plan, P50, Wh.
    pub energy_p50_wh: f64,
    /// Whole plan, P90, Wh.
    pub energy_p90_wh: f64,
    /// P90 / P50.
    pub p90_ratio: f64,
    /// Cumulative P50 energy at the end of each sample, Wh (P90 is `p90_ratio` × this).
    #[serde(skip)]
    pub cum_p50_wh: Vec<f64>,
    /// Sample period, s.
    #[serde(skip)]
    pub dt_s: f64,
}

/// Run `models` on `traj` and integrate. `window_t` is the window length T, `stride` the
/// sample step at which models run (≥ 1). The model named by `cal.model` gives the P50
/// (when it did not run, the first model that did: its name is in the result).
pub fn forecast(traj: &Trajectory, models: &mut [Box<dyn PowerModel>], cal: &Calibration, window_t: usize, stride: usize) -> MissionForecast {
    let n = traj.samples.len();
    let stride = stride.max(1);
    let t = window_t.max(1);
    let mut powers: Vec<(String, Vec<f32>)> = Vec::with_capacity(models.len());
    let mut windows: Vec<Window> = Vec::new();
    let mut preds: Vec<Prediction> = Vec::new();
    let mut at = Vec::new();
    let mut built_for = None;
    for m in models.iter_mut() {
        let lag = m.target_lag();
        // windows ending at j + lag for j = 0, stride, 2·stride, …; clamped at both ends
        // (before take-off and after touchdown the vehicle is still). Models with the same
        // lag share them.
        if built_for == Some(lag) {
            m.predict(&windows, &mut preds);
            powers.push((m.name().to_string(), hold(&at, &preds, n)));
            continue;
        }
        built_for = Some(lag);
        windows.clear();
        at.clear();
        let mut j = 0;
        while j < n {
            let end = (j + lag).min(n - 1);
            let samples: Vec<_> = if end + 1 >= t {
                traj.samples[end + 1 - t..=end].to_vec()
            } else {
                (0..t)
                    .map(|i| {
                        let mut s = traj.samples[(end + i + 1).saturating_sub(t)].clone();
                        s.t_s = (end as f64 + i as f64 + 1.0 - t as f64) * traj.dt_s;
                        s
                    })
                    .collect()
            };
            windows.push(Window { samples, arrived: None });
            at.push(j);
            j += stride;
        }
        m.predict(&windows, &mut preds);
        powers.push((m.name().to_string(), hold(&at, &preds, n)));
    }
    integrate(traj, &powers, cal)
}

/// Per-sample power from predictions at samples `at`, each held until the next.
fn hold(at: &[usize], preds: &[Prediction], n: usize) -> Vec<f32> {
    let mut p = vec![0.0f32; n];
    for (w, (&j0, pr)) in at.iter().zip(preds).enumerate() {
        let j1 = at.get(w + 1).copied().unwrap_or(n);
        let v = if pr.power_w.is_finite() { pr.power_w.max(0.0) } else { 0.0 };
        p[j0..j1].fill(v);
    }
    p
}

fn integrate(traj: &Trajectory, powers: &[(String, Vec<f32>)], cal: &Calibration) -> MissionForecast {
    let dt_h = traj.dt_s / 3600.0;
    let models_raw_wh: Vec<(String, f64)> = powers.iter().map(|(n, p)| (n.clone(), p.iter().map(|&w| f64::from(w)).sum::<f64>() * dt_h)).collect();
    let chosen = powers.iter().find(|(n, _)| *n == cal.model).or_else(|| powers.first());
    let (model, p) = match chosen {
        Some((n, p)) => (n.clone(), p.as_slice()),
        None => (String::from("none"), &[][..]),
    };
    let mut cum = Vec::with_capacity(p.len());
    let mut e = 0.0;
    for (s, &w) in traj.samples.iter().zip(p) {
        e += cal.scale * cal.phase_scale[phase_of(s)] * f64::from(w) * dt_h;
        cum.push(e);
    }
    let at = |i: usize| if i == 0 { 0.0 } else { cum.get(i - 1).copied().unwrap_or(e) };
    let legs = traj
        .legs
        .iter()
        .map(|l| {
            let e50 = at(l.samples.end) - at(l.samples.start);
            LegForecast {
                item: l.item,
                label: l.label.clone(),
                t_start_s: l.t_start_s,
                duration_s: l.t_end_s - l.t_start_s,
                distance_m: l.distance_m,
                energy_p50_wh: e50,
                energy_p90_wh: e50 * cal.p90_ratio,
            }
        })
        .collect::<Vec<_>>();
    MissionForecast {
        model,
        models_raw_wh,
        distance_m: legs.iter().map(|l| l.distance_m).sum(),
        legs,
        duration_s: traj.duration_s(),
        energy_p50_wh: e,
        energy_p90_wh: e * cal.p90_ratio,
        p90_ratio: cal.p90_ratio,
        cum_p50_wh: cum,
        dt_s: traj.dt_s,
    }
}

/// What is left of the mission from one point of it.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Remaining {
    /// Trajectory sample the vehicle is at.
    pub sample: usize,
    /// Planned time left, s.
    pub time_s: f64,
    /// P50 energy left, Wh.
    pub energy_p50_wh: f64,
    /// P90 energy left, Wh.
    pub energy_p90_wh: f64,
}

impl MissionForecast {
    /// P50 energy from the start to the end of sample `k`, Wh.
    pub fn energy_to_wh(&self, k: usize) -> f64 {
        if self.cum_p50_wh.is_empty() {
            return 0.0;
        }
        self.cum_p50_wh[k.min(self.cum_p50_wh.len() - 1)]
    }

    /// The live re-forecast: the rest of the mission (and its landing) from trajectory
    /// sample `k`, scaled by the flight's own showing so far when `measured_so_far_wh` is
    /// given (see the module docs; `live_weight` = 0 ignores it). O(1).
    pub fn remaining_from(&self, k: usize, measured_so_far_wh: Option<f64>, live_weight: f64) -> Remaining {
        let total = self.energy_p50_wh;
        let done = self.energy_to_wh(k);
        let mut left = (total - done).max(0.0);
        if let Some(m) = measured_so_far_wh {
            if done > 0.05 * total && m.is_finite() && m > 0.0 {
                let s = (m / done).clamp(0.8, 1.25);
                left *= 1.0 + live_weight * (s - 1.0);
            }
        }
        let n = self.cum_p50_wh.len();
        Remaining {
            sample: k,
            time_s: (n.saturating_sub(k + 1)) as f64 * self.dt_s,
            energy_p50_wh: left,
            energy_p90_wh: left * self.p90_ratio,
        }
    }

    /// Usable energy left after the mission at P50 and P90: `capacity − reserve − E`, Wh.
    pub fn margins_wh(&self, capacity_wh: f64, reserve_pct: f64) -> (f64, f64) {
        let usable = capacity_wh * (1.0 - reserve_pct / 100.0);
        (usable - self.energy_p50_wh, usable - self.energy_p90_wh)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mission::plan::{GeoPoint, Plan};
    use crate::mission::trajectory::{fly, Conditions, KinematicsConfig, Wind};

    fn plan(n: usize) -> Plan {
        let home = GeoPoint { lat_deg: 40.0, lon_deg: -80.0, alt_m: 300.0 };
        let wps: Vec<GeoPoint> = (0..n).map(|i| GeoPoint { lat_deg: 40.0 + 0.001 * (i % 2) as f64, lon_deg: -80.0 + 0.001 * i as f64, alt_m: 30.0 }).collect();
        Plan::from_waypoints("zigzag", home, &wps, 8.0)
    }

    fn run(payload_g: f64, wind: Wind, cal: &Calibration) -> MissionForecast {
        let tr = fly(&plan(6), &KinematicsConfig::default(), &Conditions { wind, payload_g, speed_m_s: None, rate_hz: 10.0 });
        let mut models = crate::model::physics::models(&crate::model::profile::VehicleProfile::m100());
        forecast(&tr, &mut models, cal, 10, 5)
    }

    #[test]
    fn energy_adds_up_and_grows_with_payload_and_wind() {
        let cal = Calibration { model: "dandrea".into(), scale: 1.0, p90_ratio: 1.1, live_weight: 0.0, recent_flights: 0, phase_scale: [1.0; 3] };
        let f = run(0.0, Wind::default(), &cal);
        assert_eq!(f.model, "dandrea");
        let legs: f64 = f.legs.iter().map(|l| l.energy_p50_wh).sum();
        assert!((legs - f.energy_p50_wh).abs() < 1e-9, "legs sum to the whole: {legs} vs {}", f.energy_p50_wh);
        assert!((f.energy_p90_wh / f.energy_p50_wh - 1.1).abs() < 1e-12);
        let mean_w = f.energy_p50_wh * 3600.0 / f.duration_s;
        assert!((150.0..1500.0).contains(&mean_w), "an M100's power: {mean_w} W");
        let heavy = run(500.0, Wind::default(), &cal);
        assert!(heavy.energy_p50_wh > f.energy_p50_wh * 1.02, "payload costs energy");
        let windy = run(0.0, "8@0".parse().unwrap(), &cal);
        assert!(windy.energy_p50_wh > f.energy_p50_wh, "wind costs energy");
        let scaled = run(0.0, Wind::default(), &Calibration { scale: 1.2, ..cal.clone() });
        assert!((scaled.energy_p50_wh / f.energy_p50_wh - 1.2).abs() < 1e-9);
    }

    #[test]
    fn the_live_reforecast_reads_what_is_left() {
        let cal = Calibration { model: "dandrea".into(), scale: 1.0, p90_ratio: 1.1, live_weight: 1.0, recent_flights: 0, phase_scale: [1.0; 3] };
        let f = run(0.0, Wind::default(), &cal);
        let n = f.cum_p50_wh.len();
        let r0 = f.remaining_from(0, None, 1.0);
        assert!((r0.energy_p50_wh - f.energy_p50_wh).abs() < 0.01 * f.energy_p50_wh);
        let half = f.remaining_from(n / 2, None, 1.0);
        assert!(half.energy_p50_wh < r0.energy_p50_wh && half.energy_p50_wh > 0.0);
        assert!((half.time_s - f.duration_s / 2.0).abs() < 1.0);
        // a flight drawing 10 % more than forecast so far is forecast 10 % more for the rest
        let done = f.energy_to_wh(n / 2);
        let hot = f.remaining_from(n / 2, Some(done * 1.1), 1.0);
        assert!((hot.energy_p50_wh / half.energy_p50_wh - 1.1).abs() < 1e-9);
        assert_eq!(f.remaining_from(n - 1, None, 1.0).energy_p50_wh, 0.0);
    }
}
