//! The flight's own resistance, split into the part that stays and the part that warms off.
//!
//! Why: the RLS ([`super::Estimator`]) tracks the resistance of the last ~30 s, and the
//! circuit's warm factor f = 1 + warm_a·exp(−H/heat_scale) says how a *typical* pack's cold
//! excess fades with heat H. A pack flown cold (the first flight of a morning) carries a
//! larger excess that fades faster than the typical one; one flown warm, or a simulated pack
//! with a constant resistance, none. A forecast from half time that holds the RLS's value
//! (scaled by the typical f) then sags 0.7–1.2 V too deep on such a pack (M100 test flights
//! 268 and 277: R fell 0.136 → 0.085 Ω within the flight). So the forecast reads both parts
//! off the flight itself: a least-squares fit, over the loaded samples so far, of
//!
//! ```text
//! OCV − V = k_w·(R0·I + R1·x_w) + k_c·(R0·c·I + R1·x_c) + b,   c = warm_a·exp(−H/heat_scale)
//! ```
//!
//! (x_w, x_c: the RC state driven by I and by c·I), shrunk toward the nominal circuit
//! (k_w = k_c = 1, b = `bias_v`) with the weight of [`PRIOR_S`] seconds of this flight's own
//! data (a g-prior: unit-free, the same on a 3S and a 6S pack), forgetting with a memory of
//! [`MEMORY_S`] seconds of loaded flight. The forecast then fades k_c's part with the heat
//! it forecasts. With no loaded sample yet (before take-off) the fit is the nominal circuit,
//! and the forecast is exactly the circuit's.
//!
//! Chosen by 5-fold by-flight CV on the M100 training flights (`lab/scripts/battery/lab_split.py`,
//! `lab/scripts/battery/NOTES-min-voltage.md` round 4): the lowest loaded voltage from half time
//! with the measured power, median |error| 0.111 → 0.087 V (first flight of a pack 0.199 →
//! 0.109 V; nested, [`PRIOR_S`] picked on the other folds: 0.087 V, 40 s in 3 of 5 folds, 20
//! and 80 s in the others).

/// The nominal circuit's weight in the fit, in seconds of the flight's own loaded data.
pub const PRIOR_S: f64 = 40.0;
/// Memory of the fit, in seconds of loaded flight (the M100's flights, 2–7 min, could not
/// tell 150 s from no forgetting; a finite memory keeps a long flight's fit recent).
pub const MEMORY_S: f64 = 600.0;

/// Bounds on the fit: [k_w, k_c, b (V)] (the M100 training flights' fits at half time lie in
/// [0.81, 1.42], [0.76, 1.56], [−0.27, 0.54] V).
const LO: [f64; 3] = [0.0, 0.0, -1.0];
const HI: [f64; 3] = [5.0, 5.0, 1.0];

/// Running sums of the fit and the two RC states.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct Split {
    /// RC state driven by I (V/Ω, as the circuit's x1).
    pub(crate) xw: f64,
    /// RC state driven by c·I.
    pub(crate) xc: f64,
    /// Σ z·zᵀ·dt and Σ z·y·dt over loaded samples, z = [g_w, g_c, 1], y = OCV − V.
    zz: [[f64; 3]; 3],
    zy: [f64; 3],
    /// Σ dt (s), forgotten alike.
    t: f64,
}

impl Split {
    /// Advances the two RC states over a step with current `i` and cold share `c`
    /// (`e1` = exp(−dt/τ1)).
    pub(crate) fn propagate(&mut self, e1: f64, i: f64, c: f64) {
        self.xw = self.xw * e1 + i * (1.0 - e1);
        self.xc = self.xc * e1 + c * i * (1.0 - e1);
    }

    /// Adds a loaded sample: `g` = [R0·I + R1·x_w, R0·c·I + R1·x_c], `y` = OCV − V.
    pub(crate) fn add(&mut self, dt: f64, g: [f64; 2], y: f64) {
        let z = [g[0], g[1], 1.0];
        if !(dt.is_finite() && y.is_finite() && z.iter().all(|v| v.is_finite())) {
            return;
        }
        let keep = (-dt / MEMORY_S).exp();
        for r in 0..3 {
            for c in 0..3 {
                self.zz[r][c] = self.zz[r][c] * keep + z[r] * z[c] * dt;
            }
            self.zy[r] = self.zy[r] * keep + z[r] * y * dt;
        }
        self.t = self.t * keep + dt;
    }

    /// [k_w, k_c, b]: the fit shrunk toward [1, 1, `bias_v`]; the prior alone before any
    /// loaded sample or when the system is singular.
    pub(crate) fn fit(&self, bias_v: f64) -> [f64; 3] {
        let prior = [1.0, 1.0, bias_v];
        if self.t <= 0.0 {
            return prior;
        }
        let w = PRIOR_S / self.t;
        let mut a = self.zz;
        let mut rhs = self.zy;
        for r in 0..3 {
            a[r][r] += w * self.zz[r][r];
            rhs[r] += w * self.zz[r][r] * prior[r];
        }
        match solve3(a, rhs) {
            Some(k) => std::array::from_fn(|r| k[r].clamp(LO[r], HI[r])),
            None => prior,
        }
    }
}

/// Solves a 3×3 system by Cramer's rule; `None` when (near) singular or not finite.
fn solve3(a: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let det = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(&a);
    let scale = a.iter().flatten().fold(0.0_f64, |s, v| s.max(v.abs()));
    if !(d.is_finite() && scale > 0.0 && d.abs() > 1e-12 * scale.powi(3)) {
        return None;
    }
    let x: [f64; 3] = std::array::from_fn(|c| {
        let mut m = a;
        for r in 0..3 {
            m[r][c] = b[r];
        }
        det(&m) / d
    });
    x.iter().all(|v| v.is_finite()).then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_data_is_the_prior() {
        assert_eq!(Split::default().fit(-0.02), [1.0, 1.0, -0.02]);
    }

    #[test]
    fn recovers_a_split_from_clean_data() {
        // a pack whose cold part is twice the nominal and whose warm part is 0.8 of it
        let mut s = Split::default();
        for k in 0..6000 {
            let c = 1.2 * (-(k as f64) / 2000.0).exp();
            let i = 20.0 + 10.0 * ((k as f64) * 0.05).sin();
            s.propagate((-0.1_f64 / 28.0).exp(), i, c);
            let g = [0.04 * i + 0.02 * s.xw, 0.04 * c * i + 0.02 * s.xc];
            s.add(0.1, g, 0.8 * g[0] + 2.0 * g[1] + 0.05);
        }
        let k = s.fit(0.0);
        // from the prior most of the way to the truth: the cold part well over 1, the warm
        // part under it (the two regressors are alike but for c's fading, so the prior of
        // 40 s holds back some along that direction)
        assert!(k[0] < 0.95 && k[1] > 1.7, "{k:?}");
    }

    #[test]
    fn garbage_is_skipped_and_bounds_hold() {
        let mut s = Split::default();
        s.add(f64::NAN, [1.0, 1.0], 1.0);
        s.add(0.1, [f64::INFINITY, 1.0], 1.0);
        assert_eq!(s, Split::default());
        for _ in 0..100 {
            s.add(0.1, [1.0, 1.0], 1e6);
        }
        let k = s.fit(0.0);
        assert!(k
            .iter()
            .zip(LO.iter().zip(HI))
            .all(|(x, (l, h))| *x >= *l && *x <= h));
        assert_eq!(solve3([[0.0; 3]; 3], [1.0; 3]), None);
    }
}
