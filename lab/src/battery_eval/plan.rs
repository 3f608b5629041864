//! The pre-flight power profile of a route flight as `plan-eval` builds it: the flight's plan
//! ([`crate::route`]), flown by the trajectory model in the pre-take-off ground
//! wind, its power forecast by the calibration `plan-eval` fits on the training flights
//! (each member with its scale from the training flights before this one, as `plan-eval`
//! scores them). This is what a planner has before take-off; `battery-eval` flies the pack
//! along it from the flight's start resting voltage.

use std::collections::HashMap;

use crate::forecast_fit::{fit, prepare, rolling_scales, Fitted, Prepared};
use crate::route::geometry_for;
use dronewatt::config::Config;
use dronewatt::mission::forecast::{forecast, Calibration};
use dronewatt::offline::data::TEST_FLIGHTS;
use dronewatt::source::logs::dataset::Flight;

/// One flight's planned power: P50 power a trajectory sample (W) at `dt_s` steps from the
/// take-off command.
#[derive(Debug, Clone)]
pub struct PlanPower {
    pub dt_s: f64,
    pub power_w: Vec<f64>,
    /// Which flight's track gave the waypoints.
    pub geometry_from: u32,
    /// The forecast's energy, Wh.
    pub energy_wh: f64,
    /// Live at half the airborne time, as `plan-eval` does it: the trajectory sample the
    /// vehicle was found at, and the factor on the rest's power from the energy measured
    /// so far against the forecast's (1 + live weight × (ratio − 1), ratio within 0.8–1.25).
    pub live_k: usize,
    pub live_scale: f64,
}

/// Whether `plan-eval` plans a flight: the route flights (`R…`).
pub fn is_route(f: &Flight) -> bool {
    f.route.starts_with('R')
}

/// The planned power of every route flight in `flights`, fitted on the training route flights
/// (the calibrated profile `calibrated`, default configuration, ground wind: `plan-eval`'s
/// defaults). A flight that cannot be planned is left out with a warning.
pub fn plan_powers(
    flights: &[Flight],
    calibrated: &dronewatt::offline::args::CalibratedArg,
) -> anyhow::Result<HashMap<u32, PlanPower>> {
    let cfg = Config::default();
    let mut models = dronewatt::offline::plan::models_for(&cfg, calibrated)?;
    let all_train: Vec<&Flight> = flights
        .iter()
        .filter(|f| is_route(f) && !TEST_FLIGHTS.contains(&f.flight))
        .collect();
    let mut prepared: Vec<Prepared> = Vec::new();
    for f in flights.iter().filter(|f| is_route(f)) {
        match prepare(f, geometry_for(f, &all_train), true, &cfg, &mut models) {
            Ok(p) => prepared.push(p),
            Err(e) => tracing::warn!("flight {}: no plan ({e:#})", f.flight),
        }
    }
    let (train, test): (Vec<Prepared>, Vec<Prepared>) = prepared
        .into_iter()
        .partition(|p| !TEST_FLIGHTS.contains(&p.flight));
    if train.is_empty() {
        anyhow::bail!("no training route flight to fit the mission forecast on");
    }
    let Fitted { cal, .. } = fit(&train);
    let mut out = HashMap::new();
    for p in train.iter().chain(&test) {
        let scales = rolling_scales(&train, &cal, p.flight);
        let n = p.traj.samples.len();
        let mut cum = vec![0.0f64; n];
        let mut members = 0usize;
        for (m, scale) in cal.members.iter().zip(scales) {
            let Some(mi) = models.iter().position(|x| x.name() == m.model) else {
                continue;
            };
            let one = Calibration {
                members: vec![dronewatt::mission::forecast::Member { scale, ..m.clone() }],
                ..cal.clone()
            };
            let fc = forecast(
                &p.traj,
                std::slice::from_mut(&mut models[mi]),
                &one,
                cfg.telemetry.window,
                dronewatt::mission::MODEL_STRIDE,
            );
            for (c, e) in cum.iter_mut().zip(&fc.cum_p50_wh) {
                *c += e;
            }
            members += 1;
        }
        if members == 0 {
            continue;
        }
        let share = 1.0 / members as f64;
        let total = cum.last().copied().unwrap_or(0.0) * share;
        let done = cum.get(p.live_k).copied().unwrap_or(0.0) * share;
        let live_scale = if done > 0.05 * total && p.live_so_far_wh > 0.0 {
            1.0 + cal.live_weight * ((p.live_so_far_wh / done).clamp(0.8, 1.25) - 1.0)
        } else {
            1.0
        };
        let dt_s = p.traj.dt_s;
        let mut prev = 0.0;
        let power_w = cum
            .iter()
            .map(|&e| {
                let w = (e - prev) * share * 3600.0 / dt_s;
                prev = e;
                w
            })
            .collect();
        out.insert(
            p.flight,
            PlanPower {
                dt_s,
                power_w,
                geometry_from: p.geometry_from,
                energy_wh: total,
                live_k: p.live_k,
                live_scale,
            },
        );
    }
    Ok(out)
}
