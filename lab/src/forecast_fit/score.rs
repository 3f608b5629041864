//! One flight's scores: the forecast of a prepared flight (`Prepared`) against what it
//! drew, beside the ground station's clock (`gcs_left_s`) and the pre-flight baseline.

use dronewatt::mission::forecast::{live_scaled, Calibration};
use dronewatt::mission::trajectory::{Trajectory, Wind};

use super::{dot5, Prepared};

/// One flight's scores.
#[derive(Debug, Clone, serde::Serialize)]
pub struct FlightScore {
    pub flight: u32,
    pub route: String,
    pub speed_m_s: f64,
    pub payload_g: f64,
    pub altitude: String,
    /// Which flight's track gave the waypoints.
    pub geometry_from: u32,
    pub waypoints: usize,
    pub wind: Wind,
    /// Recording length and planned flight time, s.
    pub measured_s: f64,
    pub planned_s: f64,
    /// Airborne time (first to last row above `AIRBORNE_W`), s.
    pub airborne_s: f64,
    /// Live: where the vehicle was found on the plan at half time (planned time, s) and
    /// the half time itself (from the motors' start, s).
    pub live_plan_t_s: f64,
    /// The plan's legs as flown on paper: label, start and end (s from the motors' start), horizontal
    /// distance (m): where the plan's clock can be set beside the flight's.
    pub plan_legs: Vec<(String, f64, f64, f64)>,
    pub live_t_s: f64,
    /// Measured ∫V·I, Wh.
    pub measured_wh: f64,
    /// Every model's uncorrected forecast of the whole plan, Wh.
    pub models_raw_wh: Vec<(String, f64)>,
    pub p50_wh: f64,
    pub p90_wh: f64,
    /// |P50 − measured| / measured, %.
    pub preflight_err_pct: f64,
    /// measured ≤ P90.
    pub p90_covers: bool,
    /// Live at 50 %: measured energy of the rest, dronewatt's and the baseline's forecast, Wh.
    pub live_measured_rest_wh: f64,
    pub live_forecast_rest_wh: f64,
    /// Live at 50 %: measured energy so far (from the recording's start; from take-off)
    /// and the forecast of the part of the plan flown, Wh.
    pub live_measured_done_wh: f64,
    pub live_measured_airborne_done_wh: f64,
    pub live_forecast_done_wh: f64,
    pub live_err_pct: f64,
    pub baseline_rest_wh: f64,
    pub baseline_err_pct: f64,
    /// Live baseline with the ground station's clock: mean power so far × QGroundControl's
    /// mission time left (`gcs_left_s`), Wh, and its error, %.
    pub gcs_left_s: f64,
    pub baseline_gcs_rest_wh: f64,
    pub baseline_gcs_err_pct: f64,
    /// Pre-flight baseline: the training flights' median mean power × the planned time, Wh.
    pub baseline_preflight_wh: f64,
    pub baseline_preflight_err_pct: f64,
}

/// QGroundControl's mission time for what is left of `traj` from sample `k`, s: the rule of
/// its plan view (`MissionController`), which is the only mission clock a pilot has today:
/// horizontal distance at the plan's speed, the take-off's height at the ascent speed, the
/// final descent at the descent speed, holds (`loiter` legs) at their length; no
/// accelerations, stops or spin-up, and a leg's climb or descent costs no time. The ascent
/// and descent speeds are the vehicle's own (`climb_m_s`, `descent_m_s`), kinder to the
/// baseline than QGroundControl's offline defaults.
pub(crate) fn gcs_left_s(
    traj: &Trajectory,
    k: usize,
    speed_m_s: f64,
    kin: &dronewatt::mission::trajectory::KinematicsConfig,
) -> f64 {
    let n = traj.enu_m.len();
    if k + 1 >= n {
        return 0.0;
    }
    let horizontal: f64 = traj.enu_m[k..]
        .windows(2)
        .map(|w| f64::from(w[1][0] - w[0][0]).hypot(f64::from(w[1][1] - w[0][1])))
        .sum();
    let z = |j: usize| f64::from(traj.enu_m[j.min(n - 1)][2]);
    let leg_at = traj.leg_of.get(k).map_or(0, |&l| l as usize);
    let mut t = horizontal / speed_m_s.max(0.1);
    for (i, l) in traj.legs.iter().enumerate().skip(leg_at) {
        let from = if i == leg_at { k } else { l.samples.start };
        let label = l.label.as_str();
        if label == "takeoff" {
            t += (z(l.samples.end.saturating_sub(1)) - z(from)).max(0.0) / kin.climb_m_s.max(0.1);
        } else if label == "rtl" || label.starts_with("land") {
            t += z(from).max(0.0) / kin.descent_m_s.max(0.1);
        } else if label == "loiter" {
            t += l.samples.end.saturating_sub(from) as f64 * traj.dt_s;
        }
    }
    t
}

/// Flight `p` forecast with `cal`, each member `i` with the scale `scales[i]` (the one
/// fitted before the flight) in place of its own.
pub(crate) fn score(
    p: &Prepared,
    cal: &Calibration,
    scales: &[f64],
    baseline_w: f64,
) -> FlightScore {
    let (mut done, mut left, mut n) = (0.0f64, 0.0f64, 0.0f64);
    let mut planned_left_s = 0.0;
    for (c, scale) in cal.members.iter().zip(scales) {
        let Some(m) = p.raw.iter().find(|m| m.name == c.model) else {
            continue;
        };
        let ks = c.weights();
        done += scale * dot5(&ks, &m.first_wh);
        left += scale * dot5(&ks, &m.rest_wh);
        planned_left_s = m.planned_left_s;
        n += 1.0;
    }
    let (done, left) = (done / n.max(1.0), left / n.max(1.0));
    let p50 = done + left;
    let p90 = p50 * cal.p90_ratio;
    // the monitor's own live correction (the same function)
    let left = live_scaled(left, p.live_so_far_wh, done, p50, cal.live_weight);
    let baseline = p.live_mean_w * planned_left_s / 3600.0;
    let baseline_gcs = p.live_mean_w * p.live_gcs_left_s / 3600.0;
    let err = |f: f64, m: f64| 100.0 * (f - m).abs() / m.max(1e-9);
    let baseline_preflight_wh = baseline_w * p.traj.duration_s() / 3600.0;
    FlightScore {
        flight: p.flight,
        route: p.route.clone(),
        speed_m_s: p.speed_m_s,
        payload_g: p.payload_g,
        altitude: p.altitude.clone(),
        geometry_from: p.geometry_from,
        waypoints: p.waypoints,
        wind: p.wind,
        measured_s: p.measured_s,
        planned_s: p.traj.duration_s(),
        airborne_s: p.airborne_s,
        live_plan_t_s: p.live_k as f64 * p.traj.dt_s,
        plan_legs: p
            .traj
            .legs
            .iter()
            .map(|l| (l.label.clone(), l.t_start_s, l.t_end_s, l.distance_m))
            .collect(),
        live_t_s: p.live_t_s,
        measured_wh: p.measured_wh,
        models_raw_wh: p.raw.iter().map(|m| (m.name.clone(), m.total_wh)).collect(),
        p50_wh: p50,
        p90_wh: p90,
        preflight_err_pct: err(p50, p.measured_wh),
        p90_covers: p.measured_wh <= p90,
        live_measured_rest_wh: p.live_rest_wh,
        live_forecast_rest_wh: left,
        live_measured_done_wh: p.live_so_far_wh,
        live_measured_airborne_done_wh: p.live_airborne_so_far_wh,
        live_forecast_done_wh: done,
        live_err_pct: err(left, p.live_rest_wh),
        baseline_rest_wh: baseline,
        baseline_err_pct: err(baseline, p.live_rest_wh),
        gcs_left_s: p.live_gcs_left_s,
        baseline_gcs_rest_wh: baseline_gcs,
        baseline_gcs_err_pct: err(baseline_gcs, p.live_rest_wh),
        baseline_preflight_wh,
        baseline_preflight_err_pct: err(baseline_preflight_wh, p.measured_wh),
    }
}
