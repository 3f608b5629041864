//! The physics models' least-squares fit (bounded Levenberg–Marquardt with nalgebra), shared by
//! `dronewatt learn` and the lab's `calibrate`: on in-flight windows only ([`in_flight_above`]
//! the vehicle's [`in_flight_w_for`]), free parameters per model as below, the rest as
//! published.
//!
//! What is free per model (the rest stays as published, because it is not identifiable
//! beside what is fitted — e.g. η and r enter D'Andrea only as their product):
//!
//! | model | free parameters |
//! |---|---|
//! | dandrea, dandrea_headwind | lift_drag (r), p_avio_w |
//! | dorling | eta, p_avio_w |
//! | stolaroff | eta, drag_area_m2, p_avio_w |
//! | kirschstein | kappa, kappa2, kappa3, drag_area_m2, p_avio_w |
//! | tseng | β₁…β₉ |
//! | tseng_solo | c₁…c₃ |

use nalgebra::{DMatrix, DVector};

use crate::model::physics::{Kind, Kinematics};
use crate::model::profile::{Calibration, VehicleProfile};
use crate::offline::data::{FlightWindows, TEST_FLIGHTS};
use crate::offline::metrics::{in_flight_above, in_flight_w_for};

/// Training fit of one model.
#[derive(Debug, Clone)]
pub struct FitReport {
    /// Model base name.
    pub model: &'static str,
    /// Training RMSE with the published parameters, W.
    pub rmse_before_w: f64,
    /// Training RMSE with the fitted parameters, W.
    pub rmse_after_w: f64,
}

/// Which parameters of a model are free, their bounds, and where they sit in a profile.
struct Spec {
    kind: Kind,
    lo: Vec<f64>,
    hi: Vec<f64>,
    /// The free parameters of a profile, in the order of `lo` and `hi`.
    params: fn(&mut VehicleProfile) -> Vec<&mut f64>,
}

impl Spec {
    fn new(
        kind: Kind,
        lo: &[f64],
        hi: &[f64],
        params: fn(&mut VehicleProfile) -> Vec<&mut f64>,
    ) -> Self {
        Self {
            kind,
            lo: lo.to_vec(),
            hi: hi.to_vec(),
            params,
        }
    }

    fn get(&self, p: &VehicleProfile) -> Vec<f64> {
        (self.params)(&mut p.clone())
            .into_iter()
            .map(|v| *v)
            .collect()
    }

    fn set(&self, p: &mut VehicleProfile, x: &[f64]) {
        for (v, x) in (self.params)(p).into_iter().zip(x) {
            *v = *x;
        }
    }
}

const INF: f64 = f64::INFINITY;

fn specs() -> Vec<Spec> {
    let spec = Spec::new;
    vec![
        spec(Kind::DAndrea, &[0.05, 0.0], &[1e4, 5e3], |p| {
            vec![&mut p.dandrea.lift_drag, &mut p.dandrea.p_avio_w]
        }),
        spec(Kind::DAndreaHeadwind, &[0.05, 0.0], &[1e4, 5e3], |p| {
            let m = &mut p.dandrea_headwind;
            vec![&mut m.lift_drag, &mut m.p_avio_w]
        }),
        spec(Kind::Dorling, &[0.05, 0.0], &[5.0, 5e3], |p| {
            vec![&mut p.dorling.eta, &mut p.dorling.p_avio_w]
        }),
        spec(Kind::Stolaroff, &[0.05, 0.0, 0.0], &[5.0, 5.0, 5e3], |p| {
            let m = &mut p.stolaroff;
            vec![&mut m.eta, &mut m.drag_area_m2, &mut m.p_avio_w]
        }),
        spec(
            Kind::Kirschstein,
            &[0.1, 0.0, 0.0, 0.0, 0.0],
            &[20.0, 50.0, 10.0, 5.0, 5e3],
            |p| {
                let k = &mut p.kirschstein;
                vec![
                    &mut k.kappa,
                    &mut k.kappa2,
                    &mut k.kappa3,
                    &mut k.drag_area_m2,
                    &mut k.p_avio_w,
                ]
            },
        ),
        spec(Kind::Tseng, &[-INF; 9], &[INF; 9], |p| {
            p.tseng.beta.iter_mut().collect()
        }),
        spec(Kind::TsengSolo, &[-INF; 3], &[INF; 3], |p| {
            p.tseng_solo.coef.iter_mut().collect()
        }),
    ]
}

/// Fit every physics model on these flights (test flights and ground tests are dropped
/// here, whatever the caller passed) and return the calibrated profile and the training
/// RMSE before and after.
pub fn fit(
    flights: &[FlightWindows],
    base: &VehicleProfile,
    data_sha256: String,
    max_windows: usize,
) -> anyhow::Result<(VehicleProfile, Vec<FitReport>)> {
    let train: Vec<&FlightWindows> = flights
        .iter()
        .filter(|f| !TEST_FLIGHTS.contains(&f.flight) && !f.route.starts_with('A'))
        .collect();
    let mut states: Vec<(Kinematics, f64)> = Vec::new();
    let threshold = in_flight_w_for(base);
    for f in &train {
        for w in &f.windows {
            if let Some(m) = w
                .last()
                .measured_w
                .map(f64::from)
                .filter(|m| in_flight_above(*m, threshold))
            {
                states.push((Kinematics::from_window(w, base), m));
            }
        }
    }
    if states.len() < 50 {
        anyhow::bail!(
            "only {} in-flight windows in {} training flights: too few to calibrate",
            states.len(),
            train.len()
        );
    }
    let stride = states.len().div_ceil(max_windows.max(50));
    let states: Vec<(Kinematics, f64)> = states.into_iter().step_by(stride).collect();
    tracing::info!(
        flights = train.len(),
        windows = states.len(),
        "calibrating physics models"
    );
    let bar = indicatif::ProgressBar::new(specs().len() as u64).with_style(
        indicatif::ProgressStyle::with_template("calibrating {bar:30} {pos}/{len} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut cal = base.clone();
    let mut report = Vec::new();
    for spec in specs() {
        bar.set_message(spec.kind.name());
        let rmse = |p: &VehicleProfile| {
            let se: f64 = states
                .iter()
                .map(|(k, m)| (spec.kind.power_w(k, p) - m).powi(2))
                .sum();
            (se / states.len() as f64).sqrt()
        };
        let before = rmse(base);
        let mut scratch = base.clone();
        let x = levenberg_marquardt(spec.get(base), &spec.lo, &spec.hi, states.len(), |x, r| {
            spec.set(&mut scratch, x);
            for (ri, (k, m)) in r.iter_mut().zip(&states) {
                *ri = spec.kind.power_w(k, &scratch) - m;
            }
        });
        spec.set(&mut cal, &x);
        let after = rmse(&cal);
        report.push(FitReport {
            model: spec.kind.name(),
            rmse_before_w: before,
            rmse_after_w: after,
        });
        bar.inc(1);
    }
    bar.finish_and_clear();
    cal.name = format!("{} (calibrated)", base.name);
    cal.calibration = Some(Calibration {
        data_sha256,
        flights: train.iter().map(|f| f.flight).collect(),
        windows: states.len(),
    });
    cal.validate()
        .map_err(|e| anyhow::anyhow!("calibration produced an invalid profile: {e}"))?;
    Ok((cal, report))
}

/// Minimise Σ rᵢ(x)² over the box [lo, hi] by Levenberg–Marquardt with Marquardt's
/// diagonal scaling and a forward-difference Jacobian; steps are projected onto the box.
/// `resid(x, r)` fills the `n` residuals. Returns the best x seen.
pub fn levenberg_marquardt(
    x0: Vec<f64>,
    lo: &[f64],
    hi: &[f64],
    n: usize,
    mut resid: impl FnMut(&[f64], &mut [f64]),
) -> Vec<f64> {
    let k = x0.len();
    let clamp = |x: &mut [f64]| {
        for i in 0..k {
            x[i] = x[i].clamp(lo[i], hi[i]);
        }
    };
    let mut x = x0;
    clamp(&mut x);
    let mut r = vec![0.0; n];
    let mut r2 = vec![0.0; n];
    resid(&x, &mut r);
    let cost = |r: &[f64]| r.iter().map(|v| v * v).sum::<f64>();
    let mut c = cost(&r);
    let mut lambda = 1e-3;
    let mut jac = DMatrix::<f64>::zeros(n, k);
    for _ in 0..200 {
        for j in 0..k {
            let h = 1e-6 * x[j].abs().max(1e-3);
            let mut xh = x.clone();
            xh[j] += h;
            resid(&xh, &mut r2);
            for i in 0..n {
                jac[(i, j)] = (r2[i] - r[i]) / h;
            }
        }
        let jtj = jac.transpose() * &jac;
        let jtr = jac.transpose() * DVector::from_column_slice(&r);
        let mut improved = false;
        while lambda < 1e12 {
            let mut a = jtj.clone();
            for d in 0..k {
                a[(d, d)] += lambda * jtj[(d, d)].max(1e-12);
            }
            let Some(step) = a.cholesky().map(|ch| ch.solve(&(-&jtr))) else {
                lambda *= 10.0;
                continue;
            };
            let mut xn: Vec<f64> = x.iter().zip(step.iter()).map(|(a, b)| a + b).collect();
            clamp(&mut xn);
            resid(&xn, &mut r2);
            let cn = cost(&r2);
            if cn.is_finite() && cn < c {
                let rel = (c - cn) / c.max(1e-300);
                x = xn;
                std::mem::swap(&mut r, &mut r2);
                c = cn;
                lambda = (lambda / 3.0).max(1e-12);
                improved = rel > 1e-10;
                break;
            }
            lambda *= 4.0;
        }
        if !improved {
            break;
        }
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lm_recovers_a_nonlinear_fit_and_respects_bounds() {
        // y = a·exp(b·t) + c with a = 2, b = −0.7, c = 1.
        let t: Vec<f64> = (0..40).map(|i| i as f64 * 0.1).collect();
        let y: Vec<f64> = t.iter().map(|t| 2.0 * (-0.7 * t).exp() + 1.0).collect();
        let f = |x: &[f64], r: &mut [f64]| {
            for ((ri, t), y) in r.iter_mut().zip(&t).zip(&y) {
                *ri = x[0] * (x[1] * t).exp() + x[2] - y;
            }
        };
        let x = levenberg_marquardt(vec![1.0, -0.1, 0.0], &[-INF; 3], &[INF; 3], t.len(), f);
        assert!(
            (x[0] - 2.0).abs() < 1e-5 && (x[1] + 0.7).abs() < 1e-5 && (x[2] - 1.0).abs() < 1e-5,
            "{x:?}"
        );
        let x = levenberg_marquardt(
            vec![1.0, -0.1, 0.0],
            &[-INF, -INF, 0.0],
            &[1.5, INF, INF],
            t.len(),
            f,
        );
        assert!(x[0] <= 1.5 && x[2] >= 0.0, "{x:?}");
    }
}
