//! A model's own regression fitted online: for a model linear in its regressors,
//! `P = θ·φ` (the fixed-wing model's φ = [ρV³, (n·m·g)²/(ρV), m·g·v_z, 1]), the
//! coefficients θ themselves follow the vehicle, not only an affine correction of the
//! output. The same scheme as the affine fit ([`super`]): exponentially weighted least
//! squares with forgetting λ (its own memory, `regression_memory_s`, 0.5 s by default),
//! the prior θ₀ (the model's published coefficients) kept as a fixed regulariser R₀ = diag(σ_y² / σ_k²) with σ_k = 50 % of θ₀ₖ (σ_y = 20 W), and
//! bounds after every solve: each coefficient within [θ₀ₖ/4, 4·θ₀ₖ] (the offset within
//! [0, 4·θ₀ + 50 W]). The prior holds what the flight does not excite (a plane that never
//! climbs says nothing about its climb coefficient). A 4 × 4 solve a window. The
//! prediction is then low-passed ([`RegressionFit::smooth`], `regression_smooth_s`).

/// Regressors and coefficients: four of each.
pub const N: usize = 4;
/// The measurement noise the prior is weighed against, W (as the affine fit's σ_y).
const SIGMA_Y_W: f64 = 20.0;
/// The prior's width, a share of each coefficient.
const PRIOR_FRAC: f64 = 0.5;

/// The fit of one model on one vehicle.
#[derive(Debug, Clone)]
pub struct RegressionFit {
    s: [[f64; N]; N],
    r: [f64; N],
    theta0: [f64; N],
    theta: [f64; N],
    /// The low-passed prediction ([`RegressionFit::smooth`]), None before the first.
    smoothed: Option<f64>,
    /// Windows that taught it.
    pub taught: u64,
}

impl RegressionFit {
    /// A fit starting at the model's own coefficients `theta0` (all ≥ 0).
    pub fn new(theta0: [f64; N]) -> Self {
        Self {
            s: [[0.0; N]; N],
            r: [0.0; N],
            theta0,
            theta: theta0,
            smoothed: None,
            taught: 0,
        }
    }

    /// The coefficients now.
    pub fn theta(&self) -> [f64; N] {
        self.theta
    }

    /// The fitted prediction for regressors `phi`, W (never below the fitted offset).
    pub fn predict(&self, phi: &[f64; N]) -> f64 {
        let p: f64 = (0..N).map(|k| self.theta[k] * phi[k]).sum();
        if p.is_finite() {
            p.max(self.theta[N - 1])
        } else {
            self.theta[N - 1]
        }
    }

    /// The prediction `p` (W) low-passed: λ·(the previous) + (1 − λ)·`p`, `p` itself the
    /// first time, or when either is not finite; λ = 0 passes `p` through.
    pub fn smooth(&mut self, p: f64, lambda: f64) -> f64 {
        let s = match self.smoothed {
            Some(prev) if prev.is_finite() && p.is_finite() => lambda * prev + (1.0 - lambda) * p,
            _ => p,
        };
        self.smoothed = Some(s);
        s
    }

    /// Teach with regressors `phi` and measured power `y` (W), forgetting by `lambda`.
    pub fn teach(&mut self, phi: &[f64; N], y: f64, lambda: f64) {
        if !(y.is_finite() && phi.iter().all(|x| x.is_finite())) {
            return;
        }
        for k in 0..N {
            self.r[k] = lambda * self.r[k] + phi[k] * y;
            for j in 0..N {
                self.s[k][j] = lambda * self.s[k][j] + phi[k] * phi[j];
            }
        }
        self.taught += 1;
        self.solve();
    }

    fn solve(&mut self) {
        // (S + R₀)·θ = r + R₀·θ₀, R₀ diagonal.
        let mut a = self.s;
        let mut b = self.r;
        for k in 0..N {
            let sigma = (PRIOR_FRAC * self.theta0[k]).abs().max(1e-12);
            let r0 = SIGMA_Y_W * SIGMA_Y_W / (sigma * sigma);
            a[k][k] += r0;
            b[k] += r0 * self.theta0[k];
        }
        let Some(theta) = gauss(a, b) else {
            return;
        };
        for (k, (now, (&t, &t0))) in self
            .theta
            .iter_mut()
            .zip(theta.iter().zip(&self.theta0))
            .enumerate()
        {
            let (lo, hi) = if k == N - 1 {
                (0.0, 4.0 * t0 + 50.0)
            } else {
                (t0 / 4.0, 4.0 * t0)
            };
            if t.is_finite() {
                *now = t.clamp(lo, hi);
            }
        }
    }
}

/// Solve a·x = b by Gaussian elimination with partial pivoting; `None` when singular.
fn gauss(mut a: [[f64; N]; N], mut b: [f64; N]) -> Option<[f64; N]> {
    for c in 0..N {
        let p = (c..N).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if a[p][c].abs() < 1e-300 || !a[p][c].is_finite() {
            return None;
        }
        a.swap(c, p);
        b.swap(c, p);
        let (pivot_row, pivot_b) = (a[c], b[c]);
        for (row, bi) in a.iter_mut().zip(b.iter_mut()).skip(c + 1) {
            let f = row[c] / pivot_row[c];
            for (x, &pv) in row.iter_mut().zip(&pivot_row).skip(c) {
                *x -= f * pv;
            }
            *bi -= f * pivot_b;
        }
    }
    let mut x = [0.0; N];
    for i in (0..N).rev() {
        let s: f64 = (i + 1..N).map(|j| a[i][j] * x[j]).sum();
        x[i] = (b[i] - s) / a[i][i];
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_low_pass_starts_at_the_first_prediction_blends_after_and_passes_nan_by() {
        let mut fit = RegressionFit::new([0.01, 0.1, 2.0, 5.0]);
        assert_eq!(fit.smooth(40.0, 0.8), 40.0);
        assert!((fit.smooth(50.0, 0.8) - 42.0).abs() < 1e-12);
        // λ = 0: none.
        assert_eq!(fit.smooth(60.0, 0.0), 60.0);
        // A non-finite prediction is passed on, and the next finite one starts afresh.
        assert!(fit.smooth(f64::NAN, 0.8).is_nan());
        assert_eq!(fit.smooth(30.0, 0.8), 30.0);
        // A step settles to within 1 % in ln(100)/(1 − λ) windows or so.
        let mut fit = RegressionFit::new([0.01, 0.1, 2.0, 5.0]);
        fit.smooth(0.0, 0.8);
        let last = (0..25)
            .map(|_| fit.smooth(100.0, 0.8))
            .last()
            .unwrap_or(0.0);
        assert!(last > 99.0 && last <= 100.0, "{last}");
    }

    #[test]
    fn learns_a_plane_that_is_not_the_default_within_a_minute_and_stays_bounded() {
        // The defaults' coefficients (S·C_D0/2η, 2/(S·π·e·AR·η), 1/η, P_0) of the 2 kg plane,
        // and a "true" plane with 40 % more drag, 30 % more induced loss, a better η and 8 W.
        let theta0 = [0.0126, 0.1008, 2.0, 5.0];
        let truth = [0.0176, 0.1310, 1.7, 8.0];
        let mut fit = RegressionFit::new(theta0);
        let lambda = (-0.1f64 / 30.0).exp();
        let phi = |i: usize| {
            // 10 Hz over a minute: airspeed 11–17 m/s, climbs and descents, one turn.
            let t = i as f64 * 0.1;
            let v = 14.0 + 3.0 * (t / 7.0).sin();
            let n = if (20.0..30.0).contains(&t) { 1.3 } else { 1.0 };
            let climb = 1.5 * (t / 11.0).sin();
            let w = n * 2.0 * crate::features::units::G;
            [
                1.2 * v * v * v,
                w * w / (1.2 * v),
                2.0 * crate::features::units::G * climb,
                1.0,
            ]
        };
        let y = |p: &[f64; N]| (0..N).map(|k| truth[k] * p[k]).sum::<f64>();
        let before: f64 = (600..700)
            .map(|i| ((fit.predict(&phi(i)) - y(&phi(i))) / y(&phi(i))).abs())
            .sum::<f64>()
            / 100.0;
        for i in 0..600 {
            let p = phi(i);
            fit.teach(&p, y(&p), lambda);
        }
        let after: f64 = (600..700)
            .map(|i| ((fit.predict(&phi(i)) - y(&phi(i))) / y(&phi(i))).abs())
            .sum::<f64>()
            / 100.0;
        assert!(before > 0.15, "the default is off: {before}");
        assert!(after < 0.03, "after 60 s: {after} (θ = {:?})", fit.theta());
        // Garbage never leaves the bounds.
        for i in 0..200 {
            let p = phi(i);
            fit.teach(&p, if i % 2 == 0 { 1e6 } else { -1e6 }, lambda);
            fit.teach(&[f64::NAN; N], 1.0, lambda);
        }
        for (k, t) in fit.theta().iter().enumerate() {
            let t0 = theta0[k];
            let hi = if k == N - 1 {
                4.0 * t0 + 50.0
            } else {
                4.0 * t0
            };
            assert!(t.is_finite() && *t <= hi && *t >= 0.0, "θ{k} = {t}");
        }
    }
}
