//! The pack in the energy stage: its start state from the resting voltage before take-off,
//! the equivalent circuit ([`crate::battery`]) tracked on the measured voltage and current,
//! and the loaded-voltage forecast at the forecast power.
//!
//! - **Rest.** While the current stays under [`rest_current_a`] (1 A; less on a pack under
//!   about 3 Ah) and the voltage has moved
//!   less than [`REST_SPREAD_V`] over [`REST_SETTLE_S`], the median of those seconds is the
//!   resting voltage. Before the first take-off (current over [`load_current_a`]) each new
//!   resting voltage restarts the pack's state from it: energy to the floor through the OCV
//!   curve (the TB48D's fitted one for the M100's pack, else the chemistry's default shape
//!   scaled to the capacity). After a flight, a resting voltage more than
//!   [`SWAP_RISE_V_CELL`] a cell above the model's open-circuit voltage is a new pack: the
//!   state restarts, with a warning.
//! - **In flight** the estimator's RLS follows the resistance and the polarisation; its
//!   a-priori voltage is the modelled loaded voltage (`battery_v_model`).
//! - **Forecast** every [`FORECAST_EVERY_S`], the loaded voltage at a constant power, in
//!   steps of [`FORECAST_STEP_S`]:
//!   - the lowest over the rest of the flight, and when: the rest of the mission at its mean
//!     power when one is known, else the forecast power until the energy left reaches the
//!     reserve (where a pilot lands); the smooth path's sag deepened by the transients it
//!     lacks ([`crate::battery::forecast::dip`]);
//!   - the time until it crosses the low threshold (the autopilot's `BATT_LOW_VOLT`, else
//!     3.5 V a cell) flying on at that power (up to [`FORECAST_HORIZON_S`]), and the energy
//!     usable before it: the remaining energy to the usable floor.
//!
//! - **Any start.** With no resting voltage read after [`LOAD_START_S`] of readings (a rest
//!   too short, none at all, a ground current too noisy to call rest, a monitor attached
//!   in flight), the state starts load-compensated: OCV = V + I·R with the prior resistance
//!   for the chemistry and the pack's size ([`prior_r_ohm`]), the median over those seconds,
//!   said once, with a wider band ([`PackNow::soc_band_pct`]). "Assumed full" is left for a
//!   vehicle that sends no voltage or no current.
//! - **No capacity** ([`crate::report::CAPACITY_UNKNOWN`]): no circuit (its energy needs
//!   the capacity), but the state of charge from the voltage and cells through the
//!   chemistry's curve: at rest, else load-compensated as above.
//! - **No sag** ([`SagCheck`]): a pack whose voltage stays put while the current swings
//!   (SITL's default battery, a stuck reading, a sensor behind a regulator) cannot show its
//!   resistance: the modelled voltage, the voltage forecast and the time to the low voltage
//!   are withheld (null, the reason in [`PackNow::withheld`], said once); energy counting
//!   goes on.
//! - **No impossible value.** A modelled voltage outside the chemistry's range for the cell
//!   count, a resistance under 0 or over [`MAX_R_CELL_OHM`] a cell is withheld, never shown;
//!   the state of charge is kept in 0-100 %, energies ≥ 0.
//!
//! Nothing here does I/O; a sample with no voltage, a NaN, or a current under −2 A
//! leaves the state as it was.

use crate::battery::forecast::{
    constant, first_crossing, lowest_dip, SAG_IN_FLIGHT, SAG_PREFLIGHT,
};
use crate::battery::{Chemistry, CircuitParams, Estimator, OcvCurve, PackHistory};
use crate::report::{BatteryFacts, Provenance};

/// Current under which the pack counts as resting, A ([`rest_current_a`]: less on a small pack).
pub const REST_CURRENT_A: f64 = 1.0;
/// The least rest current, A ([`rest_current_a`]): what a flight controller, receiver and
/// video transmitter draw idling on the ground, whatever the pack (a 4 Wh 3S pack idling at
/// 2 W, 0.18 A, rests).
pub const REST_FLOOR_A: f64 = 0.3;
/// How long the voltage must hold still at rest before it is read, s.
pub const REST_SETTLE_S: f64 = 2.0;
/// The most the resting voltage may move over [`REST_SETTLE_S`] to count as settled, V.
pub const REST_SPREAD_V: f64 = 0.05;
/// Current over which the M100's pack counts as loaded (flying: the start state is then kept;
/// the sag check's seconds under load), A; other packs: [`load_current_a`].
pub const LOAD_CURRENT_A: f64 = 3.0;

/// A resting voltage this far above the model's OCV after a flight is a new pack, V a cell.
pub const SWAP_RISE_V_CELL: f64 = 0.05;
/// How often the voltage forecast is recomputed, s of source time.
pub const FORECAST_EVERY_S: f64 = 1.0;
/// The voltage forecast's step, s.
pub const FORECAST_STEP_S: f64 = 5.0;
/// The voltage forecast's horizon, s.
pub const FORECAST_HORIZON_S: f64 = 3600.0;
/// The low threshold when the autopilot gives none, V a cell (the `battery-eval` line).
pub const DEFAULT_LOW_V_CELL: f64 = 3.5;
/// How long readings must come with no resting voltage before the state starts
/// load-compensated, s.
pub const LOAD_START_S: f64 = 3.0;
/// The most series resistance a cell may show, Ω (a 200 mAh cell is ~0.3 Ω): past it the
/// fit is withheld.
pub const MAX_R_CELL_OHM: f64 = 0.5;
/// The state of charge's band, ± points: from a resting voltage, load-compensated, and
/// added where the chemistry is assumed.
pub const SOC_BAND_REST_PCT: f64 = 3.0;
pub const SOC_BAND_LOADED_PCT: f64 = 10.0;
pub const SOC_BAND_CHEMISTRY_PCT: f64 = 10.0;

/// The forecast model's power may be this far (a factor either way) from the measured power in
/// flight and still be flown by the pack's forecast.
pub const MODEL_AGREE: f64 = 1.5;

/// The power the pack's forecast flies with no mission: the forecast model's, unless the
/// measured power in flight (smoothed) says it is not this vehicle's (more than
/// [`MODEL_AGREE`]× off: a model fitted on another airframe, the M100's 400 W on a 20 W quad,
/// would put the low-voltage crossing minutes early), then the measured power.
pub fn pack_power(model_w: Option<f64>, measured_w: Option<f64>) -> Option<f64> {
    let m = measured_w.filter(|p| p.is_finite() && *p > 1.0);
    match (model_w.filter(|p| p.is_finite()), m) {
        (Some(f), Some(m)) if f > m * MODEL_AGREE || f * MODEL_AGREE < m => Some(m),
        (Some(f), _) => Some(f),
        (None, m) => m,
    }
}

/// What the pack model says now (all absent until a resting voltage was read).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PackNow {
    /// The resting voltage the state started from, V.
    pub rest_v: Option<f64>,
    /// Open-circuit voltage now, V.
    pub ocv_v: Option<f64>,
    /// State of charge, % of the OCV curve's energy.
    pub soc_pct: Option<f64>,
    /// Effective series resistance now, Ω.
    pub internal_r_ohm: Option<f64>,
    /// Modelled loaded voltage for this sample (before it was learned from), V.
    pub v_model: Option<f64>,
    /// Energy above the curve's floor, Wh.
    pub energy_wh: Option<f64>,
    /// The curve's whole energy, floor to full, Wh.
    pub curve_wh: Option<f64>,
    /// Lowest forecast loaded voltage, V, and when, s from now.
    pub v_min_forecast: Option<(f64, f64)>,
    /// Time until the forecast loaded voltage crosses the low threshold, s.
    pub time_to_low_v_s: Option<f64>,
    /// Energy usable before the low threshold, Wh.
    pub usable_wh: Option<f64>,
    /// The low threshold used, V.
    pub low_v: Option<f64>,
    /// The resting voltage after the flight (landed, settled), V, and its state of charge, %.
    pub end_rest_v: Option<f64>,
    pub end_rest_soc_pct: Option<f64>,
    /// This flight's resistance against the nominal circuit's (least squares under load).
    pub r_scale: Option<f64>,
    /// The heat proxy now, A²·s (carried to the next flight on this pack).
    pub heat: Option<f64>,
    /// The slope of the sag's growth as the pack empties this pack has shown
    /// ([`crate::battery::deep`]; for the store, to start its next flight from:
    /// [`CircuitParams::with_deep`]).
    pub deep_slope: Option<f64>,
    /// Whether the state started from the previous flight on this pack (its resistance and
    /// heat carried over).
    pub carried: bool,
    /// How the start state was read: a resting voltage, or load-compensated (V + I·R).
    #[serde(deserialize_with = "said::deserialize")]
    pub start: Said,
    /// The state of charge's band, ± points.
    pub soc_band_pct: Option<f64>,
    /// Why the modelled voltage, the voltage forecast and the time to the low voltage are
    /// null, when they are withheld.
    #[serde(deserialize_with = "said::deserialize")]
    pub withheld: Said,
}

/// One of the pack's fixed texts (named so that serde's derive asks no `'static` input).
pub type Said = Option<&'static str>;

/// [`PackNow`]'s fixed texts read back (a fleet worker's checkpoint): one of the texts
/// this module says, or an error.
mod said {
    use serde::{Deserialize, Deserializer};

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<super::Said, D::Error> {
        let Some(s) = Option::<String>::deserialize(d)? else {
            return Ok(None);
        };
        [
            super::FROM_REST,
            super::FROM_LOAD,
            super::NO_SAG,
            super::SAG_PENDING,
            super::OUT_OF_RANGE,
        ]
        .into_iter()
        .find(|k| *k == s)
        .map(Some)
        .ok_or_else(|| serde::de::Error::custom(format!("not a text of the pack's: {s:?}")))
    }
}

/// The reason the voltage figures are withheld for a pack that does not sag.
pub const NO_SAG: &str = "the pack's voltage does not sag under load (a simulator's fixed battery, a stuck reading or a sensor behind a regulator): no voltage forecast, energy still counted";
/// How a start state read off a resting voltage is said.
pub const FROM_REST: &str = "resting voltage";
/// How a load-compensated start state is said.
pub const FROM_LOAD: &str = "load-compensated (V + I·R, prior R)";

/// The median of some readings (None for none).
fn median(xs: impl Iterator<Item = f64>) -> Option<f64> {
    let mut v: Vec<f64> = xs.filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied()
}

/// The reason they are withheld for a model outside the chemistry's range.
pub const SAG_PENDING: &str = "the state started load-compensated: the voltage forecast waits for 10 s under load, until the pack has shown how it sags";
/// The reason they are withheld for a model outside the chemistry's range.
pub const OUT_OF_RANGE: &str =
    "the pack model left the chemistry's voltage or resistance range: its voltages are withheld";

/// The load the forecast flies: `first_w` (W) for `first_s` (s; the rest of a mission; None:
/// on until the reserve), then `then_w`, the flight's sustained power, on past the mission's
/// end (so that the usable floor does not leap when a mission's last, light descent ends).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Load {
    pub first_w: f64,
    pub first_s: Option<f64>,
    pub then_w: f64,
}

impl Load {
    /// One power for the whole forecast.
    pub fn constant(w: f64) -> Self {
        Self {
            first_w: w,
            first_s: None,
            then_w: w,
        }
    }
}

/// The pack's state across the estimates of one vehicle.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct Pack {
    /// (t, V) of the current rest stretch, at most [`REST_SETTLE_S`] long.
    rest: std::collections::VecDeque<(f64, f64)>,
    rest_v: Option<f64>,
    flown: bool,
    est: Option<Estimator>,
    last_t: Option<f64>,
    last_forecast_t: Option<f64>,
    now: PackNow,
    /// (t, V + I·R prior) of the last [`LOAD_START_S`]: the load-compensated start, and the
    /// state of charge with no capacity.
    loaded: std::collections::VecDeque<(f64, f64)>,
    /// Since when readings have come with no state (s).
    since: Option<f64>,
    sag: SagCheck,
    /// Said once: the load-compensated start, the withheld voltages.
    said_start: bool,
    said_withheld: bool,
    /// Energy kept in reserve, fraction of the curve's (the rest of a flight with no
    /// mission ends there).
    pub reserve_frac: f64,
    /// The last flight's pack, from the vehicle store.
    pub history: Option<PackHistory>,
    /// The measured loaded voltage's trend this flight: the time to the low voltage.
    trend: crate::battery::trend::VoltageTrend,
    /// Messages for a warning, taken by the caller.
    pub notes: Vec<String>,
    /// The ground idle's currents and its I·R ([`rest`]).
    #[serde(default)]
    idle: rest::Idle,
}

impl Pack {
    /// A pack whose flights end at `reserve_frac` of the curve's energy when no mission says.
    pub fn new(reserve_frac: f64) -> Self {
        Self {
            reserve_frac,
            ..Self::default()
        }
    }

    /// Take one sample: time (s), pack voltage (V) and current (A, discharge positive);
    /// `rest_of_flight` is what the forecast flies ([`Load`]); `facts` say which pack.
    pub fn update(
        &mut self,
        t: f64,
        v: Option<f64>,
        i: Option<f64>,
        rest_of_flight: Option<Load>,
        facts: &BatteryFacts,
    ) -> PackNow {
        let (Some(v), Some(i)) = (
            v.filter(|v| v.is_finite() && *v > 0.5),
            i.filter(|i| i.is_finite() && *i > -2.0),
        ) else {
            // Nothing new, but the facts may be (a cell count heard since): what was said
            // must still be possible for them.
            let chem = Chemistry::from_name(&facts.chemistry.value).unwrap_or(Chemistry::LiPo);
            self.possible(chem, facts.cell_count.value.max(1));
            return self.now;
        };
        if !t.is_finite() {
            return self.now;
        }
        let dt = self
            .last_t
            .map(|t0| t - t0)
            .filter(|dt| *dt > 0.0 && *dt <= 5.0);
        self.last_t = Some(t);
        let chem = Chemistry::from_name(&facts.chemistry.value).unwrap_or(Chemistry::LiPo);
        let cells = facts.cell_count.value.max(1);
        // V + I·R with the prior resistance: the open-circuit voltage under any load.
        let ah = pack_ah(facts, chem);
        let r = prior_r_ohm(cells, ah);
        let (rest_a, load_a) = priors::currents_of(ah);
        self.loaded.push_back((t, v + i.max(0.0) * r));
        while self
            .loaded
            .front()
            .is_some_and(|(t0, _)| t - t0 > LOAD_START_S)
        {
            self.loaded.pop_front();
        }
        if i.abs() < rest_a {
            self.rest_sample(t, v, i, r, chem);
            if let Some(rest_v) = self.settled(t) {
                self.at_rest(rest_v, facts);
            }
        } else {
            self.rest_clear();
            if i >= load_a && self.rest_v.is_some() {
                self.flown = true;
            }
        }
        // the trend's loaded samples; with the capacity not known, any current over the rest
        // current (a micro pack hovering under 3 A still gets its time to the low voltage)
        let trend_a = ah.map_or(REST_CURRENT_A, |ah| {
            crate::battery::trend::loaded_a(Some(ah))
        });
        if i >= trend_a {
            self.trend.add(t, v, i);
        }
        if i >= load_a {
            if let Some(dt) = dt {
                self.sag.update(dt, v, i, cells, r);
            }
        }
        self.maybe_start_loaded(t, i, r, load_a, facts);
        if self.rest_v.is_some() && self.est.is_none() && !self.sag.flat {
            // No capacity: the state of charge from the load-compensated voltage.
            if let Some(ocv) = median(self.loaded.iter().map(|(_, x)| *x)) {
                self.now.ocv_v = Some(ocv);
                self.now.soc_pct = Some(100.0 * chem.default_curve().soc(ocv / f64::from(cells)));
            }
        }
        let Some(est) = self.est.as_mut() else {
            // No circuit (no capacity): the time to the low voltage from the trend alone.
            self.now.time_to_low_v_s = rest_of_flight.and_then(|l| {
                let low = low_v(facts);
                self.now.low_v = Some(low);
                self.trend
                    .time_to(low, l.first_w)
                    .filter(|s| *s <= FORECAST_HORIZON_S)
            });
            self.possible(chem, cells);
            return self.now;
        };
        if let Some(e) = dt.and_then(|dt| est.update(dt, i, v)) {
            self.now.v_model = Some(e.v_prior);
            self.now.ocv_v = Some(e.ocv);
            self.now.internal_r_ohm = Some(e.r0_eff);
            self.now.soc_pct = Some((100.0 * e.soc).clamp(0.0, 100.0));
            self.now.energy_wh = Some(e.energy_wh.max(0.0));
            self.now.r_scale = est.pack_scale();
            self.now.heat = Some(est.heat());
            self.now.deep_slope = Some(est.deep_learned());
        }
        self.learn_idle_r(v, i, load_a, cells);
        if self.flown && !self.rest.is_empty() {
            // Landed: no rest of the flight to forecast.
            (self.now.v_min_forecast, self.now.time_to_low_v_s) = (None, None);
        } else if self
            .last_forecast_t
            .is_none_or(|t0| t - t0 >= FORECAST_EVERY_S || t < t0)
        {
            self.last_forecast_t = Some(t);
            self.forecast(rest_of_flight, facts);
        }
        self.possible(chem, cells);
        self.now
    }

    /// Withhold what cannot be: every voltage figure of a pack that does not sag, and any
    /// modelled voltage outside the chemistry's range for the cell count or resistance
    /// outside 0..[`MAX_R_CELL_OHM`] a cell. Each reason said once.
    fn possible(&mut self, chem: Chemistry, cells: u32) {
        let n = f64::from(cells);
        let (lo, hi) = (
            n * chem.loaded_min_v(),
            n * (chem.full_v() + crate::battery::chemistry::FULL_TOL_V),
        );
        let in_range = |x: Option<f64>| x.is_none_or(|x| x.is_finite() && (lo..=hi).contains(&x));
        // A forecast that runs under the chemistry's floor says the pack would be flown flat
        // before the flight ends: bounded at the floor (still under every threshold, so the
        // time to the low voltage and its alert stand), not withheld.
        if let Some((v, at)) = self.now.v_min_forecast {
            if v.is_finite() && v < lo {
                self.now.v_min_forecast = Some((lo, at));
            }
        }
        let r_ok = self
            .now
            .internal_r_ohm
            .is_none_or(|r| r.is_finite() && (0.0..=MAX_R_CELL_OHM * n).contains(&r));
        let pending = self.now.start.is_some_and(|s| s != FROM_REST)
            && self.sag.loaded_s < SagCheck::MIN_LOADED_S;
        let why = if self.sag.flat {
            Some(NO_SAG)
        } else if pending && self.est.is_some() {
            Some(SAG_PENDING)
        } else if !(in_range(self.now.v_model)
            && in_range(self.now.ocv_v)
            && in_range(self.now.v_min_forecast.map(|(v, _)| v))
            && r_ok)
        {
            Some(OUT_OF_RANGE)
        } else {
            None
        };
        self.now.withheld = why;
        let Some(why) = why else { return };
        self.now.v_model = None;
        self.now.v_min_forecast = None;
        self.now.time_to_low_v_s = None;
        self.now.usable_wh = None;
        self.now.internal_r_ohm = None;
        if !in_range(self.now.ocv_v) {
            self.now.ocv_v = None;
        }
        if !self.said_withheld && why != SAG_PENDING {
            self.said_withheld = true;
            self.notes.push(format!("battery: {why}"));
        }
    }

    /// No resting voltage after [`LOAD_START_S`] of readings (and none settling now, or
    /// three times that long): start from the load-compensated voltage, said once.
    fn maybe_start_loaded(&mut self, t: f64, i: f64, r: f64, load_a: f64, facts: &BatteryFacts) {
        if self.rest_v.is_some() {
            self.since = None;
            return;
        }
        let since = *self.since.get_or_insert(t);
        let resting = self.rest.front().is_some_and(|(t0, _)| t - t0 >= 1.0);
        if t - since < LOAD_START_S || (resting && t - since < 3.0 * LOAD_START_S) {
            return;
        }
        let Some(ocv) = median(self.loaded.iter().map(|(_, x)| *x)) else {
            return;
        };
        // Within the chemistry's resting window for the cells (a prior resistance too high
        // for this pack must not start it over full).
        let chem = Chemistry::from_name(&facts.chemistry.value).unwrap_or(Chemistry::LiPo);
        let n = f64::from(facts.cell_count.value.max(1));
        let ocv = ocv.clamp(n * chem.floor_v(), n * chem.full_v());
        if !self.said_start {
            self.said_start = true;
            self.notes.push(format!(
                "battery: no resting voltage was read before {t:.0} s: the pack's state starts load-compensated (V + I·R, prior R {:.0} mΩ for {} cells) at {ocv:.2} V, band ±{SOC_BAND_LOADED_PCT:.0} points",
                1000.0 * r,
                facts.cell_count.value
            ));
        }
        self.start(ocv, FROM_LOAD, facts);
        // Flying already: the start is not a rest before take-off.
        self.flown = i >= load_a;
    }

    /// Whether the start state may still come from a resting voltage: the pack is resting
    /// now, no resting voltage has been read yet and nothing has flown. Until then the
    /// remaining energy is unknown rather than assumed.
    pub fn pending(&self) -> bool {
        self.est.is_none() && !self.rest.is_empty()
    }

    /// The median of the rest stretch when it is long and still enough.
    fn settled(&self, t: f64) -> Option<f64> {
        let (t0, _) = *self.rest.front()?;
        if t - t0 < REST_SETTLE_S - 0.25 {
            return None;
        }
        let mut vs: Vec<f64> = self.rest.iter().map(|(_, v)| *v).collect();
        vs.sort_by(f64::total_cmp);
        let (lo, hi) = (vs[0], vs[vs.len() - 1]);
        (hi - lo <= REST_SPREAD_V).then(|| vs[vs.len() / 2])
    }

    fn at_rest(&mut self, rest_v: f64, facts: &BatteryFacts) {
        let cells = f64::from(facts.cell_count.value.max(1));
        if self.flown {
            let ocv = self.est.as_ref().map(|e| e.ocv()).or(self.now.ocv_v);
            if ocv.is_some_and(|ocv| rest_v > ocv + SWAP_RISE_V_CELL * cells) {
                self.notes.push(format!(
                    "battery: the resting voltage rose to {rest_v:.2} V after flying (the model had {:.2} V): a new pack, its state starts again from this voltage",
                    ocv.unwrap_or(f64::NAN)
                ));
                self.flown = false;
                self.history = None;
                self.trend = Default::default();
                self.sag = SagCheck::default();
                self.said_withheld = false;
            } else {
                // Landed: the resting voltage after the flight (pack health, the next flight).
                self.trend = Default::default();
                self.now.end_rest_v = Some(rest_v);
                let chem = Chemistry::from_name(&facts.chemistry.value).unwrap_or(Chemistry::LiPo);
                self.now.end_rest_soc_pct = Some(
                    100.0
                        * self
                            .est
                            .as_ref()
                            .map_or(chem.default_curve().soc(rest_v / cells), |e| {
                                e.curve_soc(rest_v / cells)
                            }),
                );
                return;
            }
        }
        if self.rest_v.is_some_and(|r| (r - rest_v).abs() < 0.005)
            && self.now.start == Some(FROM_REST)
        {
            return;
        }
        self.start(rest_v, FROM_REST, facts);
    }

    /// Start the pack's state from an open-circuit voltage `v0` (`how` it was read): the
    /// circuit where the capacity is known, else the state of charge alone.
    fn start(&mut self, v0: f64, how: &'static str, facts: &BatteryFacts) {
        let chem = Chemistry::from_name(&facts.chemistry.value).unwrap_or(Chemistry::LiPo);
        let cells = facts.cell_count.value.max(1);
        let band = if how == FROM_REST {
            SOC_BAND_REST_PCT
        } else {
            SOC_BAND_LOADED_PCT
        } + if facts.chemistry.source == Provenance::Default {
            SOC_BAND_CHEMISTRY_PCT
        } else {
            0.0
        };
        self.idle_at_start(v0, how, prior_r_ohm(cells, pack_ah(facts, chem)), chem);
        let Some((curve, params)) = pack_model(facts) else {
            // No capacity (or no pack the model can take): the state of charge alone.
            self.est = None;
            self.rest_v = Some(v0);
            self.now = PackNow {
                rest_v: Some(v0),
                ocv_v: Some(v0),
                soc_pct: Some(100.0 * chem.default_curve().soc(v0 / f64::from(cells))),
                start: Some(how),
                soc_band_pct: Some(band),
                ..PackNow::default()
            };
            return;
        };
        let curve_wh = curve.capacity();
        // The same pack flown again soon: its resistance and warmth carry over.
        let carry = self
            .history
            .filter(|h| h.same_pack(v0, facts.cell_count.value));
        let params = carry.and_then(|h| h.r_scale).map_or(params, |k| {
            params.carried_over(k, crate::battery::PACK_SCALE_CARRY)
        });
        let heat0 = carry.map_or(0.0, |h| h.heat * (-h.gap_s / params.tau_heat_s).exp());
        // The slope of its deeper sag is the pack's own, recharged or not: carried whenever it
        // is known to be the same pack, for a chemistry whose sag grows (battery::deep).
        let params = self
            .history
            .filter(|h| h.identified || h.same_pack(v0, facts.cell_count.value))
            .and_then(|h| h.deep_slope)
            .filter(|_| params.deep_slope > 0.0)
            .map_or(params, |b| params.with_deep(b));
        if let Some(est) = Estimator::new(params, curve, v0, heat0) {
            self.est = Some(est);
            self.rest_v = Some(v0);
            self.now = PackNow {
                rest_v: Some(v0),
                curve_wh: Some(curve_wh),
                carried: carry.is_some(),
                start: Some(how),
                soc_band_pct: Some(band),
                ..PackNow::default()
            };
        }
    }
}

#[path = "pack_forecast.rs"]
mod forecast;
#[path = "pack_priors.rs"]
mod priors;
#[path = "pack_rest.rs"]
mod rest;
#[path = "pack_sag.rs"]
mod sag;
pub use priors::{
    currents, load_current_a, ocv_table, pack_model, prior_r_ohm, rest_current_a, rest_ocv,
};
use priors::{low_v, pack_ah};
pub use sag::SagCheck;

#[cfg(test)]
#[path = "pack_tests.rs"]
mod tests;
