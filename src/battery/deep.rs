//! The deeper sag of an emptying pack: resistance and polarisation as functions of the state
//! of charge.
//!
//! Why: a lithium cell sags more as it empties (its electrode surfaces run out of lithium
//! first, so the polarisation grows). One fixed resistance learned at 80 % carries a forecast
//! down to the low-voltage threshold with the sag of a full pack, and on NASA ProgPy's 18650
//! packs the time to `BATT_LOW_VOLT` came out 2–12× too long (issue 44). Both resistances are
//! therefore scaled by
//!
//! ```text
//! g(soc) = (1 + β·(1 − soc)) · (1 + a·exp(−soc/s0))     (soc: the OCV curve's energy fraction)
//! ```
//!
//! a slope β (the sag grows with the charge used) and a knee a (it grows faster near empty),
//! with a prior for a chemistry's default curve ([`PRIOR_SLOPE`], [`PRIOR_A`]: chosen on the
//! fit set of ProgPy packs, `tests/peers/progpy_flights.py`; the book's pack page says
//! against which alternatives), and none (exactly g = 1) for the M100's TB48D fit: its flights
//! never went below 3.7 V a cell, its warm/cold split already carries how its resistance
//! moves in flight, and its figures stay as they were.
//!
//! **Learned online, remembered per pack.** [`DeepFit`] keeps, in [`BINS`] bands of state of
//! charge, the least-squares scale of the measured sag against the nominal one; from the bands
//! a flight has reached it fits β = k_β/k (scale_b = k + k_β·(1 − soc_b)), shrunk toward the
//! prior with [`PRIOR_BINS`] bands' weight. The forecast flies on along that slope from the
//! sag it has now ([`mod@super::forecast`]), and [`DeepFit::learned`] is what the next flight on
//! this pack starts from ([`super::CircuitParams::with_deep`]).

/// The prior's s0: the state of charge over which the knee's growth fades.
pub const S0: f64 = 0.12;
/// The prior slope β for the Li-ion default curve (chosen on the fit packs, ProgPy's 18650s:
/// the fewest forecasts more than 25 % late, then the median error; see the module docs). Not
/// applied to LiPo or LiHV: nothing here was fitted on them, and β = 8 on the simulator's LiPo
/// pack, whose sag does not grow, would forecast a low-voltage crossing far too soon.
pub const PRIOR_SLOPE: f64 = 8.0;
/// The prior knee a for a chemistry's default curve: none (a = 2 with s0 = 0.12 was tried on
/// the fit packs and changed little beside the slope).
pub const PRIOR_A: f64 = 0.0;
/// Bands of state of charge the sag scale is kept in.
pub const BINS: usize = 50;
/// The prior's weight in the fit of β, in bands of evidence spread over the whole range of
/// state of charge (a flight that used a tenth of the pack shows the slope with about a
/// hundredth of that spread's weight per band).
pub const PRIOR_BINS: f64 = 4.0;
/// The largest growth of the resistance at empty the fit may reach (g(0) ≤ 1 + this).
pub const A_MAX: f64 = 20.0;

/// g(soc) = (1 + β·(1 − soc))·(1 + a·exp(−soc/s0)); exactly 1 for a = β = 0 (the TB48D's
/// circuit is unchanged).
pub fn growth(a: f64, s0: f64, beta: f64, soc: f64) -> f64 {
    if (a == 0.0 && beta == 0.0) || s0.is_nan() || s0 <= 0.0 || !soc.is_finite() {
        return 1.0;
    }
    let soc = soc.clamp(0.0, 1.0);
    // no exp() for the knee when there is none (the shipped prior): a forecast step's cost
    let knee = if a == 0.0 {
        1.0
    } else {
        1.0 + a * (-soc / s0).exp()
    };
    (1.0 + beta * (1.0 - soc)) * knee
}

/// Per-band sums of the measured sag against the nominal one (Σ d·y, Σ d², d the nominal drop
/// at g = 1, y the measured drop less the bias), over a flight's loaded samples.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DeepFit {
    #[serde(with = "bins")]
    dy: [f64; BINS],
    #[serde(with = "bins")]
    dd: [f64; BINS],
}

/// The per-band sums as a sequence (serde has no arrays this long); one of another length
/// is an error.
mod bins {
    use super::BINS;
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(a: &[f64; BINS], s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(a.iter())
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; BINS], D::Error> {
        let v = Vec::<f64>::deserialize(d)?;
        <[f64; BINS]>::try_from(v.as_slice())
            .map_err(|_| serde::de::Error::invalid_length(v.len(), &"one sum per band"))
    }
}

impl Default for DeepFit {
    fn default() -> Self {
        Self {
            dy: [0.0; BINS],
            dd: [0.0; BINS],
        }
    }
}

impl DeepFit {
    /// Adds a loaded sample at `soc` with nominal drop `d` and measured drop `y` (V).
    pub fn add(&mut self, soc: f64, d: f64, y: f64, dt: f64) {
        if !(soc.is_finite() && d.is_finite() && y.is_finite() && dt.is_finite() && d > 0.0) {
            return;
        }
        let b = ((soc.clamp(0.0, 1.0) * BINS as f64) as usize).min(BINS - 1);
        self.dy[b] += d * y * dt;
        self.dd[b] += d * d * dt;
    }

    /// The slope β this flight's bands show (scale_b = k·(1 + β·(1 − soc_b))), shrunk toward
    /// `prior` with [`PRIOR_BINS`] bands' weight; `prior` itself when fewer than two bands hold
    /// evidence.
    pub fn learned(&self, prior: f64) -> f64 {
        // weighted least squares of scale_b = k + k·β·h_b, each band weighted alike once it
        // holds 10 V²·s of nominal drop (a few seconds of flight): a band is one observation
        let mut s = [[0.0; 2]; 2];
        let mut r = [0.0; 2];
        let mut bands = 0.0;
        for b in 0..BINS {
            if self.dd[b] <= 1e-9 {
                continue;
            }
            let w = (self.dd[b] / 10.0).min(1.0);
            let scale = self.dy[b] / self.dd[b];
            let h = 1.0 - (b as f64 + 0.5) / BINS as f64;
            let z = [1.0, h];
            for i in 0..2 {
                for j in 0..2 {
                    s[i][j] += w * z[i] * z[j];
                }
                r[i] += w * z[i] * scale;
            }
            bands += w;
        }
        let det = s[0][0] * s[1][1] - s[0][1] * s[1][0];
        if bands < 2.0 || !(det.is_finite() && det > 1e-12) {
            return prior;
        }
        let k = (r[0] * s[1][1] - s[0][1] * r[1]) / det;
        let ka = (s[0][0] * r[1] - s[1][0] * r[0]) / det;
        if !(k.is_finite() && ka.is_finite() && k > 1e-3) {
            return prior;
        }
        // what the bands say about the slope, in flights that spanned the whole range (the
        // weighted spread of h over that of 0..1, 1/12), against the prior's PRIOR_BINS
        let info = det / s[0][0] * 12.0;
        let beta = (ka / k).clamp(0.0, A_MAX);
        ((info * beta + PRIOR_BINS * prior) / (info + PRIOR_BINS)).clamp(0.0, A_MAX)
    }

    /// How many bands hold evidence (for the record: a flight that stayed high learns nothing).
    pub fn bands(&self) -> usize {
        self.dd.iter().filter(|d| **d > 1e-9).count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_growth_is_exactly_one() {
        assert_eq!(growth(0.0, 0.1, 0.0, 0.05), 1.0);
        assert_eq!(growth(2.0, 0.0, 1.0, 0.05), 1.0);
        assert_eq!(growth(2.0, 0.1, 1.0, f64::NAN), 1.0);
        assert!((growth(2.0, 0.1, 0.0, 0.0) - 3.0).abs() < 1e-12);
        assert!((growth(0.0, 0.1, 4.0, 0.5) - 3.0).abs() < 1e-12);
        // monotone: emptier sags more
        let mut last = f64::INFINITY;
        for k in 0..=100 {
            let g = growth(1.5, 0.12, 3.0, f64::from(k) / 100.0);
            assert!(g <= last && g >= 1.0);
            last = g;
        }
    }

    #[test]
    fn learns_the_slope_of_a_pack_flown_low_and_keeps_the_prior_otherwise() {
        let beta_true = 3.0;
        let mut low = DeepFit::default();
        let mut flat = DeepFit::default();
        for k in 0..2000 {
            let soc = 0.9 - 0.7 * f64::from(k) / 2000.0;
            let d = 0.5 + 0.1 * (f64::from(k) * 0.1).sin();
            low.add(soc, d, 1.3 * growth(0.0, S0, beta_true, soc) * d, 0.5);
            flat.add(soc, d, 1.3 * d, 0.5);
        }
        // 70 % of the pack flown: most of the way from the prior (8) to the truth (3)
        let b = low.learned(8.0);
        assert!(b > beta_true && b < 5.0, "{b}");
        // a pack whose sag does not grow: most of the way to 0
        let b = flat.learned(8.0);
        assert!((0.0..3.0).contains(&b), "{b}");
        assert_eq!(DeepFit::default().learned(0.7), 0.7);
        assert!(low.bands() > 30);
        let mut junk = DeepFit::default();
        junk.add(f64::NAN, 1.0, 1.0, 1.0);
        junk.add(0.5, -1.0, 1.0, 1.0);
        assert_eq!(junk, DeepFit::default());
    }
}
