//! One flight's figures: the pack model (shipped constants) and the autopilots' rules, with
//! the same definitions as fit.py's `evaluate` (signed errors here; the summary takes the
//! median of their absolute values). Volts are pack volts (6S) unless a name says cell.

use dronewatt::battery::forecast::{lowest_dip, steps, SAG_IN_FLIGHT, SAG_PREFLIGHT};
use dronewatt::battery::{forecast, CircuitParams, Estimator, OcvCurve};

use super::autopilots::{ArduBattery, Px4Battery, PX4_LOW_SOC};
use super::plan::PlanPower;
use super::prep::{measured_wh, Prepared, DT};

/// Cells in series (TB48D: 6S).
pub const NC: f64 = 6.0;
/// TB48D rated energy (Wh) and charge (Ah).
pub const RATED_WH: f64 = 129.96;
pub const RATED_AH: f64 = 5.7;
/// The 3.5 V/cell threshold under load, V pack.
pub const THR_V: f64 = NC * 3.5;
/// Rows with more current than this are "in flight" for loaded-voltage errors, A.
pub const IN_FLIGHT_A: f64 = 3.0;

/// PX4's linear state of charge from a per-cell voltage: (v − lo)/(4.05 − lo), clamped.
pub fn px4_soc(v_cell: f64, lo: f64) -> f64 {
    ((v_cell - lo) / (4.05 - lo)).clamp(0.0, 1.0)
}

/// Every figure of one flight (signed; NaN where it does not apply).
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct FlightFigures {
    pub flight: u32,
    pub route: String,
    pub test: bool,
    /// Rest voltages (V pack), end slope (V/s), measured ∫V·I (Wh), carried-over heat (A²·s).
    pub v_start: f64,
    pub v_end_meas: f64,
    pub end_slope_v_s: f64,
    pub v_end_rest: f64,
    pub measured_wh: f64,
    pub heat0_a2s: f64,
    /// The resistance scale of the previous flight on the same pack, carried over (none: the
    /// first flight of a pack).
    pub k_prev: Option<f64>,
    /// Energy between the two rest voltages (OCV curve) − measured, Wh.
    pub ocv_energy_err_wh: f64,
    /// End rest V predicted from the start rest V and the measured energy − end rest V, V.
    pub ocv_end_v_err_v: f64,
    /// PX4 linear rule 3.6→4.05 V/cell (and the older 3.5→4.05) × 129.96 Wh between the
    /// rest voltages − measured, Wh.
    pub px4_36_energy_err_wh: f64,
    pub px4_35_energy_err_wh: f64,
    /// Start energy: 129.96 Wh ("full at take-off") − our curve's, Wh; PX4's SoC × 129.96 −
    /// our curve's, Wh; ArduPilot's full-at-boot missing charge vs our curve, mAh.
    pub full_pack_start_energy_err_wh: f64,
    pub px4_start_energy_err_wh: f64,
    pub ardupilot_start_mah_err: f64,
    /// Loaded-voltage RMSE over rows with I > 3 A: open loop (0.1 s grid) and the online
    /// estimator's one-step a-priori error and 10-s-ahead error (raw rows), V.
    pub ecm_rmse_v: f64,
    pub online_onestep_rmse_v: f64,
    pub online_10s_rmse_v: f64,
    /// Lowest measured loaded voltage in flight (V) and its forecasts' errors (forecast −
    /// measured): pre-flight with the measured power, pre-flight with 5-s-averaged power,
    /// from half time (estimator state there) with the measured power of the rest.
    pub measured_min_v: f64,
    pub preflight_min_v_err: f64,
    pub preflight_ma5_min_v_err: f64,
    pub halftime_min_v_err: f64,
    /// Pre-flight from the plan (route flights, [`super::plan`]): the flight whose track gave
    /// the waypoints, the planned energy (Wh), the lowest loaded voltage of the pack flown
    /// along the planned power from the start resting voltage (V), the sag below the
    /// open-circuit voltage there (V), and the forecast's error once its sag term is added
    /// (forecast − measured lowest, V).
    pub plan_geometry_from: Option<u32>,
    pub plan_energy_wh: f64,
    pub preflight_plan_v_min_smooth: f64,
    pub preflight_plan_sag_v: f64,
    pub preflight_plan_min_v_err: f64,
    /// The same raw figures with the measured power (the sag below the OCV at the lowest
    /// forecast step, V) and from half time.
    pub preflight_sag_v: f64,
    pub halftime_sag_v: f64,
    /// From half time along the rest of the plan (its power × the live factor): the lowest
    /// loaded voltage (V), its sag (V), the error with the sag term (V).
    pub halftime_plan_v_min_smooth: f64,
    /// The measured lowest loaded voltage after half time (V).
    pub halftime_measured_min_v: f64,
    pub halftime_plan_sag_v: f64,
    pub halftime_plan_min_v_err: f64,
    /// Half time (s from the recording's start) the forecast starts at.
    pub halftime_s: f64,
    /// First 3.5 V/cell crossing under load: measured time (s; NaN if the flight never
    /// crosses), forecast − measured from pre-flight and half time (NaN: no crossing
    /// forecast, or the crossing happened before half time).
    pub cross35_measured_s: f64,
    pub cross35_preflight_err_s: f64,
    pub cross35_halftime_err_s: f64,
    /// The forecast predicted no crossing on a flight that crossed.
    pub cross35_preflight_missed: bool,
    pub cross35_halftime_missed: bool,
    /// The autopilots' answer to the same crossing, when − measured (s): PX4's low warning
    /// (SoC under `BAT_LOW_THR` 15 %), ArduPilot's raw-voltage failsafe (under 3.5 V a cell
    /// for `BATT_LOW_TIMER` 10 s); missed: not raised by the end of the flight.
    pub cross35_px4_low_err_s: f64,
    pub cross35_ardupilot_fs_err_s: f64,
    pub cross35_px4_low_missed: bool,
    pub cross35_ardupilot_fs_missed: bool,
    /// Resting voltage read at the last in-flight sample − the end rest voltage, V: ours
    /// (estimator energy → OCV), PX4 (its load-compensated, low-passed voltage, R from its
    /// online RLS: [`super::autopilots::Px4Battery`]), ArduPilot (`voltage_resting_estimate`,
    /// [`super::autopilots::ArduBattery`]).
    pub rest_under_load_ours_v: f64,
    pub rest_under_load_px4_v: f64,
    pub rest_under_load_ardupilot_v: f64,
    /// Energy left at the last in-flight sample − our curve's energy at the end rest
    /// voltage, Wh: ours (the online estimator), PX4 (SoC × 129.96 Wh), ArduPilot
    /// (remaining charge from boot × 129.96 Wh), full pack at take-off − energy used.
    pub landing_energy_ours_err_wh: f64,
    pub landing_energy_px4_err_wh: f64,
    pub landing_energy_ardupilot_err_wh: f64,
    pub landing_energy_full_pack_err_wh: f64,
}

/// What the plot needs besides the figures.
#[derive(Debug, Clone, Default)]
pub struct Traces {
    /// Open-loop modelled loaded voltage on the grid, V.
    pub open_loop_v: Vec<f64>,
    /// Estimator state at half time and the grid index the forecast starts at.
    pub mid: Option<(Estimator, usize)>,
}

fn rmse(e: &[f64]) -> f64 {
    if e.is_empty() {
        f64::NAN
    } else {
        (e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64).sqrt()
    }
}

/// numpy `convolve(x, ones(n)/n, mode='same')`.
fn moving_average_same(x: &[f64], n: usize) -> Vec<f64> {
    let off = (n - 1) / 2;
    (0..x.len())
        .map(|i| {
            let c = i + off;
            let lo = c.saturating_sub(n - 1);
            let hi = c.min(x.len() - 1);
            x[lo..=hi].iter().sum::<f64>() / n as f64
        })
        .collect()
}

/// The lowest loaded voltage flying `profile` from `est` (V), and its sag below the
/// open-circuit voltage there (V); NaN for an empty profile.
fn lowest(est: &Estimator, profile: impl IntoIterator<Item = (f64, f64)>) -> (f64, f64) {
    steps(est, profile)
        .filter(|s| s.v.is_finite())
        .min_by(|a, b| a.v.total_cmp(&b.v))
        .map_or((f64::NAN, f64::NAN), |s| (s.v, s.ocv - s.v))
}

/// Energy-between-rests figures (flights with both rest voltages).
fn rest_figures(p: &Prepared, curve: &OcvCurve, out: &mut FlightFigures) {
    let (vs, ve) = (p.v_start / NC, p.v_end_rest / NC);
    let e0 = curve.energy(vs);
    out.ocv_energy_err_wh = e0 - curve.energy(ve) - p.e_wh;
    out.ocv_end_v_err_v = NC * curve.v_cell_at_energy(e0 - p.e_wh) - NC * ve;
    out.px4_36_energy_err_wh = (px4_soc(vs, 3.6) - px4_soc(ve, 3.6)) * RATED_WH - p.e_wh;
    out.px4_35_energy_err_wh = (px4_soc(vs, 3.5) - px4_soc(ve, 3.5)) * RATED_WH - p.e_wh;
    out.full_pack_start_energy_err_wh = RATED_WH - e0;
    out.px4_start_energy_err_wh = px4_soc(vs, 3.6) * RATED_WH - e0;
    out.ardupilot_start_mah_err = (1.0 - e0 / curve.capacity()) * RATED_AH * 1000.0;
}

/// Score one flight. `heat0`: carried-over heat (A²·s). Loaded-voltage figures only when
/// the flight is [`Prepared::ecm_ok`] and its grid is filled.
pub fn score_flight(
    p: &Prepared,
    heat0: f64,
    params: CircuitParams,
    curve: &OcvCurve,
    plan: Option<&PlanPower>,
) -> (FlightFigures, Traces) {
    let mut o = unscored(p, heat0);
    let mut tr = Traces::default();
    if p.rest_ok() {
        rest_figures(p, curve, &mut o);
    }
    let Some((i_on, i_off)) = p.on else {
        return (o, tr);
    };
    if !p.ecm_ok() || p.tg.is_empty() {
        return (o, tr);
    }
    let Some(est0) = Estimator::new(params, curve.clone(), p.v_start, heat0) else {
        return (o, tr);
    };
    let m: Vec<bool> = p.ig.iter().map(|&i| i > IN_FLIGHT_A).collect();
    tr.open_loop_v = open_loop(p, &est0, &m, &mut o);
    let (prof, below) = preflight(p, &est0, &m, plan, &mut o);
    if let Some(mid) = online(p, &est0, i_on, i_off, &mut o) {
        tr.mid = Some(halftime(p, mid, &m, &prof, below, plan, &mut o));
    }
    let (px4, ap) = autopilots(p, i_on, i_off, &mut o);
    if p.v_end_rest.is_finite() {
        landing(p, curve, &est0, i_off, &px4, &ap, &mut o);
    }
    (o, tr)
}

/// The flight's own figures, every other f64 NaN until computed.
fn unscored(p: &Prepared, heat0: f64) -> FlightFigures {
    let nan = f64::NAN;
    let mut o = FlightFigures {
        flight: p.flight,
        route: p.route.clone(),
        test: p.test,
        v_start: p.v_start,
        v_end_meas: p.v_end_meas,
        end_slope_v_s: p.end_slope,
        v_end_rest: p.v_end_rest,
        measured_wh: p.e_wh,
        heat0_a2s: heat0,
        ..FlightFigures::default()
    };
    // every f64 NaN until computed
    for x in [
        &mut o.ocv_energy_err_wh,
        &mut o.ocv_end_v_err_v,
        &mut o.px4_36_energy_err_wh,
        &mut o.px4_35_energy_err_wh,
        &mut o.full_pack_start_energy_err_wh,
        &mut o.px4_start_energy_err_wh,
        &mut o.ardupilot_start_mah_err,
        &mut o.ecm_rmse_v,
        &mut o.online_onestep_rmse_v,
        &mut o.online_10s_rmse_v,
        &mut o.measured_min_v,
        &mut o.preflight_min_v_err,
        &mut o.preflight_ma5_min_v_err,
        &mut o.halftime_min_v_err,
        &mut o.plan_energy_wh,
        &mut o.preflight_plan_v_min_smooth,
        &mut o.preflight_plan_sag_v,
        &mut o.preflight_plan_min_v_err,
        &mut o.preflight_sag_v,
        &mut o.halftime_sag_v,
        &mut o.halftime_plan_v_min_smooth,
        &mut o.halftime_measured_min_v,
        &mut o.halftime_plan_sag_v,
        &mut o.halftime_plan_min_v_err,
        &mut o.halftime_s,
        &mut o.cross35_measured_s,
        &mut o.cross35_preflight_err_s,
        &mut o.cross35_halftime_err_s,
        &mut o.cross35_px4_low_err_s,
        &mut o.cross35_ardupilot_fs_err_s,
        &mut o.rest_under_load_ours_v,
        &mut o.rest_under_load_px4_v,
        &mut o.rest_under_load_ardupilot_v,
        &mut o.landing_energy_ours_err_wh,
        &mut o.landing_energy_px4_err_wh,
        &mut o.landing_energy_ardupilot_err_wh,
        &mut o.landing_energy_full_pack_err_wh,
    ] {
        *x = nan;
    }
    o
}

/// Open loop on the grid: the modelled loaded voltage (returned) and its RMSE over the rows
/// in flight (`m`).
fn open_loop(p: &Prepared, est0: &Estimator, m: &[bool], o: &mut FlightFigures) -> Vec<f64> {
    let (tg, ig, vg) = (&p.tg, &p.ig, &p.vg);
    let mut s = est0.clone();
    let open_loop_v: Vec<f64> = ig.iter().map(|&i| s.step_open_loop(DT, i)).collect();
    let err: Vec<f64> = (0..tg.len())
        .filter(|&k| m[k])
        .map(|k| open_loop_v[k] - vg[k])
        .collect();
    o.ecm_rmse_v = rmse(&err);
    open_loop_v
}

/// Pre-flight forecasts over the measured power profile (and the plan's): returns that
/// profile on the grid and the first grid row in flight under 3.5 V/cell.
fn preflight(
    p: &Prepared,
    est0: &Estimator,
    m: &[bool],
    plan: Option<&PlanPower>,
    o: &mut FlightFigures,
) -> (Vec<(f64, f64)>, Option<usize>) {
    let nan = f64::NAN;
    let (tg, ig, vg) = (&p.tg, &p.ig, &p.vg);
    let meas_min = (0..tg.len())
        .filter(|&k| m[k])
        .map(|k| vg[k])
        .fold(f64::INFINITY, f64::min);
    o.measured_min_v = if meas_min.is_finite() { meas_min } else { nan };
    let pw: Vec<f64> = vg.iter().zip(ig).map(|(v, i)| v * i).collect();
    let prof: Vec<(f64, f64)> = pw.iter().map(|&w| (DT, w)).collect();
    let s0 = est0.clone();
    let fc = forecast(&s0, &prof, &[THR_V]);
    o.preflight_min_v_err = fc.v_min - o.measured_min_v;
    o.preflight_sag_v = lowest(&s0, prof.iter().copied()).1;
    if let Some(pl) = plan {
        let prof = || pl.power_w.iter().map(|&w| (pl.dt_s, w));
        let (v, sag) = lowest(&s0, prof());
        o.plan_geometry_from = Some(pl.geometry_from);
        o.plan_energy_wh = pl.energy_wh;
        o.preflight_plan_v_min_smooth = v;
        o.preflight_plan_sag_v = sag;
        if let Some((_, v)) = lowest_dip(&s0, prof(), SAG_PREFLIGHT) {
            o.preflight_plan_min_v_err = v - o.measured_min_v;
        }
    }
    let prof5: Vec<(f64, f64)> = moving_average_same(&pw, 50)
        .into_iter()
        .map(|w| (DT, w))
        .collect();
    o.preflight_ma5_min_v_err = forecast(&s0, &prof5, &[THR_V]).v_min - o.measured_min_v;
    let below = (0..tg.len()).find(|&k| m[k] && vg[k] < THR_V);
    if let Some(b) = below {
        o.cross35_measured_s = tg[b];
        match fc.crossings.first().copied().flatten() {
            Some(c) => o.cross35_preflight_err_s = c - tg[b],
            None => o.cross35_preflight_missed = true,
        }
    }
    (prof, below)
}

/// The online estimator on the raw rows: one-step a-priori and 10-s-ahead errors; returns
/// its state at half the airborne time and the raw row index there.
fn online(
    p: &Prepared,
    est0: &Estimator,
    i_on: usize,
    i_off: usize,
    o: &mut FlightFigures,
) -> Option<(Estimator, usize)> {
    let nan = f64::NAN;
    let (t, i, v) = (&p.t, &p.i, &p.v);
    let tmid = 0.5 * (t[i_on] + t[i_off]);
    let mut s = est0.clone();
    let (mut e1, mut e10) = (Vec::new(), Vec::new());
    let mut mid: Option<(Estimator, usize)> = None;
    for k in 1..t.len() {
        if t[k] >= tmid && mid.is_none() {
            mid = Some((s.clone(), k));
        }
        let est = s.update(t[k] - t[k - 1], i[k], v[k]);
        if let Some(e) = est.filter(|_| i[k] > IN_FLIGHT_A) {
            e1.push(e.error);
        }
        if i[k] > IN_FLIGHT_A && k % 25 == 0 {
            let j = t.partition_point(|&x| x < t[k] + 10.0);
            if j < t.len() && i[j] > IN_FLIGHT_A {
                let mut q = s.clone();
                let mut vhat = nan;
                for n in k + 1..=j {
                    vhat = q.step_open_loop(t[n] - t[n - 1], i[n]);
                }
                e10.push(v[j] - vhat);
            }
        }
    }
    o.online_onestep_rmse_v = rmse(&e1);
    o.online_10s_rmse_v = rmse(&e10);
    mid
}

/// Half-time forecast: the estimator state at half the airborne time (`mid`), the measured
/// power after (`prof`'s rest) and the plan's rest; returns the state and the grid index the
/// forecast starts at.
fn halftime(
    p: &Prepared,
    (sm, k): (Estimator, usize),
    m: &[bool],
    prof: &[(f64, f64)],
    below: Option<usize>,
    plan: Option<&PlanPower>,
    o: &mut FlightFigures,
) -> (Estimator, usize) {
    let (t, tg, vg) = (&p.t, &p.tg, &p.vg);
    let tk = t[k - 1];
    let j = tg.partition_point(|&x| x < tk);
    o.halftime_s = tk;
    let fcm = forecast(&sm, &prof[j..], &[THR_V]);
    o.halftime_sag_v = lowest(&sm, prof[j..].iter().copied()).1;
    let rest_min_v = (j..tg.len())
        .filter(|&n| m[n])
        .map(|n| vg[n])
        .fold(f64::INFINITY, f64::min);
    o.halftime_measured_min_v = rest_min_v;
    if let Some(pl) = plan {
        let rest = || {
            pl.power_w
                .iter()
                .skip(pl.live_k + 1)
                .map(|&w| (pl.dt_s, w * pl.live_scale))
        };
        let (v, sag) = lowest(&sm, rest());
        o.halftime_plan_v_min_smooth = v;
        o.halftime_plan_sag_v = sag;
        if let Some((_, v)) = lowest_dip(&sm, rest(), SAG_IN_FLIGHT) {
            o.halftime_plan_min_v_err = v - rest_min_v;
        }
    }
    let rest_min = (j..tg.len())
        .filter(|&n| m[n])
        .map(|n| vg[n])
        .fold(f64::INFINITY, f64::min);
    if rest_min.is_finite() {
        o.halftime_min_v_err = fcm.v_min - rest_min;
    }
    if let Some(b) = below.filter(|&b| b >= j) {
        match fcm.crossings.first().copied().flatten() {
            Some(c) => o.cross35_halftime_err_s = c + tk - tg[b],
            None => o.cross35_halftime_missed = true,
        }
    }
    (sm, j)
}

/// The autopilots as they run: their monitors see every row from the recording's start
/// (the pack at rest on the ground), so PX4 settles on the resting voltage. In flight,
/// PX4's low warning (SoC under BAT_LOW_THR) and ArduPilot's raw-voltage failsafe (under
/// 3.5 V a cell for BATT_LOW_TIMER) against the first measured 3.5 V/cell crossing.
/// Returns both monitors as they stand at the last in-flight sample.
fn autopilots(
    p: &Prepared,
    i_on: usize,
    i_off: usize,
    o: &mut FlightFigures,
) -> (Px4Battery, ArduBattery) {
    let (t, i, v) = (&p.t, &p.i, &p.v);
    let (mut px4, mut ap) = (
        Px4Battery::new(NC as u32, RATED_AH * 1e3),
        ArduBattery::new(RATED_AH * 1e3),
    );
    let (mut px4_low_s, mut ap_fs_s) = (None, None);
    for k in 0..=i_off {
        let dt = if k == 0 { 0.0 } else { t[k] - t[k - 1] };
        px4.update(dt, v[k], i[k]);
        ap.update(dt, v[k], i[k]);
        if k >= i_on {
            if px4_low_s.is_none() && px4.soc() < PX4_LOW_SOC {
                px4_low_s = Some(t[k]);
            }
            ap_fs_s = ap.low_failsafe(t[k], v[k], THR_V);
        }
    }
    if o.cross35_measured_s.is_finite() {
        let c = o.cross35_measured_s;
        match px4_low_s {
            Some(w) => o.cross35_px4_low_err_s = w - c,
            None => o.cross35_px4_low_missed = true,
        }
        match ap_fs_s {
            Some(w) => o.cross35_ardupilot_fs_err_s = w - c,
            None => o.cross35_ardupilot_fs_missed = true,
        }
    }
    (px4, ap)
}

/// Resting voltage read at the last in-flight sample vs the relaxed end rest voltage, and
/// the energy left there (flights with an end rest voltage).
fn landing(
    p: &Prepared,
    curve: &OcvCurve,
    est0: &Estimator,
    i_off: usize,
    px4: &Px4Battery,
    ap: &ArduBattery,
    o: &mut FlightFigures,
) {
    let (t, i, v) = (&p.t, &p.i, &p.v);
    let mut s = est0.clone();
    for k in 1..=i_off {
        s.update(t[k] - t[k - 1], i[k], v[k]);
    }
    o.rest_under_load_ours_v = NC * curve.v_cell_at_energy(s.energy_wh()) - p.v_end_rest;
    o.rest_under_load_px4_v = px4.compensated_v() - p.v_end_rest;
    o.rest_under_load_ardupilot_v = ap.resting_v(v[i_off], i[i_off]) - p.v_end_rest;
    // Energy left at the last in-flight sample against our curve at the end rest
    // voltage (model-based, as the start rows): ours, PX4's SoC and ArduPilot's
    // remaining charge × the rated 129.96 Wh, and "full at take-off" − the energy used.
    let truth = curve.energy(p.v_end_rest / NC);
    let used_wh = measured_wh(t, v, i, i_off + 1);
    o.landing_energy_ours_err_wh = s.energy_wh() - truth;
    o.landing_energy_px4_err_wh = px4.soc() * RATED_WH - truth;
    o.landing_energy_ardupilot_err_wh = ap.remaining() * RATED_WH - truth;
    o.landing_energy_full_pack_err_wh = RATED_WH - used_wh - truth;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moving_average_is_numpy_same() {
        // np.convolve([1,2,3,4,5], ones(2)/2, 'same') = [0.5, 1.5, 2.5, 3.5, 4.5]
        assert_eq!(
            moving_average_same(&[1.0, 2.0, 3.0, 4.0, 5.0], 2),
            vec![0.5, 1.5, 2.5, 3.5, 4.5]
        );
        // n = 3: [1, 2, 3, 4, 3]
        let y = moving_average_same(&[1.0, 2.0, 3.0, 4.0, 5.0], 3);
        assert!((y[0] - 1.0).abs() < 1e-12 && (y[4] - 3.0).abs() < 1e-12);
        assert!((px4_soc(3.825, 3.6) - 0.5).abs() < 1e-12);
    }
}
