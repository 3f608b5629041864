//! Loaded-voltage forecast over a future power profile.
//!
//! Why power and not current: planners predict power (W) from speed/mass/wind; the pack
//! decides the current. Each step solves P = V·I with V = C − R·I, where, on the flight's
//! own fit [k_w, k_c, b] ([`super::split`]; k = k_w + k_c·c, c the cold share that fades
//! with the forecast's heat), C = OCV − b − R1·(k_w·x_w + k_c·x_c)·e1 and
//! R = k·(R0 + R1·(1 − e1)) (the RC states' exact step; before take-off k_w = k_c = 1 and
//! this is the circuit's f·R0 + f·R1·(1 − e1)),
//! i.e. R·I² − C·I + P = 0, taking the smaller root (the stable operating point).
//! If C² < 4·R·P the pack cannot deliver P: the current is set to the maximum-power point
//! C/(2R) and `power_limited` is set.
//!
//! **The lowest voltage of a smooth forecast.** A power forecast (the plan's, or a constant
//! power) is smooth; the measured voltage dips lower under the short power transients it
//! lacks (gusts, manoeuvres, the controller's corrections). The forecast of the *measured*
//! lowest voltage is therefore the forecast path's lowest point with its sag below the
//! open-circuit voltage deepened by a fraction ([`dip`]): [`SAG_PREFLIGHT`] from a state at
//! rest before take-off, [`SAG_IN_FLIGHT`] from a state in flight. Both were chosen by 5-fold
//! by-flight cross-validation on the M100 training flights (`lab/scripts/battery/lab_minv.py`,
//! `lab/scripts/battery/NOTES-min-voltage.md`). Crossing times are those of the smooth path: the
//! autopilots' low-voltage failsafes act on a filtered voltage held under the threshold for
//! seconds, not on a transient.

use super::circuit::Estimator;

/// Forecast result. Times are seconds from the forecast start.
#[derive(Debug, Clone, PartialEq)]
pub struct Forecast {
    /// Lowest loaded voltage (V); NaN if no valid step.
    pub v_min: f64,
    /// When `v_min` occurs (s).
    pub t_v_min: f64,
    /// Loaded voltage at the end of the profile (V).
    pub v_end: f64,
    /// First time the voltage falls below each threshold (same order), `None` if never.
    pub crossings: Vec<Option<f64>>,
    /// Energy left above the floor when each threshold is first crossed (same order, table
    /// units): what is usable before the voltage failsafe, subtracted from the energy now.
    pub energy_at_crossing: Vec<Option<f64>>,
    /// True if some step asked for more power than the pack can deliver.
    pub power_limited: bool,
    /// Energy left above floor at the end (Wh for the TB48D table).
    pub energy_end_wh: f64,
}

/// One step of a forecast: time since its start (s), the loaded voltage (V), the energy left
/// (table units), and whether the pack could not give the power asked.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    pub t_s: f64,
    pub v: f64,
    pub energy: f64,
    pub power_limited: bool,
    /// The open-circuit voltage after the step (V): `ocv − v` is the step's sag.
    pub ocv: f64,
}

/// The measured lowest voltage dips under a smooth forecast's lowest point by this fraction
/// of the forecast's sag there, from a state at rest before take-off (by-flight CV on the
/// M100 training flights, the plan's power as `plan-eval` builds it: median |error| of the
/// lowest loaded voltage 0.465 → 0.261 V).
pub const SAG_PREFLIGHT: f64 = 0.24;
/// The same from a state in flight (from half time along the rest of the plan: 0.547 →
/// 0.134 V in CV).
pub const SAG_IN_FLIGHT: f64 = 0.32;

/// A step's voltage with its sag below the open-circuit voltage deepened by `frac` (the
/// transients a smooth power forecast lacks): `v − frac·(ocv − v)`.
pub fn dip(s: &Step, frac: f64) -> f64 {
    s.v - frac * (s.ocv - s.v).max(0.0)
}

/// The step with the lowest [`dip`] (a smooth forecast's lowest measured voltage), and that
/// voltage; `None` for an empty profile.
pub fn lowest_dip(
    state: &Estimator,
    profile: impl IntoIterator<Item = (f64, f64)>,
    frac: f64,
) -> Option<(Step, f64)> {
    steps(state, profile)
        .map(|s| (s, dip(&s, frac)))
        .filter(|(_, v)| v.is_finite())
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// The steps of flying `profile` = [(dt_s, power_w)] from the estimator's present state (not
/// modified), lazily: a caller that wants only the first crossing stops there. Non-finite or
/// non-positive dt steps are skipped; NaN power is 0 W, negative power clamped to 0 W.
pub fn steps(
    state: &Estimator,
    profile: impl IntoIterator<Item = (f64, f64)>,
) -> impl Iterator<Item = Step> {
    let mut s = state.clone();
    let p = s.p;
    // the flight's own circuit: the part that stays (k_w) and the cold part (k_c) that
    // fades with the heat this forecast adds
    let [kw, kc, b] = s.split_fit();
    let deepen = deepening(&s);
    let mut t = 0.0;
    // The open-circuit voltage depends on the energy alone: the one after a step is the next
    // step's before (one table look-up a step instead of two; the forecast's hot spot).
    let mut ocv = s.ocv();
    profile
        .into_iter()
        .filter(|(dt, _)| dt.is_finite() && *dt > 0.0)
        .map(move |(dt, pw)| {
            let pw = if pw.is_finite() { pw.max(0.0) } else { 0.0 };
            let eh = (-dt / p.tau_heat_s).exp();
            s.heat *= eh;
            let cold = s.cold();
            let k = kw + kc * cold;
            let e1 = (-dt / p.tau1_s).exp();
            // the sag deepens as the pack empties (battery::deep): 1 for the TB48D
            let g = deepen(s.soc());
            let c = ocv - b - g * p.r1 * (kw * s.split.xw + kc * s.split.xc) * e1;
            let re = ((p.r0 + p.r1 * (1.0 - e1)) * k * g).max(1e-6);
            let disc = c * c - 4.0 * re * pw;
            let (i, power_limited) = if disc >= 0.0 {
                ((c - disc.sqrt()) / (2.0 * re), false)
            } else {
                (c / (2.0 * re), true)
            };
            let v = c - re * i;
            s.heat += i * i * p.tau_heat_s * (1.0 - eh);
            s.split.propagate(e1, i, cold);
            s.energy = (s.energy - v * i * dt / 3600.0).max(0.0);
            ocv = s.ocv();
            t += dt;
            Step {
                t_s: t,
                v,
                energy: s.energy,
                power_limited,
                ocv,
            }
        })
}

/// The growth of the sag from now on, g(soc) ([`super::deep`]): the circuit's own shape up to
/// now, on along the slope this flight has shown (shrunk toward the circuit's).
fn deepening(s: &Estimator) -> impl Fn(f64) -> f64 {
    let p = s.p;
    let soc_now = s.soc();
    let beta = if p.deep_a != 0.0 || p.deep_slope != 0.0 {
        s.deep_learned()
    } else {
        p.deep_slope
    };
    let g = move |soc: f64| super::deep::growth(p.deep_a, p.deep_soc, beta, soc);
    let scale = p.growth(soc_now) / g(soc_now);
    move |soc| scale * g(soc)
}

/// A constant power `power_w` for `span_s`, in steps of `dt_s` (the last step whole): a
/// profile for [`steps`] that allocates nothing.
pub fn constant(power_w: f64, dt_s: f64, span_s: f64) -> impl Iterator<Item = (f64, f64)> {
    let n = crate::features::units::ceil_ratio(span_s, dt_s).unwrap_or(0.0);
    std::iter::repeat_n((dt_s, power_w), n as usize)
}

/// The first step whose loaded voltage falls below `threshold_v` (stops there), if any.
pub fn first_crossing(
    state: &Estimator,
    profile: impl IntoIterator<Item = (f64, f64)>,
    threshold_v: f64,
) -> Option<Step> {
    steps(state, profile).find(|s| s.v < threshold_v)
}

/// Simulates from the estimator's present state (not modified) over `profile` =
/// [(dt_s, power_w)]. Non-finite or non-positive dt steps are skipped; negative or NaN
/// power is treated as 0 W (NaN) or clamped to 0 W (negative). Never panics.
pub fn forecast(state: &Estimator, profile: &[(f64, f64)], thresholds_v: &[f64]) -> Forecast {
    let mut out = Forecast {
        v_min: f64::NAN,
        t_v_min: f64::NAN,
        v_end: f64::NAN,
        crossings: vec![None; thresholds_v.len()],
        energy_at_crossing: vec![None; thresholds_v.len()],
        power_limited: false,
        energy_end_wh: state.energy,
    };
    for st in steps(state, profile.iter().copied()) {
        out.power_limited |= st.power_limited;
        if out.v_min.is_nan() || st.v < out.v_min {
            out.v_min = st.v;
            out.t_v_min = st.t_s;
        }
        out.v_end = st.v;
        out.energy_end_wh = st.energy;
        for (k, &th) in thresholds_v.iter().enumerate() {
            if out.crossings[k].is_none() && st.v < th {
                out.crossings[k] = Some(st.t_s);
                out.energy_at_crossing[k] = Some(st.energy);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::battery::{CircuitParams, OcvCurve};

    fn est() -> Estimator {
        Estimator::new(CircuitParams::default(), OcvCurve::tb48d(), 24.0, 0.0).expect("valid")
    }

    #[test]
    fn reproduces_python_forecast() {
        let mut prof = vec![(0.5, 500.0); 120];
        prof.extend(vec![(0.5, 100.0); 20]);
        let f = forecast(&est(), &prof, &[22.5, 21.0]);
        assert!((f.v_min - 21.351727443961877).abs() < 1e-9, "{f:?}");
        assert!((f.t_v_min - 60.0).abs() < 1e-9);
        assert!((f.v_end - 22.74851184137836).abs() < 1e-9);
        assert_eq!(f.crossings, vec![Some(0.5), None]);
        assert!(
            f.energy_at_crossing[0].is_some_and(|e| e > 0.0) && f.energy_at_crossing[1].is_none()
        );
        assert!(!f.power_limited);
    }

    #[test]
    fn empty_nan_and_huge_profiles_do_not_panic() {
        let e = est();
        let f = forecast(&e, &[], &[21.0]);
        assert!(f.v_min.is_nan() && f.crossings == vec![None]);
        let f = forecast(
            &e,
            &[
                (f64::NAN, 1.0),
                (1.0, f64::NAN),
                (-1.0, 5.0),
                (1.0, f64::INFINITY),
            ],
            &[f64::NAN],
        );
        assert!(f.v_min.is_finite());
        let f = forecast(&e, &[(1.0, 1e9)], &[]);
        assert!(f.power_limited && f.v_min.is_finite());
        let mut s: u64 = 99;
        for _ in 0..200 {
            let prof: Vec<(f64, f64)> = (0..50)
                .map(|_| {
                    s = s
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    let u = (s >> 11) as f64 / (1u64 << 53) as f64;
                    (u * 2.0 - 0.2, u * 3000.0 - 100.0)
                })
                .collect();
            let f = forecast(&e, &prof, &[21.0, 22.0]);
            assert!(f.v_min.is_nan() || f.v_min <= f.v_end + 1e-12);
            assert!(f.energy_end_wh >= 0.0);
        }
    }
}
