//! The live chain after the windows, run flat out over one flight: the one driver every
//! offline command that needs estimates or energy goes through, so what `eval` and `train`
//! score is what the live chain produces.
//!
//! ```text
//! windows ──▶ model::Ensemble::estimate ──Estimate──▶ energy::EnergyTracker::update
//!                                                   ──▶ alert::AlertEngine::evaluate ──▶ Report
//! ```
//!
//! [`Chain::run`] hands back, per window, the [`Report`] a sink would get live: the models
//! run the flight's windows as one batch (as a flat-out replay batches what queues up), and
//! every flight gets a fresh energy tracker and alert engine (a flight starts on a charged
//! battery). Beside each report it keeps what scoring needs and the report does not say:
//!
//! - **each model's instant**: a model with target lag L estimates the sample L steps before
//!   the window's newest ([`crate::model::PowerModel::target_lag`]), so it is scored against
//!   the power measured then;
//! - **each model's energy**: per model, a second [`EnergyTracker`] (the live code, the
//!   configuration's `[energy]`) fed that model's estimates alone, at their instants, with
//!   the measured power withheld: the energy used the live chain would report, Wh, had the
//!   power sensor been absent and this model integrated instead.
//!
//! - **each model adapted**: when the ensemble adapts to measured power
//!   ([`crate::model::adapt`]), every model also appears as `<model>~`, its adapted estimate,
//!   scored and integrated like the raw ones. Each flight starts from the models as they are
//!   ([`Chain::run`] resets what the previous flight taught), as a new vehicle's first flight
//!   would, unless [`Chain::keep_learning`] says otherwise.
//!
//! [`Chain::run_flight`] lines the steps up by instant ([`FlightSeries`]) and
//! [`FlightSeries::scores`] scores them ([`crate::offline::metrics`]).

use crate::alert::AlertEngine;
use crate::config::Config;
use crate::energy::EnergyTracker;
use crate::features::Sample;
use crate::model::Ensemble;
use crate::offline::data::FlightWindows;
use crate::offline::metrics::{self, Aligned, Scores};
use crate::report::Report;
use crate::report::{Estimate, ModelEstimate};
use crate::telemetry::window::Window;

/// One window's pass through the chain.
#[derive(Debug, Clone)]
pub struct Step {
    /// What the energy + alerts stage hands the sinks for this window, as live.
    pub report: Report,
    /// Per model, in the ensemble's order: time of the sample its estimate is for, s.
    pub for_t_s: Vec<f64>,
    /// Per model: energy used since the flight's start had the tracker integrated this
    /// model's estimates instead of the measured power, Wh (up to its instant).
    pub model_energy_wh: Vec<f64>,
}

/// Models, energy tracker and alert rules as a configuration sets them up live.
pub struct Chain {
    ensemble: Ensemble,
    /// The models' names, then (adapting) each as `<model>~`.
    names: Vec<String>,
    target_lags: Vec<usize>,
    config: Config,
    /// Whether a flight starts from what earlier flights taught the adaptation.
    keep_learning: bool,
}

impl Chain {
    /// A chain running these models, with the configuration's `[energy]` and `[[alerts]]`
    /// (checked here, so a bad table fails before any flight is loaded).
    pub fn new(cfg: &Config, ensemble: Ensemble) -> anyhow::Result<Self> {
        EnergyTracker::new(&cfg.energy, cfg.mission.speed_m_s)?;
        AlertEngine::new(&cfg.alerts)?;
        let (mut names, mut target_lags) = (ensemble.names(), ensemble.target_lags());
        if ensemble.adaptation(Default::default()).is_some() {
            names.extend(ensemble.names().iter().map(|n| format!("{n}~")));
            target_lags.extend(ensemble.target_lags());
        }
        Ok(Self {
            names,
            target_lags,
            ensemble,
            config: cfg.clone(),
            keep_learning: false,
        })
    }

    /// Let each flight start from what the flights before it taught the adaptation (the
    /// same vehicle flying again), instead of from the models as they are.
    pub fn keep_learning(mut self, keep: bool) -> Self {
        self.keep_learning = keep;
        self
    }

    /// The models and their adaptation state.
    pub fn ensemble_mut(&mut self) -> &mut Ensemble {
        &mut self.ensemble
    }

    /// The chain the configuration runs live ([`crate::model::build_ensemble`]'s models).
    pub fn from_config(cfg: &Config) -> anyhow::Result<Self> {
        Self::new(
            cfg,
            crate::model::build_ensemble(
                &cfg.models,
                cfg.vehicle.as_deref(),
                &cfg.telemetry,
                cfg.mission.payload_g,
            )?,
        )
    }

    /// The models' names, in order.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Run one flight's windows (oldest first) through models, energy and alerts.
    pub fn run(&mut self, windows: &[Window]) -> anyhow::Result<Vec<Step>> {
        let tracker = || EnergyTracker::new(&self.config.energy, self.config.mission.speed_m_s);
        let mut energy = tracker()?;
        let mut alerts = AlertEngine::new(&self.config.alerts)?;
        // The per-model trackers keep books; what there is to say of the pack (its cells,
        // its start state) the live tracker says once, not once more for each model.
        let mut model_energy = self
            .names
            .iter()
            .map(|_| tracker().map(EnergyTracker::quiet))
            .collect::<anyhow::Result<Vec<_>>>()?;
        if !self.keep_learning {
            if let Some(ad) = self.ensemble.adaptation_mut(Default::default()) {
                ad.reset();
            }
        }
        let estimates = self.ensemble.estimate(windows);
        let mut steps = Vec::with_capacity(windows.len());
        for (w, est) in windows.iter().zip(estimates) {
            let n = self.names.len();
            let (mut for_t_s, mut model_energy_wh) = (Vec::with_capacity(n), Vec::with_capacity(n));
            // The raw estimates, then (adapting) the adapted ones as their own models.
            let adapted = est.models.iter().map(|m| {
                ModelEstimate::new(
                    format!("{}~", m.name),
                    m.adapted_w.unwrap_or(f32::NAN),
                    None,
                )
            });
            let alone_models = est
                .models
                .iter()
                .map(|m| ModelEstimate {
                    adapted_w: None,
                    reference_w: None,
                    adapted_err: None,
                    ..m.clone()
                })
                .chain(adapted);
            for ((m, lag), tracker) in alone_models.zip(&self.target_lags).zip(&mut model_energy) {
                let at = w.back(*lag);
                let alone = Estimate {
                    t_s: at.t_s,
                    sample: Sample {
                        measured_w: None,
                        ..at.clone()
                    },
                    models: vec![m],
                    arrived: None,
                };
                model_energy_wh.push(tracker.update(&alone).energy_used_wh);
                for_t_s.push(at.t_s);
            }
            // The live energy + alerts step itself (a data-set flight has no system id: 1).
            let report = crate::pipeline::account(
                &mut energy,
                &mut alerts,
                est,
                crate::report::VehicleId::single(1),
            );
            steps.push(Step {
                report,
                for_t_s,
                model_energy_wh,
            });
        }
        Ok(steps)
    }

    /// [`Chain::run`] over a data-set flight, lined up for scoring.
    pub fn run_flight(&mut self, f: &FlightWindows) -> anyhow::Result<FlightSeries> {
        let steps = self.run(&f.windows)?;
        Ok(FlightSeries::from_steps(
            f.flight,
            &self.names,
            &self.target_lags,
            &steps,
        ))
    }
}

/// One flight through the chain, at every window with a measured power: the measured
/// power and energy there, and per model the estimate *for that instant* (NaN where a
/// model has none: a lagged model near the flight's end, or across a telemetry gap).
#[derive(Debug, Clone)]
pub struct FlightSeries {
    /// Flight number.
    pub flight: u32,
    /// Model names, in the chain's order.
    pub names: Vec<String>,
    /// Window times, s.
    pub t_s: Vec<f64>,
    /// Measured power, W.
    pub measured_w: Vec<f64>,
    /// Battery voltage, V (NaN where absent).
    pub voltage_v: Vec<f64>,
    /// Energy used since the flight's start as the live tracker reports it, Wh.
    pub measured_wh: Vec<f64>,
    /// Per model: its estimate, W.
    pub pred_w: Vec<Vec<f64>>,
    /// Per model: its uncertainty band (low, high), W, where it gives one.
    pub band_w: Vec<Vec<Option<(f64, f64)>>>,
    /// Per model: energy used had it been integrated instead of the measured power, Wh.
    pub pred_wh: Vec<Vec<f64>>,
    /// Alerts the configured rules raised over the flight.
    pub alerts_raised: usize,
    /// Measured power above which a window is in flight for the scores, W
    /// ([`metrics::IN_FLIGHT_W`]; `learn` sets the vehicle's, [`metrics::in_flight_w_for`]).
    pub in_flight_w: f64,
}

impl FlightSeries {
    /// Line up `steps` (from models named `names` with these target lags): a model with
    /// lag L is read from step i + L, whose estimate is for step i's instant when no gap
    /// lies between.
    pub fn from_steps(
        flight: u32,
        names: &[String],
        target_lags: &[usize],
        steps: &[Step],
    ) -> Self {
        let keep: Vec<usize> = (0..steps.len())
            .filter(|&i| steps[i].report.estimate.sample.measured_w.is_some())
            .collect();
        let sample = |i: usize| &steps[i].report.estimate.sample;
        let mut s = FlightSeries {
            flight,
            names: names.to_vec(),
            t_s: keep.iter().map(|&i| sample(i).t_s).collect(),
            measured_w: keep
                .iter()
                .map(|&i| sample(i).measured_w.map_or(f64::NAN, f64::from))
                .collect(),
            voltage_v: keep
                .iter()
                .map(|&i| sample(i).voltage_v.map_or(f64::NAN, f64::from))
                .collect(),
            measured_wh: keep
                .iter()
                .map(|&i| steps[i].report.energy.energy_used_wh)
                .collect(),
            pred_w: Vec::with_capacity(names.len()),
            band_w: Vec::with_capacity(names.len()),
            pred_wh: Vec::with_capacity(names.len()),
            alerts_raised: steps
                .iter()
                .flat_map(|s| &s.report.alerts)
                .filter(|a| a.state == crate::report::AlertState::Raised)
                .count(),
            in_flight_w: metrics::IN_FLIGHT_W,
        };
        for (j, &lag) in target_lags.iter().enumerate().take(names.len()) {
            // Column j is model j's raw estimate, or past the models, model j − n's adapted one.
            let at = |i: usize| {
                let st = steps.get(i + lag)?;
                let models = &st.report.estimate.models;
                let (m, adapted) = match models.get(j) {
                    Some(m) => (m, false),
                    None => (models.get(j - models.len())?, true),
                };
                let power_w = if adapted { m.adapted_w? } else { m.power_w };
                let band_w = if adapted { None } else { m.band_w };
                (st.for_t_s.get(j) == Some(&sample(i).t_s)).then_some((
                    power_w,
                    band_w,
                    st.model_energy_wh[j],
                ))
            };
            s.pred_w.push(
                keep.iter()
                    .map(|&i| at(i).map_or(f64::NAN, |(p, _, _)| f64::from(p)))
                    .collect(),
            );
            s.band_w.push(
                keep.iter()
                    .map(|&i| {
                        at(i)
                            .and_then(|(_, b, _)| b)
                            .map(|(lo, hi)| (f64::from(lo), f64::from(hi)))
                    })
                    .collect(),
            );
            s.pred_wh.push(
                keep.iter()
                    .map(|&i| at(i).map_or(f64::NAN, |(_, _, wh)| wh))
                    .collect(),
            );
        }
        s
    }

    /// Model `j`'s series, for [`metrics::score_over`].
    pub fn aligned(&self, j: usize) -> Aligned<'_> {
        Aligned {
            measured_w: &self.measured_w,
            pred_w: &self.pred_w[j],
            measured_wh: &self.measured_wh,
            pred_wh: &self.pred_wh[j],
            in_flight_w: self.in_flight_w,
        }
    }

    /// Model `j`'s band misses: for each window with a measured power and a band, how far
    /// the power lies outside it, `max(low − y, y − high)` (negative inside), W.
    pub fn band_excess(&self, j: usize) -> impl Iterator<Item = f64> + '_ {
        self.measured_w
            .iter()
            .zip(self.band_w.get(j).into_iter().flatten())
            .filter_map(|(y, b)| b.map(|(lo, hi)| (lo - y).max(y - hi)))
            .filter(|e| e.is_finite())
    }

    /// Every model's scores (in order; `None` where nothing was in flight), in flight only
    /// or over every window.
    pub fn scores(&self, all_windows: bool) -> Vec<Option<Scores>> {
        (0..self.pred_w.len())
            .map(|j| metrics::score_over(&self.aligned(j), all_windows))
            .collect()
    }
}

/// The models `eval` and `plan` score: the configured set, then the calibrated physics models.
pub fn eval_models(
    cfg: &Config,
    calibrated: Option<&crate::model::profile::VehicleProfile>,
) -> anyhow::Result<Vec<Box<dyn crate::model::PowerModel>>> {
    let mut models =
        crate::model::build_models(&cfg.models, cfg.vehicle.as_deref(), &cfg.telemetry)?;
    if let Some(cal) = calibrated {
        models.extend(crate::model::physics::models(cal));
    }
    Ok(models)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{PowerModel, Prediction};

    /// A model that knows the measured power `lag` samples back, times `gain`: perfect
    /// when aligned and `gain` is 1.
    struct Oracle {
        name: &'static str,
        lag: usize,
        gain: f32,
    }
    impl PowerModel for Oracle {
        fn name(&self) -> &str {
            self.name
        }
        fn predict(&mut self, windows: &[Window], out: &mut Vec<Prediction>) {
            out.clear();
            out.extend(windows.iter().map(|w| Prediction {
                power_w: self.gain * w.back(self.lag).measured_w.unwrap_or(f32::NAN),
                band_w: None,
            }));
        }
        fn target_lag(&self) -> usize {
            self.lag
        }
    }

    /// 6 s at 10 Hz: 1 s on the ground at 20 W, then a varying 300–400 W.
    fn flight() -> FlightWindows {
        let sample = |i: usize| {
            let p = if i < 10 {
                20.0
            } else {
                300.0 + (i * i % 97) as f32
            };
            Sample::new(i as f64 * 0.1, [0.0; crate::features::N_FEATURES], Some(p))
        };
        let all: Vec<Sample> = (0..60).map(sample).collect();
        let windows = (9..60)
            .map(|e| Window {
                samples: all[e - 9..=e].to_vec(),
                arrived: None,
            })
            .collect();
        FlightWindows {
            flight: 1,
            route: "R1".into(),
            windows,
        }
    }

    fn chain(cfg: &Config, models: Vec<Box<dyn PowerModel>>) -> Chain {
        Chain::new(cfg, Ensemble::new(models)).unwrap()
    }

    #[test]
    fn a_lagged_model_is_scored_at_its_own_instant() {
        let models: Vec<Box<dyn PowerModel>> = vec![
            Box::new(Oracle {
                name: "now",
                lag: 0,
                gain: 1.0,
            }),
            Box::new(Oracle {
                name: "lagged",
                lag: 3,
                gain: 1.0,
            }),
        ];
        let s = chain(&Config::default(), models)
            .run_flight(&flight())
            .unwrap();
        for pred in &s.pred_w {
            let scored: Vec<_> = pred
                .iter()
                .zip(&s.measured_w)
                .filter(|(p, _)| p.is_finite())
                .collect();
            assert!(scored.len() >= s.measured_w.len() - 3);
            assert!(
                scored.iter().all(|(p, m)| p == m),
                "a perfect model scored imperfectly"
            );
        }
        // The last three windows have no lagged estimate yet (as live).
        assert!(s.pred_w[1].iter().rev().take(3).all(|p| p.is_nan()));
    }

    #[test]
    fn energy_is_scored_on_what_the_tracker_integrates() {
        let models: Vec<Box<dyn PowerModel>> = vec![
            Box::new(Oracle {
                name: "exact",
                lag: 2,
                gain: 1.0,
            }),
            Box::new(Oracle {
                name: "high",
                lag: 0,
                gain: 1.1,
            }),
        ];
        let f = flight();
        let mut c = chain(&Config::default(), models);
        let steps = c.run(&f.windows).unwrap();
        // The live tracker integrates measured power: 20 W for 0 s (the first window is at
        // 0.9 s, on the ground), then the trapezoids.
        let last = &steps.last().unwrap().report.energy;
        assert_eq!(last.power_source, "measured");
        let t: Vec<f64> = f.windows.iter().map(|w| w.t_s()).collect();
        let p: Vec<f64> = f
            .windows
            .iter()
            .map(|w| f64::from(w.last().measured_w.unwrap()))
            .collect();
        let trapezoids: f64 = (1..t.len())
            .map(|i| 0.5 * (t[i] - t[i - 1]) * (p[i] + p[i - 1]))
            .sum::<f64>()
            / 3600.0;
        assert!(
            (last.energy_used_wh - trapezoids).abs() < 1e-9,
            "{} vs {trapezoids}",
            last.energy_used_wh
        );
        let s = FlightSeries::from_steps(f.flight, c.names(), &[2, 0], &steps);
        let scores = s.scores(false);
        let (exact, high) = (scores[0].unwrap(), scores[1].unwrap());
        assert!(
            exact.mae_w < 1e-3 && exact.energy_err_pct < 1e-6,
            "{exact:?}"
        );
        // 10 % high at every instant: 10 % too much energy, in flight and overall.
        assert!((high.energy_err_pct - 10.0).abs() < 1e-4, "{high:?}");
        assert!((s.scores(true)[1].unwrap().energy_err_pct - 10.0).abs() < 1e-4);
        // In flight skips the ground second; every window includes it.
        assert!(s.scores(true)[1].unwrap().windows > high.windows);
    }

    #[test]
    fn the_configured_alert_rules_run() {
        let cfg: Config = toml::from_str(
            r#"
            [[alerts]]
            name = "hot"
            kind = "power_above"
            above_w = 350
            clear_w = 340
            "#,
        )
        .unwrap();
        let models: Vec<Box<dyn PowerModel>> = vec![Box::new(Oracle {
            name: "exact",
            lag: 0,
            gain: 1.0,
        })];
        let mut c = chain(&cfg, models);
        let f = flight();
        let steps = c.run(&f.windows).unwrap();
        let raised = steps
            .iter()
            .flat_map(|s| &s.report.alerts)
            .filter(|a| a.rule == "hot")
            .count();
        assert!(raised > 0, "power crosses 350 W and the rule never fired");
        assert_eq!(
            c.run_flight(&f).unwrap().alerts_raised,
            steps
                .iter()
                .flat_map(|s| &s.report.alerts)
                .filter(|a| a.state == crate::report::AlertState::Raised)
                .count()
        );
    }
}
