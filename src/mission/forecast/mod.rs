//! Energy along a flown-on-paper plan: every power model on the trajectory's windows,
//! energy per leg, a P50 and a P90, and the cheap live re-forecast of what is left.
//!
//! ## Formulas
//!
//! - Each model `m` predicts power `P_m(t)` (W) on windows of T samples built from the
//!   trajectory (the window ending `target_lag` samples after t, as the model was trained).
//!   Models run on every `stride`-th sample and the power is held in between: a plan flies
//!   minutes of steady motion, and 500 waypoints must forecast in milliseconds.
//! - **P50 power**: the mean of the *forecast's members* (`[forecast.calibration] members`),
//!   each a model `f` times its own correction `k` (`scale`), fitted on training flights by
//!   `dronewatt-lab plan-eval` as the median of measured ∫V·I over the model's forecast of the
//!   flight's plan: what the model misses systematically (the plan's own simplifications —
//!   stop-and-go legs, the rotors' spin-up — and the model's bias) is removed, by flight.
//!   Each member's power is also weighted by phase (`phase_scale`: vertical climb, vertical
//!   descent, the rest) and the vertical work rate m·g·v_z added with its own weights
//!   (`climb_work`, climbing and descending), all fitted on the training flights' halves,
//!   so that what is left at any point of the plan, not only the whole, is right:
//!   `P_f,k(t) = k · (w_phase(t) · P_f(t) + w_up · m·g·max(v_z, 0) + w_down · m·g·max(−v_z, 0))`,
//!   `P50(t) = mean over members of P_f,k(t)`.
//!   The work term is what makes a slanted climb (a leg that climbs while it flies
//!   forward) cost its climb: forward-flight power plus m·g·v_z over the rotors'
//!   efficiency, the physics of any climb, where a weight on vertical climbs alone
//!   would miss it. Several members: the training flights (one route, nearly all of them)
//!   cannot rank models whose errors there differ by less than their noise, and models of
//!   different structure err differently on a route they never flew; their mean hedges
//!   what no single one of them can be shown to get right.
//! - **P90 energy** `E90 = r90 · E50` with `r90` (`p90_ratio`) the 90th percentile of
//!   measured/forecast over the same training flights after the correction: the by-flight
//!   residual spread, which holds the day-to-day wind, battery temperature and pilot
//!   variation the plan does not know. A `--wind` shifts the P50 through the models (the
//!   airspeed and headwind they read); the spread covers what wind forecasts miss.
//! - Energy `E = Σ P·Δt / 3600` (Wh), rectangle rule on the sample grid, per leg and in all.
//! - **Live re-forecast**: the remaining energy from trajectory sample `k` is
//!   `E50(end) − E50(k)`, read off the cumulative energy; finding `k` from MISSION_CURRENT
//!   and the vehicle's position is a bounded nearest-point search
//!   ([`super::trajectory::Trajectory::locate`]). Scaled by what the flight has shown so
//!   far ([`live_scaled`], the one function the monitor applies and `plan-eval` scores):
//!   `s = clamp(E_measured(0..k) / E50(0..k), 0.8, 1.25)` blended as `1 + w·(s − 1)` with
//!   `w = live_weight`.
//!
//! Pure: no I/O.

use super::trajectory::Trajectory;
use crate::features::idx;
use crate::model::{PowerModel, Prediction};
use crate::telemetry::window::Window;

/// P90 over P50 of a vehicle flown on models no one calibrated for it (a plane, a VTOL, a
/// multirotor other than the M100): wide, for what its uncorrected models may miss.
pub const UNCALIBRATED_P90: f64 = 1.3;

/// One model of the forecast with its own fitted correction (an entry of
/// `[forecast.calibration] members`).
#[derive(Debug, Clone, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Member {
    /// The model (a name from `dronewatt-lab eval`'s table).
    pub model: String,
    /// Multiplier on its weighted power (measured over forecast energy, median over the
    /// recent training flights). Default 1.
    pub scale: f64,
    /// How many recent training flights `plan-eval` fits `scale` on, before each flight
    /// (0 = all); informational here, `scale` is what the forecast uses.
    pub recent_flights: usize,
    /// Weights on the model's power by phase: vertical climb, vertical descent, anything
    /// else ([`phase_of`]), fitted by `plan-eval` on the training flights' two halves.
    /// Default 1.
    pub phase_scale: [f64; 3],
    /// Weights on the vertical work rate m·g·v_z (W) climbing and descending, added to the
    /// model's power on every sample that moves vertically, slanted legs included
    /// ([`vertical_work_w`]): a climb costs the forward-flight power plus m·g·v_z over the
    /// rotors' efficiency, whatever the horizontal speed. Fitted by `plan-eval` beside
    /// `phase_scale`. Default 0 (not used).
    pub climb_work: [f64; 2],
}

impl Default for Member {
    fn default() -> Self {
        Self {
            model: String::new(),
            scale: 1.0,
            recent_flights: 0,
            phase_scale: [1.0; 3],
            climb_work: [0.0; 2],
        }
    }
}

impl Member {
    /// Model `model`, uncorrected.
    pub fn of(model: &str) -> Self {
        Self {
            model: model.to_string(),
            ..Self::default()
        }
    }

    /// The weights on [model power in vertical climb, vertical descent, the rest, vertical
    /// work up, vertical work down].
    pub fn weights(&self) -> [f64; 5] {
        let [a, b, c] = self.phase_scale;
        let [d, e] = self.climb_work;
        [a, b, c, d, e]
    }

    /// Corrected power, W, where the model predicted `w` W in phase `phase` ([`phase_of`])
    /// with vertical work rates `[up, down]` ([`vertical_work_w`]).
    fn power_w(&self, w: f64, phase: usize, [up, down]: [f64; 2]) -> f64 {
        self.scale
            * (self.phase_scale[phase] * w + self.climb_work[0] * up + self.climb_work[1] * down)
                .max(0.0)
    }
}

/// The fitted correction of the forecast (`[forecast.calibration]`).
#[derive(Debug, Clone, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Calibration {
    /// The forecast's models, each with its correction; the P50 power is their mean
    /// (those that run). One member is one model; `plan-eval` keeps every one of the
    /// vehicle's own models the training flights cannot tell from the best. Default:
    /// `plan-eval`'s fit.
    pub members: Vec<Member>,
    /// P90 energy over P50 energy (90th percentile of measured over corrected forecast on
    /// the training flights). Default: `plan-eval`'s fit.
    pub p90_ratio: f64,
    /// Weight of the flight's own measured/forecast ratio in a live re-forecast, 0..1.
    /// Default: `plan-eval`'s choice on the training flights.
    pub live_weight: f64,
    /// The vehicle's mass without payload, kg, that the vertical work is computed with
    /// (m = `vehicle_kg` + the plan's payload); `climb_work` was fitted with it. Default
    /// 2.431 (the M100 profile's airframe and TB48D, what `plan-eval` fits with).
    pub vehicle_kg: f64,
}

impl Calibration {
    /// No correction: the model's own power (what `plan-eval` fits from).
    pub fn uncorrected(model: &str) -> Self {
        Self::of(Member::of(model))
    }

    /// One member, no P90 spread, no live weight.
    pub fn of(member: Member) -> Self {
        Self {
            members: vec![member],
            p90_ratio: 1.0,
            live_weight: 0.0,
            vehicle_kg: 2.431,
        }
    }

    /// The members' models joined with " + ".
    pub fn name(&self) -> String {
        self.members
            .iter()
            .map(|m| m.model.as_str())
            .collect::<Vec<_>>()
            .join(" + ")
    }

    /// Range checks; the message names the key.
    pub fn validate(&self) -> Result<(), String> {
        if self.members.is_empty() {
            return Err("forecast.calibration.members: empty; name at least one model".into());
        }
        for (i, m) in self.members.iter().enumerate() {
            let key = format!("forecast.calibration.members[{i}] ({:?})", m.model);
            if m.model.is_empty() {
                return Err(format!("{key}: model: missing"));
            }
            if let Some(why) = crate::validate::violation(m.scale, &crate::validate::above(0.0), "")
            {
                return Err(format!("{key}: scale = {}: {why}", m.scale));
            }
            if !m.climb_work.iter().all(|w| w.is_finite()) {
                return Err(format!(
                    "{key}: climb_work = {:?}: must be numbers",
                    m.climb_work
                ));
            }
            if !m.phase_scale.iter().all(|w| w.is_finite() && *w > 0.0) {
                return Err(format!(
                    "{key}: phase_scale = {:?}: must be > 0",
                    m.phase_scale
                ));
            }
        }
        use crate::validate::{above, in_range};
        in_range("forecast.calibration.p90_ratio", self.p90_ratio, 1.0.., "")?;
        in_range(
            "forecast.calibration.vehicle_kg",
            self.vehicle_kg,
            above(0.0),
            "kg",
        )?;
        in_range(
            "forecast.calibration.live_weight",
            self.live_weight,
            0.0..=1.0,
            "",
        )
    }
}

/// Phase of a trajectory sample for [`Member::phase_scale`]: 0 vertical climb, 1
/// vertical descent (|v_z| > 0.5 m/s with under 1 m/s horizontal), 2 anything else.
pub fn phase_of(s: &crate::features::Sample) -> usize {
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

/// The vertical work rate of a sample, W: m·g·v_z climbing and m·g·|v_z| descending
/// (`[up, down]`, one of them 0), with m = `vehicle_kg` + the sample's payload.
pub fn vertical_work_w(s: &crate::features::Sample, vehicle_kg: f64) -> [f64; 2] {
    let vz = f64::from(s.features[idx::VZ]);
    let w = (vehicle_kg + f64::from(s.features[idx::PAYLOAD]).max(0.0) / 1000.0) * 9.81 * vz.abs();
    if vz > 0.0 {
        [w, 0.0]
    } else {
        [0.0, w]
    }
}

impl Default for Calibration {
    fn default() -> Self {
        // Fitted by `dronewatt-lab plan-eval` on the M100 training flights (178 route flights, test
        // flights excluded), with the calibrated profile's physics models.
        let m = |model: &str, scale: f64, recent_flights: usize, w: f64, up: f64| Member {
            model: model.into(),
            scale,
            recent_flights,
            phase_scale: [w; 3],
            climb_work: [up, 0.0],
        };
        Self {
            members: vec![
                m("dorling_cal", 0.9983, 20, 0.9739, 1.6593),
                m("tseng_solo_cal", 0.9909, 40, 0.9670, 1.7320),
                m("tseng_cal", 0.9987, 20, 1.0042, 1.5432),
                m("kirschstein_cal", 0.9961, 20, 0.9622, 1.7957),
            ],
            p90_ratio: 1.0363,
            live_weight: 0.25,
            vehicle_kg: 2.431,
        }
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
    /// The forecast's models (P50 = the mean of their corrected power), joined with " + ".
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

/// Windows built and predicted at a time: a batch large enough for the LSTM's batched
/// kernel, small enough to stay in cache and be reused (a 500-waypoint plan has 16,600
/// windows, 23 MB as one batch: allocating and faulting that in cost more than the models).
const BATCH: usize = 512;

/// Run `models` on `traj` and integrate. `window_t` is the window length T, `stride` the
/// sample step at which models run (≥ 1). The mean of the calibration's members gives the
/// P50 (those that ran; when none did, the first model that ran, uncorrected: the names
/// are in the result).
pub fn forecast(
    traj: &Trajectory,
    models: &mut [Box<dyn PowerModel>],
    cal: &Calibration,
    window_t: usize,
    stride: usize,
) -> MissionForecast {
    let n = traj.samples.len();
    let stride = stride.max(1);
    let t = window_t.max(1);
    let mut powers: Vec<(String, Vec<f32>)> = models
        .iter()
        .map(|m| (m.name().to_string(), vec![0.0f32; n]))
        .collect();
    let mut windows: Vec<Window> = Vec::with_capacity(BATCH.min(n.div_ceil(stride)));
    let mut preds: Vec<Prediction> = Vec::new();
    // Models with the same target lag share each batch of windows.
    let mut lags: Vec<usize> = models.iter().map(|m| m.target_lag()).collect();
    lags.sort_unstable();
    lags.dedup();
    for lag in lags {
        // windows ending at j + lag for j = 0, stride, 2·stride, …; clamped at both ends
        // (before take-off and after touchdown the vehicle is still); the power of the
        // window at j is held until the next one.
        let mut j0 = 0;
        while j0 < n {
            let count = (n - j0).div_ceil(stride).min(BATCH);
            for b in 0..count {
                let end = (j0 + b * stride + lag).min(n - 1);
                if b == windows.len() {
                    windows.push(Window {
                        samples: Vec::with_capacity(t),
                        arrived: None,
                    });
                }
                let w = &mut windows[b].samples;
                w.clear();
                if end + 1 >= t {
                    w.extend_from_slice(&traj.samples[end + 1 - t..=end]);
                } else {
                    w.extend((0..t).map(|i| {
                        let mut s = traj.samples[(end + i + 1).saturating_sub(t)].clone();
                        s.t_s = (end as f64 + i as f64 + 1.0 - t as f64) * traj.dt_s;
                        s
                    }));
                }
            }
            for (m, (_, p)) in models.iter_mut().zip(powers.iter_mut()) {
                if m.target_lag() != lag {
                    continue;
                }
                let lift = m.lift();
                m.predict(&windows[..count], &mut preds);
                for (b, pr) in preds.iter().enumerate().take(count) {
                    let a = j0 + b * stride;
                    let v = if pr.power_w.is_finite() {
                        pr.power_w.max(0.0)
                    } else {
                        0.0
                    };
                    // a model's power only where it applies (NaN elsewhere)
                    for (i, s) in traj
                        .samples
                        .iter()
                        .enumerate()
                        .take((a + stride).min(n))
                        .skip(a)
                    {
                        p[i] = if s.vehicle.lift() == lift {
                            v
                        } else {
                            f32::NAN
                        };
                    }
                }
            }
            j0 += count * stride;
        }
    }
    integrate(traj, &powers, cal)
}

fn integrate(
    traj: &Trajectory,
    powers: &[(String, Vec<f32>)],
    cal: &Calibration,
) -> MissionForecast {
    let dt_h = traj.dt_s / 3600.0;
    let models_raw_wh: Vec<(String, f64)> = powers
        .iter()
        .map(|(n, p)| {
            (
                n.clone(),
                p.iter()
                    .filter(|w| w.is_finite())
                    .map(|&w| f64::from(w))
                    .sum::<f64>()
                    * dt_h
                    + 0.0, // an empty sum is −0.0
            )
        })
        .collect();
    // the members that ran
    let picked: Vec<(&Member, &[f32])> = cal
        .members
        .iter()
        .filter_map(|m| {
            powers
                .iter()
                .find(|(n, _)| *n == m.model)
                .map(|(_, p)| (m, p.as_slice()))
        })
        .collect();
    // where none of them applies (none ran, or the vehicle flies on a lift they do not
    // model): the first model that applies there, uncorrected
    let fallbacks: Vec<Member> = powers.iter().map(|(n, _)| Member::of(n)).collect();
    let mut used: Vec<&str> = Vec::new();
    let mut given = traj.given_w.iter().peekable();
    let mut cum = Vec::with_capacity(traj.samples.len());
    let mut e = 0.0;
    for (j, s) in traj.samples.iter().enumerate() {
        while given.peek().is_some_and(|(r, _)| r.end <= j) {
            given.next();
        }
        if let Some((_, w)) = given.peek().filter(|(r, _)| r.contains(&j)) {
            e += w * dt_h;
            cum.push(e);
            continue;
        }
        let (phase, work) = (phase_of(s), vertical_work_w(s, cal.vehicle_kg));
        let mut applying = picked.iter().filter(|(_, p)| p[j].is_finite()).peekable();
        let p = if applying.peek().is_some() {
            let (sum, k) = applying.fold((0.0, 0usize), |(sum, k), (m, p)| {
                (sum + m.power_w(f64::from(p[j]), phase, work), k + 1)
            });
            sum / k as f64
        } else {
            match fallbacks
                .iter()
                .zip(powers)
                .find(|(_, (_, p))| p[j].is_finite())
            {
                Some((m, (_, p))) => {
                    if !used.contains(&m.model.as_str()) {
                        used.push(&m.model);
                    }
                    m.power_w(f64::from(p[j]), phase, work)
                }
                None => 0.0,
            }
        };
        e += p * dt_h;
        cum.push(e);
    }
    let mut names: Vec<&str> = picked.iter().map(|(m, _)| m.model.as_str()).collect();
    names.extend(
        used.iter()
            .filter(|u| !names.contains(u))
            .collect::<Vec<_>>(),
    );
    let model = if names.is_empty() {
        String::from("none")
    } else {
        names.join(" + ")
    };
    let at = |i: usize| {
        if i == 0 {
            0.0
        } else {
            cum.get(i - 1).copied().unwrap_or(e)
        }
    };
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

/// Share of the plan's P50 energy flown before the live correction applies: the take-off
/// climb's measured/forecast ratio says nothing of the rest (r = −0.01 on the 178 training
/// flights, `docs/src/mission.md`), so a ratio read off little more than the climb is not
/// used. At half time, where `plan-eval` scores it, every training flight has flown 48–55 %.
pub const LIVE_FROM_SHARE: f64 = 0.25;

/// The live correction of what is left, shared by the monitor
/// ([`MissionForecast::remaining_from`]) and `plan-eval`, which measures it: the forecast
/// of the rest `left_wh` scaled by the flight's own showing so far,
/// `s = clamp(measured_so_far / forecast_done, 0.8, 1.25)` blended as `1 + w·(s − 1)` with
/// `w = live_weight`; unchanged until the part flown holds [`LIVE_FROM_SHARE`] of the plan's
/// P50 `total_wh`, or while the measured energy is unknown (not finite, not above 0).
pub fn live_scaled(
    left_wh: f64,
    measured_so_far_wh: f64,
    forecast_done_wh: f64,
    total_wh: f64,
    live_weight: f64,
) -> f64 {
    if forecast_done_wh > LIVE_FROM_SHARE * total_wh
        && measured_so_far_wh.is_finite()
        && measured_so_far_wh > 0.0
    {
        let s = (measured_so_far_wh / forecast_done_wh).clamp(0.8, 1.25);
        left_wh * (1.0 + live_weight * (s - 1.0))
    } else {
        left_wh
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
    pub fn remaining_from(
        &self,
        k: usize,
        measured_so_far_wh: Option<f64>,
        live_weight: f64,
    ) -> Remaining {
        let total = self.energy_p50_wh;
        let done = self.energy_to_wh(k);
        let mut left = (total - done).max(0.0);
        if let Some(m) = measured_so_far_wh {
            left = live_scaled(left, m, done, total, live_weight);
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
mod tests;
