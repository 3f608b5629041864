//! The resting voltage read through the ground idle (issue 44): a pack idling on the ground
//! still draws the flight controller's, receiver's and video transmitter's current (0.3 A on
//! ProgPy's packs), under the rest current, and its voltage sits that current times the
//! pack's resistance under its open-circuit voltage (35 mV a cell on a 1P 18650 pack of
//! 0.12 Ω, 3-5 points of charge). For a chemistry whose curve is a resting-voltage table
//! ([`ocv_table`]) the rest reading is `V + I·R` ([`rest_ocv`]) with the prior resistance,
//! and once the flight has shown the pack's own resistance (the median of `(OCV − V)/I` over
//! its loaded seconds [`LEARN_FROM_S`]..[`LEARN_TO_S`]) the start is restated by the idle
//! current times the difference, once, and said.

use super::*;

/// The loaded seconds over which the pack's own resistance is read for the idle's I·R.
pub const LEARN_FROM_S: f64 = 10.0;
pub const LEARN_TO_S: f64 = 30.0;

/// The rest stretch's currents, and the ground idle the start was read under.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct Idle {
    /// The currents (A) of [`Pack`]'s rest stretch, in step with its readings.
    cur: std::collections::VecDeque<f64>,
    /// (idle current A, resistance Ω it was corrected with, corrected resting voltage V) of
    /// the start, until the flight's own resistance restates it.
    start: Option<(f64, f64, f64)>,
    /// `(OCV − V)/I` of the loaded seconds so far (Ω).
    rs: Vec<f64>,
}

impl Pack {
    /// Take a reading under the rest current into the rest stretch, corrected by the idle's
    /// I·R with the prior resistance `r` for a resting-voltage table.
    pub(super) fn rest_sample(&mut self, t: f64, v: f64, i: f64, r: f64, chem: Chemistry) {
        let v = if ocv_table(chem) {
            rest_ocv(v, i, Some(r))
        } else {
            v
        };
        self.rest.push_back((t, v));
        self.idle.cur.push_back(i);
        while self
            .rest
            .front()
            .is_some_and(|(t0, _)| t - t0 > REST_SETTLE_S)
        {
            self.rest.pop_front();
            self.idle.cur.pop_front();
        }
    }

    /// The rest stretch ended (a current over the rest current).
    pub(super) fn rest_clear(&mut self) {
        self.rest.clear();
        self.idle.cur.clear();
    }

    /// The state starts from `v0` read `how`: remember the idle it was read under, when the
    /// flight may restate it.
    pub(super) fn idle_at_start(&mut self, v0: f64, how: &'static str, r: f64, chem: Chemistry) {
        self.idle.rs.clear();
        let i = median(self.idle.cur.iter().copied()).filter(|i| *i > 0.0);
        self.idle.start = i
            .filter(|_| how == FROM_REST && ocv_table(chem))
            .map(|i| (i, r, v0));
    }

    /// Under load in the first flight after a rest start: read the pack's own resistance and,
    /// at [`LEARN_TO_S`] loaded seconds, restate the start by the idle current times its
    /// difference from the one the reading used.
    pub(super) fn learn_idle_r(&mut self, v: f64, i: f64, load_a: f64, cells: u32) {
        let (Some((idle_a, r_used, v0)), Some(est)) = (self.idle.start, self.est.as_mut()) else {
            return;
        };
        if !self.flown || i < load_a {
            return;
        }
        let s = self.sag.loaded_s;
        if (LEARN_FROM_S..LEARN_TO_S).contains(&s) {
            self.idle.rs.push((est.ocv() - v) / i);
            return;
        }
        if s < LEARN_TO_S {
            return;
        }
        self.idle.start = None;
        let Some(r) = median(self.idle.rs.iter().copied()) else {
            return;
        };
        let r = r.clamp(0.0, MAX_R_CELL_OHM * f64::from(cells.max(1)));
        let wh = est.restate(v0, v0 + idle_a * (r - r_used));
        if wh.abs() > 1e-9 {
            self.notes.push(format!(
                "battery: the resting voltage was read under {idle_a:.2} A of ground idle; the pack's resistance in flight, {:.0} mΩ (read with {:.0} mΩ), restates the start by {:+.3} V: {wh:+.2} Wh",
                1000.0 * r,
                1000.0 * r_used,
                idle_a * (r - r_used),
            ));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::Sourced;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 2_000, failure_persistence: None, ..ProptestConfig::default() })]

        /// No current, a negative one (a sensor's offset; charging is no rest), a resistance
        /// not known: the reading as it is. Otherwise V + I·R, growing with both.
        #[test]
        fn the_idle_correction_is_v_plus_i_r_or_nothing(
            v in 0.5f64..60.0,
            i in 0.0f64..1.0,
            r in 0.0f64..2.0,
            neg in -2.0f64..0.0,
            bad_r in prop_oneof![Just(f64::NAN), Just(f64::INFINITY), -5.0f64..-1e-9],
        ) {
            prop_assert_eq!(rest_ocv(v, 0.0, Some(r)), v);
            prop_assert_eq!(rest_ocv(v, neg, Some(r)), v);
            prop_assert_eq!(rest_ocv(v, f64::NAN, Some(r)), v);
            prop_assert_eq!(rest_ocv(v, i, None), v);
            prop_assert_eq!(rest_ocv(v, i, Some(bad_r)), v);
            let x = rest_ocv(v, i, Some(r));
            prop_assert!((x - (v + i * r)).abs() < 1e-12);
            prop_assert!(x >= v);
            prop_assert!(rest_ocv(v, i + 0.1, Some(r)) >= x);
            prop_assert!(rest_ocv(v, i, Some(r + 0.1)) >= x);
        }
    }

    fn facts(chem: &str) -> BatteryFacts {
        BatteryFacts {
            cell_count: Sourced::new(3, Provenance::Config),
            capacity_wh: Some(Sourced::new(27.0, Provenance::Config)),
            chemistry: Sourced::new(chem.into(), Provenance::Config),
            low_voltage_v: Some(Sourced::new(9.0, Provenance::Config)),
            ..BatteryFacts::default()
        }
    }

    /// A 3S 2.5 Ah pack of 0.3 Ω resting at 11.4 V: `idle_a` on the ground for 10 s, then
    /// 3 A for `fly_s`; its voltage is 11.4 V − I·0.3 Ω (no discharge, for clarity).
    fn fly(chem: &str, idle_a: f64, fly_s: f64) -> (Pack, PackNow, PackNow) {
        let f = facts(chem);
        let mut p = Pack::default();
        let (mut rested, mut now) = (PackNow::default(), PackNow::default());
        let mut t = 0.0;
        while t < 10.0 + fly_s {
            let i = if t < 10.0 { idle_a } else { 3.0 };
            now = p.update(
                t,
                Some(11.4 - 0.3 * i),
                Some(i),
                Some(Load::constant(30.0)),
                &f,
            );
            if t < 10.0 {
                rested = now;
            }
            t += 0.1;
        }
        (p, rested, now)
    }

    #[test]
    fn a_li_ion_rest_is_read_through_the_ground_idle_and_restated_in_flight() {
        let f = facts("liion");
        let r_prior = prior_r_ohm(3, pack_ah(&f, Chemistry::LiIon));
        let (p, rested, flying) = fly("liion", 0.3, 40.0);
        let raw = 11.4 - 0.3 * 0.3;
        let rest_v = rested.rest_v.expect("a resting voltage");
        assert!((rest_v - (raw + 0.3 * r_prior)).abs() < 1e-9, "{rested:?}");
        // The flight shows ~0.3 Ω: the start is restated to the pack's 11.4 V, said once.
        let (curve, _) = pack_model(&f).expect("a model");
        let want = curve.energy(11.4 / 3.0) - curve.energy(rest_v / 3.0);
        let restated = p.notes.iter().filter(|n| n.contains("ground idle")).count();
        assert_eq!(restated, 1, "{:?}", p.notes);
        let gained = flying.energy_wh.unwrap() - rested.energy_wh.unwrap();
        // what 30 s at 3 A draws (≤ 0.3 Wh) aside, the energy rose by the restated start
        assert!(want > 0.5, "{want}");
        assert!(
            (gained - want).abs() < 0.35 + 0.2 * want,
            "{gained} vs {want}"
        );
    }

    #[test]
    fn no_idle_current_or_another_chemistry_reads_the_rest_as_it_is() {
        // no current at rest: nothing to correct, nothing restated
        let (p, rested, _) = fly("liion", 0.0, 40.0);
        assert!(
            rested.rest_v.is_some_and(|v| (v - 11.4).abs() < 1e-9),
            "{rested:?}"
        );
        assert!(
            !p.notes.iter().any(|n| n.contains("ground idle")),
            "{:?}",
            p.notes
        );
        // a LiPo pack's table is the hobby one, read as it always was
        let (p, rested, _) = fly("lipo", 0.3, 40.0);
        assert!(
            rested.rest_v.is_some_and(|v| (v - 11.31).abs() < 1e-9),
            "{rested:?}"
        );
        assert!(
            !p.notes.iter().any(|n| n.contains("ground idle")),
            "{:?}",
            p.notes
        );
    }

    /// Li-ion's table is a resting-voltage one: its packs count at the open-circuit voltage;
    /// the others (the TB48D's fit on terminal energy, LiPo, LiFePO4) at the terminals.
    #[test]
    fn only_a_resting_voltage_table_counts_at_the_ocv() {
        for (chem, on) in [
            ("liion", true),
            ("lipo", false),
            ("lihv", false),
            ("lifepo4", false),
        ] {
            let (_, p) = pack_model(&facts(chem)).expect("a model");
            assert_eq!(p.ocv_count, on, "{chem}");
        }
        let (_, m100) = pack_model(&BatteryFacts::m100()).expect("the M100's");
        assert!(!m100.ocv_count);
    }
}
