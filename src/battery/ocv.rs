//! Monotone OCV table: resting voltage per cell ↔ energy above the floor.
//!
//! Why a table and not a polynomial: a piecewise-linear table is monotone by
//! construction (so `soc` and `v_cell` are exact inverses), cheap, and easy to replace per
//! pack. Energy (Wh) rather than charge is the state because the caller asks "how many Wh
//! are left", and the fit target was E(v_start) − E(v_end) = ∫V·I dt.

/// TB48D (6S LiHV, 5700 mAh, 129.96 Wh rated) knots, V per cell.
pub const TB48D_V: [f64; 18] = [
    3.30, 3.50, 3.60, 3.65, 3.70, 3.75, 3.80, 3.85, 3.90, 3.95, 4.00, 4.05, 4.10, 4.15, 4.20, 4.25,
    4.30, 4.35,
];
/// Pack energy above the 3.30 V/cell floor at each knot (Wh), fitted by monotone NNLS with
/// a Huber loss on 162 training flights (fit.py). Above 3.70 V it is data; below 3.70 V
/// it is NOT identified (no flight went lower): 12 % of the total follows a LiPo knee shape.
pub const TB48D_E_WH: [f64; 18] = [
    0.0,
    2.696703789658739,
    5.932748337249226,
    8.629452126907953,
    12.404837432430204,
    23.237306931754283,
    33.42752391873442,
    42.531324616164106,
    50.259686389394275,
    56.894060380568845,
    62.92161740962222,
    68.80634002557551,
    74.58590907661036,
    80.24702096362753,
    85.9296353500569,
    91.78831924935713,
    97.58073927314484,
    103.37364527025169,
];

/// Strictly increasing table of (V/cell, energy above floor).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct OcvCurve {
    v: Vec<f64>,
    e: Vec<f64>,
}

fn interp(x: f64, xs: &[f64], ys: &[f64]) -> f64 {
    // callers guarantee len >= 2 and strictly increasing xs; clamp outside
    let n = xs.len();
    if x.is_nan() {
        return f64::NAN;
    }
    if x <= xs[0] {
        return ys[0];
    }
    if x >= xs[n - 1] {
        return ys[n - 1];
    }
    let i = xs.partition_point(|&k| k <= x).clamp(1, n - 1);
    let t = (x - xs[i - 1]) / (xs[i] - xs[i - 1]);
    ys[i - 1] + t * (ys[i] - ys[i - 1])
}

impl OcvCurve {
    /// Builds a curve from (V/cell, value) pairs. Returns `None` unless there are ≥ 2 finite
    /// pairs, voltages strictly increase and values strictly increase (monotone ⇒ invertible).
    pub fn new(v: Vec<f64>, e: Vec<f64>) -> Option<Self> {
        let ok = v.len() == e.len()
            && v.len() >= 2
            && v.iter().chain(e.iter()).all(|x| x.is_finite())
            && v.windows(2).all(|w| w[1] > w[0])
            && e.windows(2).all(|w| w[1] > w[0]);
        ok.then_some(Self { v, e })
    }

    pub(crate) fn from_soc_pairs(p: &[(f64, f64)]) -> Self {
        Self {
            v: p.iter().map(|x| x.0).collect(),
            e: p.iter().map(|x| x.1).collect(),
        }
    }

    /// The fitted DJI TB48D curve (values in pack Wh).
    pub fn tb48d() -> Self {
        Self {
            v: TB48D_V.to_vec(),
            e: TB48D_E_WH.to_vec(),
        }
    }

    /// Same shape scaled to 0..1 (SoC as energy fraction).
    pub fn normalized(&self) -> Self {
        let (lo, hi) = (self.e[0], self.e[self.e.len() - 1]);
        Self {
            v: self.v.clone(),
            e: self.e.iter().map(|x| (x - lo) / (hi - lo)).collect(),
        }
    }

    /// The same shape holding `capacity_wh` between its floor (0 Wh) and full: a default
    /// chemistry curve made a pack's. `None` for a capacity that is not a positive number.
    pub fn scaled(&self, capacity_wh: f64) -> Option<Self> {
        let (lo, cap) = (self.e[0], self.capacity());
        (capacity_wh.is_finite() && capacity_wh > 0.0).then(|| Self {
            v: self.v.clone(),
            e: self
                .e
                .iter()
                .map(|x| (x - lo) / cap * capacity_wh)
                .collect(),
        })
    }

    /// Energy between floor and full of the table (Wh for a fitted pack, 1 if normalised).
    pub fn capacity(&self) -> f64 {
        self.e[self.e.len() - 1] - self.e[0]
    }

    /// State of charge (energy fraction 0..1) at a resting voltage per cell; clamped.
    pub fn soc(&self, v_cell: f64) -> f64 {
        (interp(v_cell, &self.v, &self.e) - self.e[0]) / self.capacity()
    }

    /// Resting voltage per cell at a state of charge (inverse of `soc`); clamped.
    pub fn v_cell(&self, soc: f64) -> f64 {
        interp(self.e[0] + soc * self.capacity(), &self.e, &self.v)
    }

    /// Energy above floor (table units: Wh for `tb48d`) at a resting voltage per cell.
    pub fn energy(&self, v_cell: f64) -> f64 {
        interp(v_cell, &self.v, &self.e)
    }

    /// Resting voltage per cell with `energy` (table units) left; clamped.
    pub fn v_cell_at_energy(&self, energy: f64) -> f64 {
        interp(energy, &self.e, &self.v)
    }

    /// Energy (Wh) left above floor for a pack of `capacity_wh` using this curve's shape.
    pub fn energy_wh(&self, v_cell: f64, capacity_wh: f64) -> f64 {
        self.soc(v_cell) * capacity_wh
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tb48d_matches_python_fit() {
        let c = OcvCurve::tb48d();
        assert!((c.energy(4.35) - 103.37364527025169).abs() < 1e-12);
        assert!((c.energy(4.025) - 0.5 * (62.92161740962222 + 68.80634002557551)).abs() < 1e-9);
        assert!((c.v_cell_at_energy(50.259686389394275) - 3.90).abs() < 1e-9);
        // one flight worth: 4.20 -> 4.00 V/cell is ~23 Wh
        assert!((c.energy(4.20) - c.energy(4.00) - 23.00801794043468).abs() < 1e-9);
    }

    #[test]
    fn monotone_and_round_trip() {
        let mut seed: u64 = 12345;
        for c in [OcvCurve::tb48d(), OcvCurve::tb48d().normalized()] {
            for _ in 0..2000 {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let u = (seed >> 11) as f64 / (1u64 << 53) as f64;
                let v = 3.30 + u * 1.05;
                let v2 = v + 0.001;
                assert!(c.soc(v2) > c.soc(v));
                let back = c.v_cell(c.soc(v));
                assert!((back - v).abs() < 1e-9, "{v} -> {back}");
            }
        }
        let c = OcvCurve::tb48d();
        assert_eq!(c.soc(5.0), 1.0);
        assert_eq!(c.soc(1.0), 0.0);
        assert!(c.soc(f64::NAN).is_nan());
        assert!(OcvCurve::new(vec![3.0, 3.0], vec![0.0, 1.0]).is_none());
        assert!(OcvCurve::new(vec![3.0, 4.0], vec![1.0, 0.0]).is_none());
        assert!(OcvCurve::new(vec![3.0, 4.0], vec![0.0, 1.0]).is_some());
    }
}
