//! Scores of one model on one flight, in watts: what `dronewatt eval` reports.
//!
//! By default every score is over **in-flight windows** only: measured power >
//! [`IN_FLIGHT_W`]. On the ground the power falls to ~2 W (motors off) or idles; no model of
//! the comparative study describes that, a percentage of it means nothing, and on flight 276
//! the ground windows alone would put ~200 W into every model's MAE and hide every
//! difference in flight. [`score_over`] with `all_windows` scores MAE, RMSE, MSE and energy
//! over every window instead (the LSTM card's and the LightGBM baseline's reading); MAPE
//! stays in flight.
//!
//! * MAE, RMSE, MSE (W, W, W²) and MAPE (%).
//! * Energy error |∫P̂ dt − ∫P dt| / ∫P dt (%), trapezoids between consecutive in-flight
//!   windows.
//!
//! Any model's predictions can be scored: the metrics see only (time, measured, predicted).

use serde::Serialize;

/// Measured power above which a window counts as in flight, W.
pub const IN_FLIGHT_W: f64 = 100.0;

/// One model's scores on one flight (or the mean over flights).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Scores {
    /// Mean absolute error, W.
    pub mae_w: f64,
    /// Root mean square error, W.
    pub rmse_w: f64,
    /// Mean square error, W².
    pub mse_w2: f64,
    /// Mean absolute percentage error, %.
    pub mape_pct: f64,
    /// Flight energy error, %.
    pub energy_err_pct: f64,
}

/// Score `pred` against `measured` at times `t_s` over the in-flight windows (equal
/// lengths; non-finite pairs are skipped). `None` when no window is in flight.
pub fn score(t_s: &[f64], measured: &[f64], pred: &[f64]) -> Option<Scores> {
    score_over(t_s, measured, pred, false)
}

/// [`score`], with MAE, RMSE, MSE and energy error over every window when `all_windows`
/// (MAPE always over the in-flight ones).
pub fn score_over(t_s: &[f64], measured: &[f64], pred: &[f64], all_windows: bool) -> Option<Scores> {
    let finite = |i: usize| measured[i].is_finite() && pred[i].is_finite() && t_s[i].is_finite();
    let flying = |i: usize| finite(i) && measured[i] > IN_FLIGHT_W;
    let ok = |i: usize| if all_windows { finite(i) } else { flying(i) };
    let n = t_s.len().min(measured.len()).min(pred.len());
    let (mut n_all, mut abs, mut sq, mut pct, mut n_pct) = (0usize, 0.0, 0.0, 0.0, 0usize);
    for i in (0..n).filter(|&i| ok(i)) {
        let e = pred[i] - measured[i];
        n_all += 1;
        abs += e.abs();
        sq += e * e;
        if flying(i) {
            pct += (e / measured[i]).abs();
            n_pct += 1;
        }
    }
    if n_pct == 0 {
        return None;
    }
    let (mut e_meas, mut e_pred, mut prev) = (0.0, 0.0, None::<usize>);
    for i in 0..n {
        if !ok(i) {
            prev = None;
            continue;
        }
        if let Some(j) = prev {
            let dt = t_s[i] - t_s[j];
            if dt > 0.0 {
                e_meas += 0.5 * dt * (measured[i] + measured[j]);
                e_pred += 0.5 * dt * (pred[i] + pred[j]);
            }
        }
        prev = Some(i);
    }
    let mse = sq / n_all as f64;
    Some(Scores {
        mae_w: abs / n_all as f64,
        rmse_w: mse.sqrt(),
        mse_w2: mse,
        mape_pct: 100.0 * pct / n_pct as f64,
        energy_err_pct: if e_meas > 0.0 { 100.0 * (e_pred - e_meas).abs() / e_meas } else { f64::NAN },
    })
}

/// Mean of each score over flights (NaN entries skipped per score).
pub fn mean(scores: &[Scores]) -> Option<Scores> {
    if scores.is_empty() {
        return None;
    }
    let avg = |f: fn(&Scores) -> f64| {
        let v: Vec<f64> = scores.iter().map(f).filter(|x| x.is_finite()).collect();
        if v.is_empty() {
            f64::NAN
        } else {
            v.iter().sum::<f64>() / v.len() as f64
        }
    };
    Some(Scores {
        mae_w: avg(|s| s.mae_w),
        rmse_w: avg(|s| s.rmse_w),
        mse_w2: avg(|s| s.mse_w2),
        mape_pct: avg(|s| s.mape_pct),
        energy_err_pct: avg(|s| s.energy_err_pct),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_computed() {
        // Sample 0 is on the ground (50 W): ignored. In flight: errors −20, +30, 0 W.
        let t = [0.0, 1.0, 2.0, 3.0];
        let m = [50.0, 200.0, 300.0, 400.0];
        let p = [460.0, 180.0, 330.0, 400.0];
        let s = score(&t, &m, &p).unwrap();
        assert!((s.mae_w - 50.0 / 3.0).abs() < 1e-12);
        assert!((s.mse_w2 - 1300.0 / 3.0).abs() < 1e-9);
        assert!((s.rmse_w - (1300.0f64 / 3.0).sqrt()).abs() < 1e-12);
        // (20/200 + 30/300 + 0)/3 = 6.667 %.
        assert!((s.mape_pct - 20.0 / 3.0).abs() < 1e-9);
        // ∫meas = 250 + 350 = 600 W·s; ∫pred = 255 + 365 = 620 → 3.333 %.
        assert!((s.energy_err_pct - 100.0 * 20.0 / 600.0).abs() < 1e-9);
        assert!(score(&[], &[], &[]).is_none());
        assert!(score(&[0.0], &[50.0], &[50.0]).is_none());
        // All windows: the ground sample's +410 W joins MAE and energy, not MAPE.
        let a = score_over(&t, &m, &p, true).unwrap();
        assert!((a.mae_w - 460.0 / 4.0).abs() < 1e-12);
        assert!((a.mape_pct - s.mape_pct).abs() < 1e-12);
        // ∫meas = 125 + 600 = 725 W·s; ∫pred = 320 + 620 = 940.
        assert!((a.energy_err_pct - 100.0 * 215.0 / 725.0).abs() < 1e-9);
        let m2 = mean(&[s, Scores { mae_w: 5.0, mape_pct: f64::NAN, ..s }]).unwrap();
        assert!((m2.mae_w - (50.0 / 3.0 + 5.0) / 2.0).abs() < 1e-12 && (m2.mape_pct - s.mape_pct).abs() < 1e-12);
    }
}
