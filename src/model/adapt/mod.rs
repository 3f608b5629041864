//! Online adaptation: each model's output is fitted to the measured power V·I as the
//! vehicle flies, so models made for the DJI M100 (or told the wrong payload) follow the
//! vehicle they are actually attached to. Pure: numbers in, numbers out, no I/O, no clocks.
//!
//! ## What is fitted
//!
//! An affine output correction per model,
//!
//! ```text
//! P_adapted = a · P_model + b        (W; a dimensionless, b in W)
//! ```
//!
//! warm-started at (a, b) = (1, 0), i.e. the model as it is: exponentially weighted least
//! squares (recursive least squares with forgetting) on the regressor φ = [P_model, 1] and
//! the target y = measured power, with the prior (1, 0) kept as a fixed regulariser:
//!
//! ```text
//! S ← λ·S + φ·φᵀ        r ← λ·r + φ·y        (S + R₀)·θ = r + R₀·(1, 0)
//! ```
//!
//! λ = exp(−Δt / memory_s) per window (Δt = 1 / `telemetry.rate_hz`), so a sample's weight
//! falls by e every `memory_s` seconds: the default `memory_s = 30` follows a new vehicle
//! within 30–60 s (after 60 s, what it learned before weighs e⁻² ≈ 14 %). R₀ =
//! diag(σ_y²/σ_a², σ_y²/σ_b²) (σ_a = 0.5, σ_b = 50 W, σ_y = 20 W measurement noise) is a
//! weak prior that a few seconds of flight outweigh, but only in the direction the data
//! excite. Many models' outputs barely move while the vehicle cruises, so a and b are not
//! separately identifiable; the covariance form of RLS then winds its covariance up in the
//! unexcited direction and a noise burst throws θ far along it (tried on the M100 flights:
//! 1000 W estimates of a 550 W cruise). The fixed prior holds that direction at (1, 0)
//! instead. Solving the 2 × 2 system each window costs a few nanoseconds.
//!
//! Bounded: a ∈ [`gain_min`, `gain_max`] and |b| ≤ `offset_max_w` after every step, so one
//! wild sample cannot turn a model upside down, and the published value is never below 0 W.
//! The bounded fit is the least-squares fit *within* the bounds (a box-constrained 2 × 2
//! problem: the free minimum, else the best point on the box's edges), not the free fit
//! with a and b clamped each on its own: a model whose output falls while the power rises
//! (Tseng-Solo in a climb) drives the free gain far out of range, and its free offset
//! belongs to that gain, not to the bound.
//!
//! ## The recent error each model is picked by
//!
//! Each window that teaches also scores the *published* value against the measured power,
//! before teaching; the mean absolute error is forgotten with `score_memory_s` (120 s) and
//! published with how many seconds of flight it rests on ([`Adapted::err_w`],
//! [`Adapted::evidence_s`]): the forecast picks its model by it (`energy::select`).
//!
//! ## A model's own regression
//!
//! A model linear in its own regressors (the fixed-wing model: ρV³, (n·m·g)²/(ρV),
//! m·g·v_z, 1; [`super::PowerModel::regressors`]) has those coefficients fitted too, the
//! same way (forgetting `regression_memory_s`, its published coefficients as a fixed prior,
//! bounded within ×¼…×4): [`regression`]. Its prediction, made before the window teaches
//! it and low-passed (`regression_smooth_s`), is what the affine fit below then corrects,
//! scores and publishes.
//!
//! ## Two fits per model: the published one and the reference
//!
//! - **adapted** (`memory_s`, default 30 s): published beside the raw estimate
//!   ([`crate::report::ModelEstimate::adapted_w`]) and used by the energy forecast.
//! - **reference** (`reference_memory_s`, default 900 s): what the `deviation_above` alert
//!   compares measured power with ([`crate::report::ModelEstimate::reference_w`]). It learns a new
//!   vehicle's level from its first minutes just as fast (RLS starts at its prior, so its
//!   first samples weigh as much as the adapted fit's), but once it has seen a few minutes a
//!   sudden fault (a failing motor, a damaged propeller drawing 30 % more) moves it by under
//!   1 % in 10 s, so the alert still fires: the fast fit alone would learn the fault away
//!   within a minute.
//!
//! ## What teaches
//!
//! A window teaches both fits only when
//! - measured power and the raw prediction are finite and positive, and measured power is
//!   at most [`MAX_POWER_W`];
//! - the motors turn: measured power ≥ `min_power_frac` × the vehicle's ideal hover power
//!   (momentum theory, `(m·g)^1.5 / √(2·ρ·A)`, from the profile and the mission payload). A
//!   vehicle on the ground draws a few watts for its electronics while the physics models
//!   still predict a hover, which says nothing about how it flies. (The samples carry no armed flag; the power threshold
//!   stands in for "disarmed".)
//! - the model says the window is inside what it was trained on
//!   ([`super::PowerModel::in_training_range`]): the LSTM refuses windows with an input more
//!   than 6 training standard deviations from the training mean.
//!
//! The correction is always *applied* (the last fitted a, b); only teaching is gated.
//!
//! ## Never worse than the model
//!
//! An affine fit of the last half-minute can extrapolate badly into the next regime (a model
//! whose output is flat in cruise and jumps in a turn). Each window, before it teaches, the
//! raw prediction and the published fit are both scored against the measured power, and the
//! mean absolute errors forgotten like the fit ([`ModelFit::err_w`]). The published value
//! is the fit while its error is no worse than the raw model's, else the raw prediction.

use serde::{Deserialize, Serialize};

pub mod regression;

/// Measured power above this is not a multirotor's (a corrupt current reading), W.
pub const MAX_POWER_W: f64 = 50_000.0;
/// Prior standard deviation of the gain a (dimensionless).
const SIGMA_A: f64 = 0.5;
/// Prior standard deviation of the offset b, W.
const SIGMA_B_W: f64 = 50.0;
/// Measurement noise the prior is scaled by, W.
const SIGMA_Y_W: f64 = 20.0;

/// The `[models.adapt]` table: online adaptation of every model to measured power.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct AdaptConfig {
    /// Adapt at all. Default true. Off: no `adapted_w`/`reference_w`, and the forecast and
    /// the deviation alert use the raw models, as before.
    pub enabled: bool,
    /// Memory of the published fit, s: a sample's weight falls by e every `memory_s`.
    /// Default 30 (follows a new vehicle within 30–60 s).
    pub memory_s: f64,
    /// Memory of the slow reference the `deviation_above` alert compares with, s. Default
    /// 900. Must be at least 5 × `memory_s`.
    pub reference_memory_s: f64,
    /// Windows teach only when measured power is at least this fraction of the vehicle's
    /// ideal hover power (the motors lift; on the ground a vehicle draws a few watts for its
    /// electronics, while the physics models still predict a hover). Default 0.3.
    pub min_power_frac: f64,
    /// Smallest gain a allowed. Default 0.2.
    pub gain_min: f64,
    /// Largest gain a allowed. Default 5.
    pub gain_max: f64,
    /// Largest offset |b| allowed, W. Default 1000.
    pub offset_max_w: f64,
    /// Memory of each model's recent error on this vehicle, s: the error of the published
    /// (adapted) value, forgotten by e every `score_memory_s`, that the forecast picks its
    /// model by (`[energy.select]`). Default 120 (longer than `memory_s`: the forecast
    /// model should be the best over the flight's regimes, not the last half-minute's).
    pub score_memory_s: f64,
    /// Memory of a model's own regression ([`regression`]: the fixed-wing model's four
    /// coefficients), s. Default 0.5: short, because the model's inputs miss part of what
    /// moves a plane's power (the propeller's efficiency with its thrust, the servos in
    /// gusts) and the coefficients follow it; at this memory the regression follows the
    /// measured power over about five windows, its prior and bounds holding what those do
    /// not decide. Chosen with `regression_smooth_s` on the simulated validation flights
    /// (`lab/scripts/measure-planes.sh OUT --set validation`, after `learn`, plane / quadplane:
    /// 3 s 6.9 / 6.9 %, 1.5 s 6.3 / 6.4 %, 1 s 6.1 / 6.1 %, 0.7 s 6.0 / 6.0 %, 0.5 s
    /// 6.0 / 5.9 %, 0.3 s 6.0 / 5.9 %, each with the 0.5 s low-pass; docs/src/vehicle-types.md).
    pub regression_memory_s: f64,
    /// Time constant of the low-pass on a model's own regression's prediction, s (an
    /// exponential moving average of the predictions, each made before its window taught):
    /// the estimate stands for the power over its window, not the newest sample's alone,
    /// whose airspeed and acceleration carry the sensors' noise. Default 0.5 (the age of a
    /// 1 s window's mean); 0: none. Chosen on the simulated validation flights (after
    /// `learn`, plane / quadplane: at a 3 s memory none 7.9 / 7.1 %, 0.5 s 6.9 / 6.9 %; at
    /// 1.5 s, 0.3 s 6.5 / 6.2 %, 0.5 s 6.3 / 6.4 %, 1 s 6.9 / 7.1 %; at 0.7 s, 0.5 s
    /// 6.0 / 6.0 %, 0.7 s 5.8 / 6.2 %; docs/src/vehicle-types.md).
    pub regression_smooth_s: f64,
}

impl Default for AdaptConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            memory_s: 30.0,
            reference_memory_s: 900.0,
            min_power_frac: 0.3,
            gain_min: 0.2,
            gain_max: 5.0,
            offset_max_w: 1000.0,
            score_memory_s: 120.0,
            regression_memory_s: 0.5,
            regression_smooth_s: 0.5,
        }
    }
}

impl AdaptConfig {
    /// Range checks; each message names the key (several errors: one per line).
    pub fn validate(&self) -> Result<(), String> {
        let mut errs = crate::validate::Errors::new();
        for (k, v, unit) in [
            ("memory_s", self.memory_s, "s"),
            ("reference_memory_s", self.reference_memory_s, "s"),
            ("gain_min", self.gain_min, ""),
            ("gain_max", self.gain_max, ""),
            ("offset_max_w", self.offset_max_w, "W"),
            ("score_memory_s", self.score_memory_s, "s"),
            ("regression_memory_s", self.regression_memory_s, "s"),
        ] {
            errs.range(
                &format!("models.adapt.{k}"),
                v,
                crate::validate::above(0.0),
                unit,
            );
        }
        if self.reference_memory_s < 5.0 * self.memory_s {
            errs.push(format!(
                "models.adapt.reference_memory_s = {}: must be ≥ 5 × memory_s = {} (the deviation alert's reference must adapt much slower than the forecast)",
                self.reference_memory_s,
                5.0 * self.memory_s
            ));
        }
        errs.range(
            "models.adapt.regression_smooth_s",
            self.regression_smooth_s,
            0.0..=60.0,
            "s",
        );
        errs.range(
            "models.adapt.min_power_frac",
            self.min_power_frac,
            0.0..1.0,
            "",
        );
        if self.gain_min > 1.0 || self.gain_max < 1.0 {
            errs.push(format!(
                "models.adapt.gain_min = {}, gain_max = {}: the range must contain 1 (the model as it is)",
                self.gain_min, self.gain_max
            ));
        }
        errs.into_result()
    }
}

/// One affine fit: θ = (a, b), the forgotten sums it is solved from, how many windows
/// taught it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AffineFit {
    /// Gain a (dimensionless).
    pub a: f64,
    /// Offset b, W.
    pub b_w: f64,
    /// Σ λᵏ·φφᵀ, upper triangle (φ = [P_model, 1]): the information the data gave, W², W, 1.
    pub info: [f64; 3],
    /// Σ λᵏ·φ·y: W², W.
    pub rhs: [f64; 2],
    /// Windows that taught this fit.
    pub taught: u64,
}

impl Default for AffineFit {
    fn default() -> Self {
        Self {
            a: 1.0,
            b_w: 0.0,
            info: [0.0; 3],
            rhs: [0.0; 2],
            taught: 0,
        }
    }
}

/// The prior's information diag(σ_y²/σ_a², σ_y²/σ_b²): what (1, 0) weighs against data.
const PRIOR_INFO: [f64; 2] = [
    SIGMA_Y_W * SIGMA_Y_W / (SIGMA_A * SIGMA_A),
    SIGMA_Y_W * SIGMA_Y_W / (SIGMA_B_W * SIGMA_B_W),
];

impl AffineFit {
    /// The corrected power for a raw prediction, W.
    pub fn apply(&self, p_model_w: f64) -> f64 {
        self.a * p_model_w + self.b_w
    }

    /// One step: forget by `lambda`, add the window, solve, bound (module docs).
    fn teach(&mut self, x: f64, y: f64, lambda: f64, cfg: &AdaptConfig) {
        let [s00, s01, s11] = self.info;
        let [r0, r1] = self.rhs;
        let info = [lambda * s00 + x * x, lambda * s01 + x, lambda * s11 + 1.0];
        let rhs = [lambda * r0 + x * y, lambda * r1 + y];
        // (S + R₀)·θ = r + R₀·θ₀ with θ₀ = (1, 0).
        let (m00, m01, m11) = (info[0] + PRIOR_INFO[0], info[1], info[2] + PRIOR_INFO[1]);
        let (v0, v1) = (rhs[0] + PRIOR_INFO[0], rhs[1]);
        let det = m00 * m11 - m01 * m01;
        let (a, b) = ((m11 * v0 - m01 * v1) / det, (m00 * v1 - m01 * v0) / det);
        if !(det > 0.0
            && a.is_finite()
            && b.is_finite()
            && info.iter().chain(&rhs).all(|v| v.is_finite()))
        {
            return;
        }
        let (a, b) = box_solve(
            [m00, m01, m11],
            [v0, v1],
            (a, b),
            (cfg.gain_min, cfg.gain_max),
            cfg.offset_max_w,
        );
        self.info = info;
        self.rhs = rhs;
        self.a = a;
        self.b_w = b;
        self.taught += 1;
    }
}

/// The minimum of `θᵀMθ − 2vᵀθ` (M = [[m00, m01], [m01, m11]] positive definite) over the
/// box a ∈ `gain`, |b| ≤ `b_max`, given the unconstrained minimum `free`. Clamping a and b
/// each on its own is not the constrained fit: a gain held at its bound needs the offset
/// that fits *with* it (a model whose output falls while the power rises, as Tseng-Solo's
/// in a climb, drove the gain to its bound and left the offset of a gain 3× larger: a
/// 1,000 W estimate of a 600 W climb). Inside the box the free minimum is the answer; else
/// the minimum lies on an edge, where it is a one-dimensional fit clamped to the edge.
fn box_solve(
    m: [f64; 3],
    v: [f64; 2],
    free: (f64, f64),
    gain: (f64, f64),
    b_max: f64,
) -> (f64, f64) {
    let [m00, m01, m11] = m;
    let inside = |(a, b): (f64, f64)| (gain.0..=gain.1).contains(&a) && b.abs() <= b_max;
    if inside(free) {
        return free;
    }
    let cost = |(a, b): (f64, f64)| {
        m00 * a * a + 2.0 * m01 * a * b + m11 * b * b - 2.0 * (v[0] * a + v[1] * b)
    };
    let on_a = |a: f64| (a, ((v[1] - m01 * a) / m11).clamp(-b_max, b_max));
    let on_b = |b: f64| (((v[0] - m01 * b) / m00).clamp(gain.0, gain.1), b);
    [on_a(gain.0), on_a(gain.1), on_b(-b_max), on_b(b_max)]
        .into_iter()
        .filter(|p| p.0.is_finite() && p.1.is_finite())
        .min_by(|p, q| cost(*p).total_cmp(&cost(*q)))
        .unwrap_or((free.0.clamp(gain.0, gain.1), free.1.clamp(-b_max, b_max)))
}

/// A model's two fits (module docs): the published one and the slow reference.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct ModelFit {
    /// Published fit (`memory_s`).
    pub adapted: AffineFit,
    /// Slow reference for the deviation alert (`reference_memory_s`).
    pub reference: AffineFit,
    /// Recent mean absolute error of the raw prediction and of the published fit, each
    /// scored before the window taught (out of sample), W, forgotten like the published
    /// fit: the fit is published only while it beats the raw model (module docs).
    #[serde(default)]
    pub err_w: [f64; 2],
}

/// What a model's estimate becomes after adaptation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Adapted {
    /// The published fit applied to the raw prediction, W.
    pub adapted_w: f32,
    /// The slow reference applied to the raw prediction, W.
    pub reference_w: f32,
    /// Whether this window taught the fits.
    pub taught: bool,
    /// The published value's recent mean absolute error on this vehicle, W, scored before
    /// the window taught (out of sample), forgotten with `score_memory_s` and corrected for
    /// the start-up bias of a forgotten mean (divided by 1 − λⁿ after n scored windows).
    /// None before the first scored window.
    pub err_w: Option<f32>,
    /// Seconds of flight that scored this model since this run started (windows that
    /// taught × the window step): how much evidence `err_w` rests on.
    pub evidence_s: f32,
}

/// Every model's fits, by model name (in the ensemble's order).
#[derive(Clone)]
pub struct Adaptation {
    cfg: AdaptConfig,
    lambda: f64,
    lambda_ref: f64,
    /// Forgetting factor of a model's own regression (`regression_memory_s`).
    lambda_regression: f64,
    /// Weight of the previous smoothed value in the low-pass on a regression's prediction
    /// (`regression_smooth_s`; 0: none).
    lambda_smooth: f64,
    /// Below this measured power nothing teaches (motors off), W.
    min_teach_w: f64,
    fits: Vec<(String, ModelFit)>,
    /// Window step, s.
    dt_s: f64,
    /// Forgetting factor of the published value's error (`score_memory_s`).
    lambda_score: f64,
    /// Per model: windows that scored it since this run started, the forgotten mean of its
    /// published value's absolute error, W, and λⁿ (the evidence behind its recent error; a
    /// warm start restores fits, not evidence).
    scored: Vec<(u64, f64, f64)>,
    /// Per model, for the models linear in their own regressors
    /// ([`super::PowerModel::regressors`]): that regression fitted online ([`regression`]).
    regressions: Vec<Option<regression::RegressionFit>>,
}

impl Adaptation {
    /// Fits at (1, 0) for these models; windows come every `dt_s` seconds, and the vehicle's
    /// ideal hover power is `hover_w` (module docs).
    pub fn new(cfg: &AdaptConfig, names: &[String], dt_s: f64, hover_w: f64) -> Self {
        let lambda_of = |memory_s: f64| (-dt_s / memory_s).exp().clamp(0.5, 1.0);
        Self {
            cfg: cfg.clone(),
            lambda: lambda_of(cfg.memory_s),
            lambda_ref: lambda_of(cfg.reference_memory_s),
            lambda_regression: lambda_of(cfg.regression_memory_s),
            lambda_smooth: if cfg.regression_smooth_s > 0.0 {
                (-dt_s / cfg.regression_smooth_s).exp().clamp(0.0, 0.99)
            } else {
                0.0
            },
            min_teach_w: (cfg.min_power_frac * hover_w).max(0.0),
            fits: names
                .iter()
                .map(|n| (n.clone(), ModelFit::default()))
                .collect(),
            dt_s,
            lambda_score: lambda_of(cfg.score_memory_s),
            scored: vec![(0, 0.0, 1.0); names.len()],
            regressions: Vec::new(),
        }
    }

    /// Model `i`'s own regression on this vehicle, started at its coefficients `theta0`:
    /// its prediction for regressors `phi`, W, made before this window teaches it, low-passed
    /// (`regression_smooth_s`: λ·previous + (1 − λ)·this); then,
    /// when `teach` and the measured power is finite and at most [`MAX_POWER_W`], taught
    /// with it (forgotten like the published fit, `memory_s`). The caller decides `teach`
    /// as for [`Adaptation::step`] (the motors turn, the window in range).
    pub fn regress(
        &mut self,
        i: usize,
        phi: &[f64; regression::N],
        theta0: [f64; regression::N],
        measured_w: Option<f32>,
        teach: bool,
    ) -> f64 {
        if self.regressions.len() <= i {
            self.regressions.resize(i + 1, None);
        }
        let fit = self.regressions[i].get_or_insert_with(|| regression::RegressionFit::new(theta0));
        let out = fit.smooth(fit.predict(phi), self.lambda_smooth);
        if let Some(y) = measured_w.map(f64::from) {
            if teach && y.is_finite() && y > 0.0 && y <= MAX_POWER_W {
                fit.teach(phi, y, self.lambda_regression);
            }
        }
        out
    }

    /// Measured power below which nothing teaches, W.
    pub fn min_teach_w(&self) -> f64 {
        self.min_teach_w
    }

    /// Model `i`'s raw prediction `p_model_w` corrected, and (when `measured_w` qualifies and
    /// the model says the window is `in_range`) both fits taught with it. The correction is
    /// the one *before* this window taught: the published estimate never saw its own answer.
    pub fn step(
        &mut self,
        i: usize,
        p_model_w: f32,
        measured_w: Option<f32>,
        in_range: bool,
    ) -> Option<Adapted> {
        self.step_from(i, p_model_w, measured_w, in_range, None)
    }

    /// [`Adaptation::step`] with the model's own teaching threshold, W, where it has one
    /// ([`super::PowerModel::min_teach_w`]: a plane's cruise is below a rotor's hover).
    pub fn step_from(
        &mut self,
        i: usize,
        p_model_w: f32,
        measured_w: Option<f32>,
        in_range: bool,
        min_teach_w: Option<f64>,
    ) -> Option<Adapted> {
        let (lambda, lambda_ref, lambda_score, min_w, dt_s) = (
            self.lambda,
            self.lambda_ref,
            self.lambda_score,
            min_teach_w.unwrap_or(self.min_teach_w),
            self.dt_s,
        );
        let cfg = &self.cfg;
        let fit = &mut self.fits.get_mut(i)?.1;
        let (scored, score, decay) = self.scored.get_mut(i)?;
        let x = f64::from(p_model_w);
        if !x.is_finite() {
            return None;
        }
        let corrected = fit.adapted.apply(x).max(0.0);
        // Published: the fit while its recent out-of-sample error is no worse than the raw
        // model's, else the raw model (a fit that extrapolates badly never makes it worse).
        let [err_raw, err_fit] = fit.err_w;
        let published = if err_fit <= err_raw {
            corrected
        } else {
            x.max(0.0)
        };
        // A forgotten mean started at 0 is low by the factor 1 − λⁿ: undo it.
        let recent =
            |n: u64, err: f64, decay: f64| (n > 0).then(|| (err / (1.0 - decay).max(1e-9)) as f32);
        let mut out = Adapted {
            adapted_w: published as f32,
            reference_w: fit.reference.apply(x).max(0.0) as f32,
            taught: false,
            err_w: recent(*scored, *score, *decay),
            evidence_s: (*scored as f64 * dt_s) as f32,
        };
        let y = measured_w
            .map(f64::from)
            .filter(|y| y.is_finite() && *y > 0.0 && *y <= MAX_POWER_W);
        let Some(y) = y else { return Some(out) };
        if !in_range || x <= 0.0 || y < min_w {
            return Some(out);
        }
        fit.err_w = [
            lambda * err_raw + (1.0 - lambda) * (x - y).abs(),
            lambda * err_fit + (1.0 - lambda) * (corrected - y).abs(),
        ];
        *score = lambda_score * *score + (1.0 - lambda_score) * (published - y).abs();
        *scored += 1;
        *decay *= lambda_score;
        fit.adapted.teach(x, y, lambda, cfg);
        fit.reference.teach(x, y, lambda_ref, cfg);
        out.taught = true;
        out.err_w = recent(*scored, *score, *decay);
        out.evidence_s = (*scored as f64 * dt_s) as f32;
        Some(out)
    }

    /// The fits, by model name: what the vehicle store keeps between flights.
    pub fn fits(&self) -> &[(String, ModelFit)] {
        &self.fits
    }

    /// Start from fits learned before (a previous flight of the same vehicle): both fits
    /// start from the stored *reference*, the long-memory fit over the whole flight, not from
    /// the published fit, which at a flight's end has learned only its last half-minute
    /// (descent, landing: a poor guess of the next take-off). Models not in
    /// `learned` keep their current fit; learned fits of models not running are ignored. A
    /// fit outside the configured bounds or with broken sums is ignored. Returns how
    /// many fits were taken.
    pub fn restore(&mut self, learned: &[(String, ModelFit)]) -> usize {
        let mut n = 0;
        let cfg = &self.cfg;
        for (name, fit) in &mut self.fits {
            if let Some((_, l)) = learned.iter().find(|(ln, _)| ln == name) {
                if [l.adapted, l.reference].iter().all(|f| fit_ok(cfg, f)) {
                    *fit = ModelFit {
                        adapted: l.reference,
                        reference: l.reference,
                        err_w: [0.0; 2],
                    };
                    n += 1;
                }
            }
        }
        n
    }

    /// Forget everything learned: every fit back at (1, 0) (a new vehicle's first flight).
    pub fn reset(&mut self) {
        for (_, fit) in &mut self.fits {
            *fit = ModelFit::default();
        }
        self.scored.iter_mut().for_each(|n| *n = (0, 0.0, 1.0));
    }
}

/// Whether a stored fit lies inside the configured bounds with sane sums.
fn fit_ok(cfg: &AdaptConfig, f: &AffineFit) -> bool {
    (cfg.gain_min..=cfg.gain_max).contains(&f.a)
        && f.b_w.abs() <= cfg.offset_max_w
        && f.info.iter().chain(&f.rhs).all(|v| v.is_finite())
        && f.info[0] >= 0.0
        && f.info[2] >= 0.0
}

/// Ideal (momentum-theory) hover power of a vehicle of mass `mass_kg` with total rotor
/// disk area `disk_area_m2`: `(m·g)^1.5 / √(2·ρ·A)`, W. Real hover power is this over the
/// figure of merit and the motor/ESC efficiency (typically 2–3× more).
pub fn ideal_hover_w(mass_kg: f64, g_m_s2: f64, rho_kg_m3: f64, disk_area_m2: f64) -> f64 {
    let thrust_n = mass_kg * g_m_s2;
    thrust_n.powf(1.5) / (2.0 * rho_kg_m3 * disk_area_m2).sqrt()
}

#[cfg(test)]
mod tests;
