//! Per-flight facts the pack model is scored on, ported from the fitting script
//! (`lab/scripts/battery/extract.py` and fit.py's first section):
//!
//! - **start rest voltage**: median V over the 3 s before the first sample with I > 1 A
//!   (only samples with |I| < 1 A; at least 3 of them), V pack;
//! - **end rest voltage**: median V of the log's last 2 s (|I| < 1 A, ≥ 3 samples), only if
//!   the log runs ≥ 8 s past the last I > 1 A sample, **plus the relaxation correction**
//!   `k·slope + c` (slope of V over the last 6 s, V/s; k, c fitted on training flights whose
//!   pack flew again minutes later, [`RELAX_K_S`], [`RELAX_C_V`]);
//! - **measured energy**: trapezoidal ∫V·I dt over the whole recording, Wh;
//! - **pack chains**: flight B follows A on the same pack when they are consecutive in flight
//!   number, on the same date, start 1–25 min apart, and B's start rest voltage is 0.05 V
//!   below to 0.8 V above A's measured end voltage — used to carry the heat proxy over;
//! - **grid**: current and voltage linearly resampled every 0.1 s from t = 0 (open loop and
//!   forecasts run on it, as in the script).

use std::collections::HashMap;

use dronewatt::source::logs::dataset::Flight;

/// Relaxation correction of the end rest voltage: v_rest = v_tail + k·slope + c.
/// Fitted by fit.py on 87 training pairs (results.json `relax`).
pub const RELAX_K_S: f64 = 18.297533747779475;
/// See [`RELAX_K_S`], V (pack).
pub const RELAX_C_V: f64 = -0.009380413829325035;
/// Resampling step of the grid, s.
pub const DT: f64 = 0.1;
/// Routes left out of the loaded-voltage figures (hover and the A-routes), as in fit.py.
pub const NO_ECM_ROUTES: [&str; 4] = ["A1", "A2", "A3", "H"];

/// One flight, prepared.
#[derive(Debug, Clone)]
pub struct Prepared {
    pub flight: u32,
    pub route: String,
    pub test: bool,
    /// Raw rows: time (s), current (A), voltage (V).
    pub t: Vec<f64>,
    pub i: Vec<f64>,
    pub v: Vec<f64>,
    /// Measured ∫V·I dt over the recording, Wh.
    pub e_wh: f64,
    /// First and last row with I > 1 A.
    pub on: Option<(usize, usize)>,
    /// Rest voltages (V, pack; NaN when not measurable) and the end slope (V/s).
    pub v_start: f64,
    pub v_end_meas: f64,
    pub end_slope: f64,
    pub v_end_rest: f64,
    /// Start of the flight, minutes of the day (from `time_day`), and its date.
    pub date: String,
    pub tmin: Option<i64>,
    /// The next flight on the same pack, if any.
    pub next: Option<u32>,
    /// The 0.1 s grid (only for flights scored under load): time, current, voltage.
    pub tg: Vec<f64>,
    pub ig: Vec<f64>,
    pub vg: Vec<f64>,
}

impl Prepared {
    /// Both rest voltages and an in-flight part: the energy ↔ voltage figures apply.
    pub fn rest_ok(&self) -> bool {
        self.on.is_some() && self.v_start.is_finite() && self.v_end_rest.is_finite()
    }
    /// In-flight part, a start rest voltage, a route flown (not hover/A): the loaded-voltage
    /// figures apply.
    pub fn ecm_ok(&self) -> bool {
        self.on.is_some()
            && self.v_start.is_finite()
            && !NO_ECM_ROUTES.contains(&self.route.as_str())
    }
}

/// Median of the finite values (mean of the middle two for an even count); NaN if none.
pub fn median(x: impl IntoIterator<Item = f64>) -> f64 {
    dronewatt::offline::metrics::median_finite(x)
}

fn median_where(t: &[f64], v: &[f64], keep: impl Fn(usize) -> bool, min_n: usize) -> f64 {
    let sel: Vec<f64> = (0..t.len()).filter(|&k| keep(k)).map(|k| v[k]).collect();
    if sel.len() >= min_n {
        median(sel)
    } else {
        f64::NAN
    }
}

/// Least-squares slope of y on x, NaN for fewer than 2 points.
fn slope(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len() as f64;
    if x.len() < 2 {
        return f64::NAN;
    }
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
    sxy / sxx
}

/// `H:MM` → minutes of the day.
fn minutes(s: &str) -> Option<i64> {
    let (h, m) = s.trim().split_once(':')?;
    Some(h.trim().parse::<i64>().ok()? * 60 + m.trim().parse::<i64>().ok()?)
}

/// Linear interpolation of (t, y) at increasing `at`, clamped at the ends (numpy's interp).
pub fn interp_sorted(t: &[f64], y: &[f64], at: &[f64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(at.len());
    let mut k = 0;
    for &x in at {
        if t.is_empty() {
            out.push(f64::NAN);
            continue;
        }
        while k + 1 < t.len() && t[k + 1] <= x {
            k += 1;
        }
        if x <= t[0] {
            out.push(y[0]);
        } else if k + 1 >= t.len() {
            out.push(y[t.len() - 1]);
        } else {
            let w = (x - t[k]) / (t[k + 1] - t[k]);
            out.push(y[k] + w * (y[k + 1] - y[k]));
        }
    }
    out
}

/// Measured ∫V·I dt over the rows before `end` (trapezoids), Wh.
pub fn measured_wh(t: &[f64], v: &[f64], i: &[f64], end: usize) -> f64 {
    (1..end.min(t.len()))
        .map(|k| (t[k] - t[k - 1]) * 0.5 * (v[k] * i[k] + v[k - 1] * i[k - 1]))
        .sum::<f64>()
        / 3600.0
}

/// One flight's facts (no grid, no chain yet).
pub fn prepare(f: &Flight, test: bool) -> Prepared {
    let t: Vec<f64> = f.rows.iter().map(|r| r.time_s).collect();
    let v: Vec<f64> = f.rows.iter().map(|r| r.voltage_v).collect();
    let i: Vec<f64> = f.rows.iter().map(|r| r.current_a).collect();
    let e_wh = measured_wh(&t, &v, &i, t.len());
    let first = i.iter().position(|&a| a > 1.0);
    let last = i.iter().rposition(|&a| a > 1.0);
    let mut p = Prepared {
        flight: f.flight,
        route: f.route.clone(),
        test,
        e_wh,
        on: first.zip(last),
        v_start: f64::NAN,
        v_end_meas: f64::NAN,
        end_slope: f64::NAN,
        v_end_rest: f64::NAN,
        date: f.date.trim().to_string(),
        tmin: minutes(&f.time_day),
        next: None,
        tg: Vec::new(),
        ig: Vec::new(),
        vg: Vec::new(),
        t,
        i,
        v,
    };
    if let Some((i0, i1)) = p.on {
        let (t, v, i) = (&p.t, &p.v, &p.i);
        let (t0, t1, tl) = (t[i0], t[i1], t[t.len() - 1]);
        p.v_start = median_where(
            t,
            v,
            |k| t[k] < t0 && t[k] >= t0 - 3.0 && i[k].abs() < 1.0,
            3,
        );
        let post_len = tl - t1;
        if post_len >= 8.0 {
            p.v_end_meas = median_where(
                t,
                v,
                |k| t[k] > t1 && t[k] >= tl - 2.0 && i[k].abs() < 1.0,
                3,
            );
            let s: Vec<usize> = (0..t.len())
                .filter(|&k| t[k] > t1 && t[k] >= tl - 6.0)
                .collect();
            if s.len() >= 8 {
                let x: Vec<f64> = s.iter().map(|&k| t[k] - tl).collect();
                let y: Vec<f64> = s.iter().map(|&k| v[k]).collect();
                p.end_slope = slope(&x, &y);
            }
        }
        p.v_end_rest = p.v_end_meas + RELAX_K_S * p.end_slope + RELAX_C_V;
    }
    p
}

/// Fill the grid of a flight (t from 0 every [`DT`] below the last time).
pub fn fill_grid(p: &mut Prepared) {
    let tl = p.t.last().copied().unwrap_or(0.0);
    let n = if tl > 0.0 {
        dronewatt::features::units::ceil_ratio(tl, DT).unwrap_or(0.0) as usize
    } else {
        0
    };
    p.tg = (0..n).map(|k| k as f64 * DT).filter(|&x| x < tl).collect();
    p.ig = interp_sorted(&p.t, &p.i, &p.tg);
    p.vg = interp_sorted(&p.t, &p.v, &p.tg);
}

/// Link consecutive flights flown on the same pack (see the module docs). `all` in
/// increasing flight number, every flight of the file.
pub fn link_chains(all: &mut [Prepared]) {
    for k in 1..all.len() {
        let (a, b) = (&all[k - 1], &all[k]);
        let gap = a.tmin.zip(b.tmin).map(|(x, y)| y - x);
        let linked = a.date == b.date
            && gap.is_some_and(|g| g > 0 && g <= 25)
            && a.on.is_some()
            && b.on.is_some()
            && a.v_end_meas.is_finite()
            && b.v_start.is_finite()
            && b.v_start - a.v_end_meas > -0.05
            && b.v_start - a.v_end_meas < 0.8;
        if linked {
            all[k - 1].next = Some(all[k].flight);
        }
    }
}

/// Heat proxy (A²·s) carried into `flight` from the previous flight on the same pack:
/// the previous flight's heat at its end (itself carried from its own predecessor),
/// decayed over the gap between its end and this flight's start. 0 for a pack with no
/// known predecessor scored under load. Same recursion and formula as fit.py's `heat_carry`.
pub fn heat_carry(
    flight: u32,
    by_id: &HashMap<u32, &Prepared>,
    prev: &HashMap<u32, u32>,
    tau_heat_s: f64,
    cache: &mut HashMap<u32, f64>,
) -> f64 {
    if let Some(h) = cache.get(&flight) {
        return *h;
    }
    let h = (|| {
        let pf = *prev.get(&flight)?;
        let q = by_id.get(&pf).filter(|q| q.ecm_ok() && !q.tg.is_empty())?;
        let r = by_id.get(&flight)?;
        let h0 = heat_carry(pf, by_id, prev, tau_heat_s, cache);
        let a = (-DT / tau_heat_s).exp();
        let h_end = q.ig.iter().fold(h0, |h, i| a * h + DT * i * i);
        let gap = (r.tmin? - q.tmin?) as f64 * 60.0 - q.tg[q.tg.len() - 1];
        Some(h_end * (-gap.max(0.0) / tau_heat_s).exp())
    })()
    .unwrap_or(0.0);
    cache.insert(flight, h);
    h
}

/// The resistance scale k of the flight before `flight` on the same pack
/// ([`dronewatt::battery::Estimator::pack_scale`]: the nominal circuit run over that flight's
/// rows, its own heat carried in), or None for the first flight of a pack. The next flight
/// starts from `params.carried_over(k, PACK_SCALE_CARRY)`.
pub fn previous_pack_scale(
    flight: u32,
    by_id: &HashMap<u32, &Prepared>,
    prev: &HashMap<u32, u32>,
    params: dronewatt::battery::CircuitParams,
    curve: &dronewatt::battery::OcvCurve,
    heat: &mut HashMap<u32, f64>,
) -> Option<f64> {
    let pf = *prev.get(&flight)?;
    let q = by_id.get(&pf).filter(|q| q.ecm_ok() && !q.tg.is_empty())?;
    let h0 = heat_carry(pf, by_id, prev, params.tau_heat_s, heat);
    let mut est = dronewatt::battery::Estimator::new(params, curve.clone(), q.v_start, h0)?;
    for k in 1..q.t.len() {
        est.update(q.t[k] - q.t[k - 1], q.i[k], q.v[k]);
    }
    est.pack_scale()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_and_interp_match_numpy() {
        assert_eq!(median([3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median([4.0, 1.0, 2.0, 3.0, f64::NAN]), 2.5);
        assert!(median([]).is_nan());
        let y = interp_sorted(
            &[0.0, 1.0, 2.0],
            &[0.0, 10.0, 0.0],
            &[-1.0, 0.5, 1.0, 1.5, 3.0],
        );
        assert_eq!(y, vec![0.0, 5.0, 10.0, 5.0, 0.0]);
        assert!((slope(&[0.0, 1.0, 2.0], &[1.0, 3.0, 5.0]) - 2.0).abs() < 1e-12);
        assert_eq!(minutes(" 9:05"), Some(545));
    }
}
