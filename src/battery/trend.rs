//! The time to a low-voltage threshold from the measured voltage's own trend in flight.
//!
//! Why: the circuit's forecast ([`mod@super::forecast`]) flies the pack's model down to the
//! threshold, and on packs nobody tuned it for (NASA ProgPy's 18650 packs, issue 44) its time
//! to `BATT_LOW_VOLT` was off by −95 % to +1000 %: the threshold is approached slowly (an 18650
//! at 1–2C loses 0.1 V a cell over minutes near 3.5 V), so a 0.05 V error in the modelled path
//! is minutes, whichever way it falls. The measured voltage itself shows how fast the loaded
//! voltage is falling at this power, on this pack, now. This module fits it:
//!
//! ```text
//! V = a + b·t + c·I        exponentially weighted least squares (memory TAU_S),
//!                          from SKIP_S after take-off, c ≤ 0 (the load's sag, ridge-kept)
//! dip = the deepest one-step-ahead residual under the fit, fading with TAU_S
//! time to low = (a + b·now + c·P/V_low − dip − V_low) / (−b·P/P_recent)
//! ```
//!
//! the line at the forecast's power P (the current P/V_low at the threshold, the slope scaled
//! by P over the recent power P_recent; P no less than P_recent: a forecast model that says
//! less must not stretch what the pack has shown), deepened by the deepest dip the flight has shown under
//! its own trend (a climb or a gust crosses the threshold before the mean does: the
//! autopilot's failsafe sees the dip). A pack whose loaded voltage is not falling (b ≥ 0)
//! gives no time. The monitor says the sooner of this and the circuit's crossing
//! ([`crate::energy`]'s pack stage); with no capacity (no circuit), this alone.
//!
//! Chosen on the fit packs only (`tests/peers/progpy_flights.py --set fit`, 18 flights, 54
//! forecasts; the book's pack page has the table): memory 60/120/240 s, skip 10/30 s, with and
//! without the dip, the trend alone or with the circuit's crossing (the sooner, the trend
//! capped at 2× or 3× the circuit's, their geometric mean), by the fewest forecasts more than
//! 25 % late, then the median error. Model code: no I/O, never panics, allocation-free (O(1) a
//! sample).

/// The fit's memory, s.
pub const TAU_S: f64 = 240.0;
/// Samples this long after take-off are left out (the polarisation building up after the
/// load steps on is not the trend).
pub const SKIP_S: f64 = 10.0;
/// Loaded samples the fit needs before it gives a time.
pub const MIN_SAMPLES: u32 = 10;
/// The memory of the recent power the slope is scaled by, s.
pub const POWER_TAU_S: f64 = 30.0;
/// The TB48D's loaded current (A) and its charge (Ah): the scale of [`loaded_a`].
const LOADED_A: f64 = 3.0;
const TB48D_AH: f64 = 103.37364527025169 / 22.8;

/// The current over which a sample is in flight for the trend: 3 A on the M100's 4.5 Ah pack,
/// less on a smaller pack in proportion to its charge (`ah`; 3 A when it is not known), as the
/// circuit's resistance fit counts loaded samples.
pub fn loaded_a(ah: Option<f64>) -> f64 {
    let k = ah
        .filter(|a| a.is_finite() && *a > 0.0)
        .map_or(1.0, |a| (a / TB48D_AH).clamp(0.05, 1.0));
    LOADED_A * k
}

/// The ridge on the current's coefficient, as a fraction of the fit's weight (hover holds the
/// current almost still: the sag per ampere is then barely shown, and must not swing the line).
const RIDGE: f64 = 1e-3;

/// The running fit of a flight's loaded voltage: sums of the weighted normal equations.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VoltageTrend {
    /// Take-off (the first loaded sample), s.
    t_takeoff: Option<f64>,
    /// The first sample in the fit (its time origin), s.
    t0: Option<f64>,
    t_last: Option<f64>,
    s: [[f64; 3]; 3],
    r: [f64; 3],
    n: u32,
    coef: Option<[f64; 3]>,
    dip: f64,
    p_recent: f64,
}

impl VoltageTrend {
    /// Take one sample in flight: time (s), pack voltage (V), current (A). Samples that are
    /// not finite, a voltage ≤ 0, a negative current or time going back are skipped.
    pub fn add(&mut self, t: f64, v: f64, i: f64) {
        if !(t.is_finite() && v.is_finite() && i.is_finite() && v > 0.0 && i >= 0.0) {
            return;
        }
        let t_off = *self.t_takeoff.get_or_insert(t);
        if t - t_off < SKIP_S {
            return;
        }
        if self.t_last.is_some_and(|tl| t < tl) {
            return;
        }
        let t0 = *self.t0.get_or_insert(t);
        let x = [1.0, t - t0, i];
        if let Some(tl) = self.t_last {
            let dt = t - tl;
            let k = (-dt / TAU_S).exp();
            for row in self.s.iter_mut() {
                for e in row.iter_mut() {
                    *e *= k;
                }
            }
            for e in self.r.iter_mut() {
                *e *= k;
            }
            self.dip *= k;
            let kp = (-dt / POWER_TAU_S).exp();
            self.p_recent = kp * self.p_recent + (1.0 - kp) * v * i;
        } else {
            self.p_recent = v * i;
        }
        self.t_last = Some(t);
        if let (Some(c), true) = (self.coef, self.n >= MIN_SAMPLES) {
            let res = v - (c[0] * x[0] + c[1] * x[1] + c[2] * x[2]);
            if res.is_finite() {
                self.dip = self.dip.max(-res);
            }
        }
        for a in 0..3 {
            for b in 0..3 {
                self.s[a][b] += x[a] * x[b];
            }
            self.r[a] += x[a] * v;
        }
        self.n = self.n.saturating_add(1);
        self.coef = self.solve();
    }

    /// [a, b, c] of V = a + b·(t − t0) + c·I, or None when the equations are singular.
    fn solve(&self) -> Option<[f64; 3]> {
        let mut m = self.s;
        m[2][2] += RIDGE * m[0][0];
        let det = det3(&m);
        if !(det.is_finite() && det.abs() > 1e-12 * m[0][0].powi(3).max(1e-300)) {
            return None;
        }
        let mut out = [0.0; 3];
        for (k, o) in out.iter_mut().enumerate() {
            let mut mk = m;
            for (row, r) in mk.iter_mut().zip(self.r) {
                row[k] = r;
            }
            *o = det3(&mk) / det;
        }
        out.iter().all(|x| x.is_finite()).then_some(out)
    }

    /// Seconds from the last sample until the loaded voltage falls under `low_v` flying on at
    /// `power_w` (or the recent measured power, if more): 0 when it is under already; None before [`MIN_SAMPLES`] samples in the fit,
    /// for a voltage that is not falling, or for bad arguments.
    pub fn time_to(&self, low_v: f64, power_w: f64) -> Option<f64> {
        if self.n < MIN_SAMPLES || !(low_v.is_finite() && low_v > 0.0) {
            return None;
        }
        if !(power_w.is_finite() && power_w > 0.0 && self.p_recent > 0.0) {
            return None;
        }
        let [a, b, c] = self.coef?;
        let now = self.t_last? - self.t0?;
        // never slower than at the power measured now: a forecast model that says less
        // must not stretch what the pack has shown (late is the dangerous side)
        let power_w = power_w.max(self.p_recent);
        let c = c.min(0.0);
        let slope = b * power_w / self.p_recent;
        let above = a + b * now + c * power_w / low_v - self.dip - low_v;
        if !(slope.is_finite() && above.is_finite()) || slope >= -1e-9 {
            return None;
        }
        Some((above / -slope).max(0.0))
    }

    /// The fitted slope of the loaded voltage, V/s (None before the fit).
    pub fn slope_v_s(&self) -> Option<f64> {
        self.coef.filter(|_| self.n >= MIN_SAMPLES).map(|c| c[1])
    }
}

fn det3(m: &[[f64; 3]; 3]) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pack falling 1 mV/s at a steady 10 A, with 0.05 Ω of sag and a current that wanders.
    fn flight(secs: u32) -> VoltageTrend {
        let mut tr = VoltageTrend::default();
        for k in 0..secs {
            let t = f64::from(k);
            let i = 10.0 + (t * 0.3).sin();
            tr.add(t, 16.0 - 0.001 * t - 0.05 * i, i);
        }
        tr
    }

    #[test]
    fn a_steady_fall_crosses_where_the_line_does() {
        let tr = flight(200);
        assert!((tr.slope_v_s().unwrap_or(0.0) + 0.001).abs() < 1e-6);
        // at t = 199 and ~10 A (power ≈ 10 × 15.3): V ≈ 15.30; to 15.0 V at the same power
        let p = 10.0 * (16.0 - 0.199 - 0.5);
        let t = tr.time_to(15.0, p).expect("a time");
        // the current at the threshold is p/15 ≈ 10.2 A: 0.01 V more sag, 10 s sooner
        assert!((t - 290.0).abs() < 15.0, "{t}");
        // twice the power, twice the slope and more sag: much sooner
        let t2 = tr.time_to(15.0, 2.0 * p).expect("a time");
        assert!(t2 < 0.5 * t, "{t2} vs {t}");
        // under the threshold already: 0
        assert_eq!(tr.time_to(15.5, p), Some(0.0));
    }

    #[test]
    fn a_dip_under_the_trend_brings_the_crossing_forward() {
        let mut tr = flight(200);
        let before = tr.time_to(15.0, 153.0).expect("a time");
        // a climb: 0.1 V under the line for a moment
        tr.add(200.0, 16.0 - 0.2 - 0.5 - 0.1, 10.0);
        let after = tr.time_to(15.0, 153.0).expect("a time");
        assert!(after < before - 50.0, "{after} vs {before}");
    }

    #[test]
    fn no_time_from_a_flat_pack_too_few_samples_or_junk() {
        let mut flat = VoltageTrend::default();
        for k in 0..100 {
            flat.add(f64::from(k), 12.6, 20.0 + f64::from(k % 7));
        }
        assert_eq!(flat.time_to(10.5, 250.0), None);
        assert_eq!(flight(15).time_to(15.0, 150.0), None);
        let tr = flight(100);
        assert_eq!(tr.time_to(f64::NAN, 150.0), None);
        assert_eq!(tr.time_to(15.0, -1.0), None);
        assert_eq!(tr.time_to(15.0, f64::INFINITY), None);
        let mut junk = VoltageTrend::default();
        for k in 0..100 {
            let t = f64::from(k);
            junk.add(t, f64::NAN, 1.0);
            junk.add(t, 12.0, -5.0);
            junk.add(f64::INFINITY, 12.0, 5.0);
        }
        assert_eq!(junk.time_to(10.0, 100.0), None);
        // a still current (hover): the ridge keeps the fit
        let mut still = VoltageTrend::default();
        for k in 0..300 {
            let t = f64::from(k);
            still.add(t, 16.0 - 0.001 * t, 10.0);
        }
        let t = still.time_to(15.0, 157.0).expect("a time");
        assert!(t.is_finite() && t > 0.0, "{t}");
    }
}
