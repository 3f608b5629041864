//! The pack's capacity and resistance over flights, each with its uncertainty.
//!
//! Why: a flight moves what is learned only by what it can show. A flight that used a quarter
//! of the pack measures its capacity through a 25-point fall of the autopilot's gauge, and a
//! few points of error in that gauge are a fifth of the answer; taken as it came (the median of
//! the last flights, as before) one part-used flight moved the demo's 130 Wh pack to 102 Wh.
//!
//! **Capacity** (Wh): a normal posterior by inverse-variance weighting. The prior is the rated
//! capacity the flights assumed (the config, `BATT_CAPACITY`, BATTERY_INFO), with a standard
//! deviation of [`PRIOR_REL_SD`] of it (a pack against its label, aged or not); each flight's
//! effective capacity (energy used ÷ the gauge's fall) carries a standard deviation of
//! `capacity × GAUGE_SD_PTS / fall`: [`GAUGE_SD_PTS`] points of the gauge over the points it
//! fell. A flight that used 80 % of the pack weighs (80/25)² ≈ 10× one that used 25 %.
//!
//! **Resistance** (Ω): flights that measured one (a flight that shows none, R = 0, shows
//! nothing and is left out) are averaged in logarithms; each carries [`R_LOG_SD`] or, when the
//! flights disagree more, their own spread, so the interval widens when they do.
//!
//! Both constants are judgements, not fits (no data set here holds a pack flown many times
//! with its true capacity): the book's pack page says so.

/// A quantity with its uncertainty: the posterior mean and standard deviation, and how many
/// flights it rests on.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Interval {
    pub mean: f64,
    pub sd: f64,
    pub flights: usize,
}

impl Interval {
    /// The ~95 % interval, mean ± 2 sd (never below 0).
    pub fn bounds(&self) -> (f64, f64) {
        (
            (self.mean - 2.0 * self.sd).max(0.0),
            self.mean + 2.0 * self.sd,
        )
    }
}

/// The prior's standard deviation, a fraction of the rated capacity.
pub const PRIOR_REL_SD: f64 = 0.2;
/// The autopilot's gauge's error, percentage points (a voltage-based % under load, rounded).
pub const GAUGE_SD_PTS: f64 = 8.0;
/// One flight's resistance's error, in its logarithm (≈ ±30 %).
pub const R_LOG_SD: f64 = 0.3;

/// The capacity's posterior from the rated capacity (`rated`, Wh; none, 0 or not finite: no
/// prior) and the flights' (effective capacity Wh, gauge fall points). Flights with a value
/// that is not finite or not positive are left out. None with no prior and no flight.
pub fn capacity(rated: Option<f64>, flights: &[(f64, f64)]) -> Option<Interval> {
    let mut w_sum = 0.0;
    let mut wx = 0.0;
    if let Some(r) = rated.filter(|r| r.is_finite() && *r > 0.0) {
        let w = 1.0 / (PRIOR_REL_SD * r).powi(2);
        w_sum += w;
        wx += w * r;
    }
    let mut n = 0;
    for &(c, fall) in flights {
        if !(c.is_finite() && c > 0.0 && fall.is_finite() && fall > 0.0) {
            continue;
        }
        let sd = c * GAUGE_SD_PTS / fall.min(100.0);
        let w = 1.0 / (sd * sd);
        w_sum += w;
        wx += w * c;
        n += 1;
    }
    (w_sum > 0.0 && w_sum.is_finite()).then(|| Interval {
        mean: wx / w_sum,
        sd: w_sum.sqrt().recip(),
        flights: n,
    })
}

/// The capacity learned from the store's rows, newest first: (effective capacity Wh, the
/// gauge's fall points, the rated capacity Wh); the newest row's rated capacity is the prior.
/// The posterior mean and how many flights it rests on; None when no flight showed one.
pub fn learned(rows: &[(f64, Option<f64>, f64)]) -> Option<(f64, usize)> {
    let flights: Vec<(f64, f64)> = rows
        .iter()
        .filter_map(|(c, fall, _)| Some((*c, (*fall)?)))
        .collect();
    let rated = rows.first().map(|r| r.2);
    capacity(rated, &flights)
        .filter(|i| i.flights > 0 && i.mean.is_finite())
        .map(|i| (i.mean, i.flights))
}

/// The resistance's posterior from the flights' measured resistances (Ω): None when no flight
/// measured one (> 0).
pub fn resistance(flights: &[f64]) -> Option<Interval> {
    let logs: Vec<f64> = flights
        .iter()
        .filter(|r| r.is_finite() && **r > 0.0)
        .map(|r| r.ln())
        .collect();
    let n = logs.len();
    if n == 0 {
        return None;
    }
    let m = logs.iter().sum::<f64>() / n as f64;
    let spread = if n > 1 {
        (logs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
    } else {
        0.0
    };
    let sd_log = R_LOG_SD.max(spread) / (n as f64).sqrt();
    // the log-normal's mean and standard deviation
    let mean = (m + sd_log * sd_log / 2.0).exp();
    let sd = mean * (sd_log * sd_log).exp_m1().sqrt();
    (mean.is_finite() && sd.is_finite()).then_some(Interval {
        mean,
        sd,
        flights: n,
    })
}

/// "122 Wh (±2 sd 104–140, 3 flights)"-style text: `unit` after the mean and the bounds,
/// `scale` applied to both (1000 for mΩ).
pub fn text(i: &Interval, scale: f64, unit: &str) -> String {
    let (lo, hi) = i.bounds();
    format!(
        "{:.0} {unit} ({:.0}–{:.0}, {} flight(s))",
        i.mean * scale,
        lo * scale,
        hi * scale,
        i.flights
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quarter_used_flight_moves_the_capacity_little_full_ones_shrink_it() {
        // the case: rated 130 Wh, one flight used a quarter and its gauge says 102 Wh
        let prior = capacity(Some(130.0), &[]).expect("a prior");
        let one = capacity(Some(130.0), &[(102.0, 25.0)]).expect("a posterior");
        assert!(one.mean > 118.0 && one.mean < 130.0, "{one:?}");
        assert!(one.sd < prior.sd);
        // three flights that used 80 % each and say 110 Wh: most of the way there, narrow
        let mut fl = vec![(110.0, 80.0)];
        let mut last = capacity(Some(130.0), &fl).expect("a posterior");
        for _ in 0..2 {
            fl.push((110.0, 80.0));
            let next = capacity(Some(130.0), &fl).expect("a posterior");
            assert!(next.sd < last.sd && (next.mean - 110.0).abs() < (last.mean - 110.0).abs());
            last = next;
        }
        assert!((last.mean - 110.0).abs() < 4.0, "{last:?}");
        assert!(last.sd < 0.06 * 110.0, "{last:?}");
        assert_eq!(last.flights, 3);
        // no prior, no flight: nothing; junk left out
        assert_eq!(capacity(None, &[]), None);
        assert_eq!(
            capacity(Some(0.0), &[(f64::NAN, 50.0), (-3.0, 50.0), (90.0, 0.0)]),
            None
        );
        let only = capacity(None, &[(90.0, 50.0)]).expect("one flight");
        assert!((only.mean - 90.0).abs() < 1e-9 && (only.sd - 90.0 * 8.0 / 50.0).abs() < 1e-9);
    }

    #[test]
    fn resistance_leaves_out_flights_that_measured_none_and_widens_when_flights_disagree() {
        assert_eq!(resistance(&[0.0, f64::NAN, -1.0]), None);
        let agree = resistance(&[0.045, 0.047, 0.046]).expect("three");
        assert_eq!(agree.flights, 3);
        assert!((agree.mean - 0.046).abs() < 0.003, "{agree:?}");
        let (lo, hi) = agree.bounds();
        assert!(lo < 0.046 && hi > 0.046);
        // the 0 → 269 → 0 mΩ: the zeros show nothing
        let one = resistance(&[0.0, 0.269, 0.0]).expect("one");
        assert_eq!(one.flights, 1);
        let disagree = resistance(&[0.03, 0.12, 0.05]).expect("three");
        assert!(disagree.sd / disagree.mean > agree.sd / agree.mean);
        assert!(text(&agree, 1000.0, "mΩ").contains("3 flight(s)"));
    }
}
