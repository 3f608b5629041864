//! Scores of one model on one flight, in watts: what `dronewatt-lab eval` reports and what
//! `dronewatt-lab train` records in the model card. One function ([`score_over`]) scores
//! both.
//!
//! By default every score is over **in-flight windows** only ([`in_flight`]: measured power
//! above [`IN_FLIGHT_W`]). On the ground the power falls to ~2 W (motors off) or idles; no model of
//! the comparative study describes that, a percentage of it means nothing, and on flight 276
//! the ground windows alone would put ~200 W into every model's MAE and hide every
//! difference in flight. [`score_over`] with `all_windows` scores MAE, RMSE, MSE and energy
//! over every window instead (the LSTM card's and the LightGBM baseline's reading); MAPE
//! stays in flight.
//!
//! * MAE, RMSE, MSE (W, W, W²) and MAPE (%).
//! * Energy error |ΔÊ − ΔE| / ΔE (%), where E is the energy used so far as the live energy
//!   tracker ([`crate::energy::EnergyTracker`]) counts it, integrating the measured power,
//!   and Ê the same tracker integrating the model's estimates instead; Δ sums the tracker's
//!   steps between consecutive scored windows (see [`crate::offline::chain`]). So the
//!   energy a model is scored on is the energy the live chain would have reported with it.
//!
//! Any model's estimates can be scored: the metrics see only aligned series ([`Aligned`]).

use serde::Serialize;

/// Measured power above which a window counts as in flight, W: the motors lift the
/// vehicle (the M100 idles on the ground at well under this, and hovers at ~400 W). The
/// one threshold behind every "in flight" in `eval`, `train`, `calibrate` and
/// `sensitivity`; compare through [`in_flight`].
pub const IN_FLIGHT_W: f64 = 100.0;

/// Is a window with this measured power in flight (measured > [`IN_FLIGHT_W`])? False for
/// a non-finite reading.
pub fn in_flight(measured_w: f64) -> bool {
    in_flight_above(measured_w, IN_FLIGHT_W)
}

/// Is a window with this measured power in flight for a vehicle whose threshold is
/// `threshold_w` ([`in_flight_w_for`])? False for a non-finite reading.
pub fn in_flight_above(measured_w: f64, threshold_w: f64) -> bool {
    measured_w.is_finite() && measured_w > threshold_w
}

/// The in-flight threshold for a vehicle, W: [`IN_FLIGHT_W`], or half the hover power its
/// profile's momentum-theory member gives when that is less than twice it. A 0.74 kg quad
/// hovers at ~70 W: at 100 W not one of its windows would be in flight and `learn` would
/// learn nothing from it. The M100 (and any vehicle hovering above 200 W) keeps 100 W.
pub fn in_flight_w_for(p: &crate::model::profile::VehicleProfile) -> f64 {
    let thrust = p.mass_kg(0.0) * p.air.g_m_s2;
    let ideal = thrust.powf(1.5) / (2.0 * p.air.rho_kg_m3 * p.disk_area_m2()).sqrt();
    let hover = ideal / p.stolaroff.eta + p.stolaroff.p_avio_w;
    if hover.is_finite() && hover > 0.0 {
        IN_FLIGHT_W.min(0.5 * hover)
    } else {
        IN_FLIGHT_W
    }
}

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
    /// Windows MAE, RMSE and MSE are over (summed when pooled or averaged).
    #[serde(skip)]
    pub windows: usize,
    /// In-flight windows MAPE is over.
    #[serde(skip)]
    pub in_flight_windows: usize,
}

/// One model's series over one flight, aligned at the instants its estimates are for
/// (equal lengths). Non-finite entries are not scored.
#[derive(Debug, Clone, Copy)]
pub struct Aligned<'a> {
    /// Measured power at each instant, W.
    pub measured_w: &'a [f64],
    /// The model's estimate for each instant, W.
    pub pred_w: &'a [f64],
    /// Energy used since the start as the energy tracker counts it from the measured
    /// power, at each instant, Wh.
    pub measured_wh: &'a [f64],
    /// Energy used since the start as the energy tracker counts it from this model's
    /// estimates, at each instant, Wh.
    pub pred_wh: &'a [f64],
    /// Measured power above which an instant is in flight, W ([`IN_FLIGHT_W`] unless the
    /// vehicle's is lower: [`in_flight_w_for`]).
    pub in_flight_w: f64,
}

/// Score over the in-flight windows. `None` when no window is in flight.
pub fn score(s: &Aligned) -> Option<Scores> {
    score_over(s, false)
}

/// [`score`], with MAE, RMSE, MSE and energy error over every window when `all_windows`
/// (MAPE always over the in-flight ones). The energy sums take the tracker's step into a
/// scored window from the scored window just before it (none across an unscored one).
pub fn score_over(s: &Aligned, all_windows: bool) -> Option<Scores> {
    let (measured, pred) = (s.measured_w, s.pred_w);
    let finite = |i: usize| {
        measured[i].is_finite()
            && pred[i].is_finite()
            && s.measured_wh[i].is_finite()
            && s.pred_wh[i].is_finite()
    };
    let flying = |i: usize| finite(i) && in_flight_above(measured[i], s.in_flight_w);
    let ok = |i: usize| if all_windows { finite(i) } else { flying(i) };
    let n = measured
        .len()
        .min(pred.len())
        .min(s.measured_wh.len())
        .min(s.pred_wh.len());
    let (mut n_all, mut abs, mut sq, mut pct, mut n_pct) = (0usize, 0.0, 0.0, 0.0, 0usize);
    let (mut e_meas, mut e_pred) = (0.0, 0.0);
    for i in (0..n).filter(|&i| ok(i)) {
        let e = pred[i] - measured[i];
        n_all += 1;
        abs += e.abs();
        sq += e * e;
        if flying(i) {
            pct += (e / measured[i]).abs();
            n_pct += 1;
        }
        if i > 0 && ok(i - 1) {
            e_meas += s.measured_wh[i] - s.measured_wh[i - 1];
            e_pred += s.pred_wh[i] - s.pred_wh[i - 1];
        }
    }
    if n_pct == 0 {
        return None;
    }
    let mse = sq / n_all as f64;
    Some(Scores {
        mae_w: abs / n_all as f64,
        rmse_w: mse.sqrt(),
        mse_w2: mse,
        mape_pct: 100.0 * pct / n_pct as f64,
        energy_err_pct: if e_meas > 0.0 {
            100.0 * (e_pred - e_meas).abs() / e_meas
        } else {
            f64::NAN
        },
        windows: n_all,
        in_flight_windows: n_pct,
    })
}

/// Scores over the windows of several flights together: MAE, MSE, RMSE and MAPE as if
/// one series (each flight weighted by its windows), energy error the mean over flights.
pub fn pooled(scores: &[Scores]) -> Option<Scores> {
    let n: usize = scores.iter().map(|s| s.windows).sum();
    let n_pct: usize = scores.iter().map(|s| s.in_flight_windows).sum();
    if n == 0 || n_pct == 0 {
        return None;
    }
    let mse = scores
        .iter()
        .map(|s| s.mse_w2 * s.windows as f64)
        .sum::<f64>()
        / n as f64;
    Some(Scores {
        mae_w: scores
            .iter()
            .map(|s| s.mae_w * s.windows as f64)
            .sum::<f64>()
            / n as f64,
        rmse_w: mse.sqrt(),
        mse_w2: mse,
        mape_pct: scores
            .iter()
            .map(|s| s.mape_pct * s.in_flight_windows as f64)
            .sum::<f64>()
            / n_pct as f64,
        energy_err_pct: mean(scores)?.energy_err_pct,
        windows: n,
        in_flight_windows: n_pct,
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
        windows: scores.iter().map(|s| s.windows).sum(),
        in_flight_windows: scores.iter().map(|s| s.in_flight_windows).sum(),
    })
}

/// The median of `v` (sorted in place; the mean of the middle two for an even count), NaN
/// for none: the one median of the offline reports (plan-eval's fit, battery-eval).
pub fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The median of the finite values of `x`; NaN if none.
pub fn median_finite(x: impl IntoIterator<Item = f64>) -> f64 {
    median(&mut x.into_iter().filter(|a| a.is_finite()).collect::<Vec<_>>())
}

/// Split-conformal widening of a band (CQR, Romano et al. 2019): given each calibration
/// window's excess outside its band, `max(low − y, y − high)` (negative inside), the watts
/// to add on each side so that the band covers at least `coverage` of them: the
/// ⌈(n + 1)·coverage⌉-th smallest excess, never negative (a band is widened, not narrowed).
/// `None` with no finite excess.
pub fn conformal_widening(excess: &mut Vec<f64>, coverage: f64) -> Option<f64> {
    conformal_quantile(excess, coverage).map(|q| q.max(0.0))
}

/// [`conformal_widening`] before it is floored at 0: negative when the band already covers
/// more than `coverage` of the calibration windows (by how much it could narrow). A
/// cross-validation records it per fold, so the folds' mean keeps its sign.
pub fn conformal_quantile(excess: &mut Vec<f64>, coverage: f64) -> Option<f64> {
    excess.retain(|e| e.is_finite());
    if excess.is_empty() || !(0.0..1.0).contains(&coverage) {
        return None;
    }
    excess.sort_by(f64::total_cmp);
    let n = excess.len();
    let k = (((n + 1) as f64 * coverage).ceil() as usize).clamp(1, n);
    Some(excess[k - 1])
}

/// The `q` quantile of `v` (sorted in place), linear between ranks; NaN for none.
pub fn quantile(v: &mut [f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let pos = q * (v.len() - 1) as f64;
    let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
    v[lo] + (v[hi] - v[lo]) * (pos - lo as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_small_vehicle_is_in_flight_below_100_w_and_the_m100_keeps_it() {
        use crate::model::profile::VehicleProfile;
        assert_eq!(in_flight_w_for(&VehicleProfile::m100()), IN_FLIGHT_W);
        // the Mavic Pro's five facts: 0.743 kg on four 0.2108 m propellers hovers at ~85 W
        // on the priors; half of it is its threshold
        let spec = "[vehicle]\ntakeoff_kg = 0.743\nrotors = 4\nprop_diameter_m = 0.2108\n";
        let p = VehicleProfile::from_toml(spec, "mavic.toml").unwrap();
        let w = in_flight_w_for(&p);
        assert!((35.0..50.0).contains(&w), "{w}");
        assert!(in_flight_above(60.0, w) && !in_flight(60.0));
    }

    proptest::proptest! {
        /// Widened by the conformal amount, a band covers at least the asked share of the
        /// calibration windows, and the amount is never negative.
        #[test]
        fn conformal_widening_covers_the_calibration_set(
            excess in proptest::collection::vec(-50.0f64..50.0, 1..300),
            coverage in 0.5f64..0.99,
        ) {
            let q = conformal_widening(&mut excess.clone(), coverage).expect("some excess");
            proptest::prop_assert!(q >= 0.0);
            let inside = excess.iter().filter(|e| **e <= q).count();
            proptest::prop_assert!(inside as f64 >= coverage * excess.len() as f64);
            // The signed quantile covers the same share, and is the widening unless negative.
            let s = conformal_quantile(&mut excess.clone(), coverage).expect("some excess");
            proptest::prop_assert_eq!(s.max(0.0), q);
            let inside = excess.iter().filter(|e| **e <= s).count();
            proptest::prop_assert!(inside as f64 >= coverage * excess.len() as f64);
        }
    }

    #[test]
    fn conformal_widening_of_nothing_is_none() {
        assert_eq!(conformal_widening(&mut vec![], 0.9), None);
        assert_eq!(conformal_widening(&mut vec![f64::NAN], 0.9), None);
        assert_eq!(conformal_widening(&mut vec![1.0], 1.5), None);
        // A band that already covers everything is not narrowed; the signed quantile says
        // by how much it could be.
        assert_eq!(
            conformal_widening(&mut vec![-3.0, -2.0, -1.0], 0.9),
            Some(0.0)
        );
        assert_eq!(
            conformal_quantile(&mut vec![-3.0, -2.0, -1.0], 0.9),
            Some(-1.0)
        );
        // 10 windows, 90 %: the ⌈11 · 0.9⌉ = 10th smallest.
        let mut e: Vec<f64> = (1..=10).map(f64::from).collect();
        assert_eq!(conformal_widening(&mut e, 0.9), Some(10.0));
    }

    /// Energy used so far at each time, Wh: trapezoids, as the tracker integrates steps
    /// no longer than its cap.
    fn used_wh(t: &[f64], p: &[f64]) -> Vec<f64> {
        let mut e = vec![0.0];
        for i in 1..t.len() {
            e.push(e[i - 1] + 0.5 * (t[i] - t[i - 1]) * (p[i] + p[i - 1]) / 3600.0);
        }
        e
    }

    #[test]
    fn hand_computed() {
        // Sample 0 is on the ground (50 W): ignored. In flight: errors −20, +30, 0 W.
        let t = [0.0, 1.0, 2.0, 3.0];
        let m = [50.0, 200.0, 300.0, 400.0];
        let p = [460.0, 180.0, 330.0, 400.0];
        let (mw, pw) = (used_wh(&t, &m), used_wh(&t, &p));
        fn series<'a>(m: &'a [f64], p: &'a [f64], mw: &'a [f64], pw: &'a [f64]) -> Aligned<'a> {
            Aligned {
                measured_w: m,
                pred_w: p,
                measured_wh: mw,
                pred_wh: pw,
                in_flight_w: IN_FLIGHT_W,
            }
        }
        let s = score(&series(&m, &p, &mw, &pw)).unwrap();
        assert!((s.mae_w - 50.0 / 3.0).abs() < 1e-12);
        assert!((s.mse_w2 - 1300.0 / 3.0).abs() < 1e-9);
        assert!((s.rmse_w - (1300.0f64 / 3.0).sqrt()).abs() < 1e-12);
        // (20/200 + 30/300 + 0)/3 = 6.667 %.
        assert!((s.mape_pct - 20.0 / 3.0).abs() < 1e-9);
        // ∫meas = 250 + 350 = 600 W·s; ∫pred = 255 + 365 = 620 → 3.333 %.
        assert!((s.energy_err_pct - 100.0 * 20.0 / 600.0).abs() < 1e-9);
        assert!(score(&series(&[], &[], &[], &[])).is_none());
        assert!(score(&series(&[50.0], &[50.0], &[0.0], &[0.0])).is_none());
        // All windows: the ground sample's +410 W joins MAE and energy, not MAPE.
        let a = score_over(&series(&m, &p, &mw, &pw), true).unwrap();
        assert!((a.mae_w - 460.0 / 4.0).abs() < 1e-12);
        assert!((a.mape_pct - s.mape_pct).abs() < 1e-12);
        // ∫meas = 125 + 600 = 725 W·s; ∫pred = 320 + 620 = 940.
        assert!((a.energy_err_pct - 100.0 * 215.0 / 725.0).abs() < 1e-9);
        let m2 = mean(&[
            s,
            Scores {
                mae_w: 5.0,
                mape_pct: f64::NAN,
                ..s
            },
        ])
        .unwrap();
        assert!(
            (m2.mae_w - (50.0 / 3.0 + 5.0) / 2.0).abs() < 1e-12
                && (m2.mape_pct - s.mape_pct).abs() < 1e-12
        );
    }

    #[test]
    fn the_threshold_is_strict_and_pooling_weights_by_windows() {
        assert!(
            !in_flight(IN_FLIGHT_W)
                && in_flight(IN_FLIGHT_W + 0.01)
                && !in_flight(f64::NAN)
                && !in_flight(f64::INFINITY)
        );
        // Two flights: 1 window with error 10 W, 3 windows with error 2 W.
        let a = Scores {
            mae_w: 10.0,
            rmse_w: 10.0,
            mse_w2: 100.0,
            mape_pct: 5.0,
            energy_err_pct: 1.0,
            windows: 1,
            in_flight_windows: 1,
        };
        let b = Scores {
            mae_w: 2.0,
            rmse_w: 2.0,
            mse_w2: 4.0,
            mape_pct: 1.0,
            energy_err_pct: 3.0,
            windows: 3,
            in_flight_windows: 3,
        };
        let p = pooled(&[a, b]).unwrap();
        assert!((p.mae_w - 16.0 / 4.0).abs() < 1e-12 && (p.mse_w2 - 112.0 / 4.0).abs() < 1e-12);
        assert!((p.mape_pct - 8.0 / 4.0).abs() < 1e-12 && (p.energy_err_pct - 2.0).abs() < 1e-12);
        assert_eq!((p.windows, p.in_flight_windows), (4, 4));
        assert!(pooled(&[]).is_none());
    }
}
