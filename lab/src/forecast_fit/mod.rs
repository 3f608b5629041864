//! The mission forecast's correction, fitted on the training flights only by rolling
//! validation (what `plan-eval` applies to the test flights):
//!
//! The forecast's correction (its members — the vehicle's own models that tie for the best
//! fit, each with its weighting: one weight on the model's power plus one on the climbing
//! work m·g·v_z ([`BASES`]), and its scale — the P90 ratio, the live weight) is fitted on the
//! training flights only (route flights not in [`dronewatt::offline::data::TEST_FLIGHTS`]) by rolling validation and
//! then applied to the test flights; `--json` writes everything, the fit and the training
//! flights' own scores included.

use anyhow::Context;

pub mod score;

use crate::route::flight_plan;
use crate::route::ground_wind;
use crate::route::AIRBORNE_W;
use dronewatt::config::Config;
use dronewatt::mission::forecast::{forecast, Calibration, Member};
use dronewatt::mission::trajectory::{enu_of, fly, Conditions, Trajectory, Wind};
use dronewatt::model::profile::VehicleProfile;
use dronewatt::model::PowerModel;
use dronewatt::offline::metrics::median;
use dronewatt::offline::metrics::quantile;
use dronewatt::source::logs::dataset::{self, Flight};
use score::{gcs_left_s, score};

/// One model's uncorrected forecast of a flight's plan, split for fitting: energy by
/// phase ([`phase_of`]) up to the live point and after it, Wh.
pub(crate) struct ModelRaw {
    pub(crate) name: String,
    pub(crate) total_wh: f64,
    pub(crate) first_wh: Terms,
    pub(crate) rest_wh: Terms,
    pub(crate) planned_left_s: f64,
    /// The uncorrected P50 energy of each trajectory sample, Wh (`plan-eval --dump-live`).
    pub(crate) sample_wh: Vec<f64>,
}

/// A forecast's energy split into what the calibration weighs ([`Calibration`]'s weights):
/// the model's energy in vertical climb, vertical descent and the rest, and the vertical
/// work m·g·v_z up and down, Wh.
pub type Terms = [f64; 5];

/// Phase of a trajectory sample: 0 vertical climb, 1 vertical descent, 2 anything else.
pub use dronewatt::mission::forecast::phase_of;

pub(crate) fn dot5(a: &Terms, b: &Terms) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// How far ahead on the plan the live point is searched for from one row to the next, s.
pub(crate) const LOCATE_HORIZON_S: f64 = 15.0;

/// Inputs of one flight kept for fitting.
pub(crate) struct Prepared {
    pub(crate) flight: u32,
    pub(crate) route: String,
    pub(crate) speed_m_s: f64,
    pub(crate) payload_g: f64,
    pub(crate) altitude: String,
    pub(crate) geometry_from: u32,
    pub(crate) waypoints: usize,
    pub(crate) wind: Wind,
    pub(crate) measured_s: f64,
    pub(crate) measured_wh: f64,
    pub(crate) traj: Trajectory,
    /// The plan's home, where the rows' positions are measured from.
    pub(crate) home: dronewatt::mission::plan::GeoPoint,
    /// Per model, uncorrected.
    pub(crate) raw: Vec<ModelRaw>,
    /// Live: the trajectory sample reached at half time, energy measured so far, energy
    /// measured after, mean power since the motors started.
    pub(crate) live_k: usize,
    /// The ground station's mission time left from the live point ([`gcs_left_s`]), s.
    pub(crate) live_gcs_left_s: f64,
    pub(crate) live_so_far_wh: f64,
    /// Energy measured from take-off (first row above `AIRBORNE_W`) to the live point, Wh.
    pub(crate) live_airborne_so_far_wh: f64,
    pub(crate) live_rest_wh: f64,
    /// Rows of the recording: first airborne, half time (the live point), last airborne.
    pub(crate) live_rows: [usize; 3],
    /// Measured energy from the recording's start to each row, Wh.
    pub(crate) cum_wh: Vec<f64>,
    pub(crate) live_mean_w: f64,
    pub(crate) airborne_s: f64,
    pub(crate) live_t_s: f64,
    /// Mean power over the airborne time (first to last row above `AIRBORNE_W`), W.
    pub(crate) flight_mean_w: f64,
}

/// Measured energy, cumulative by row, Wh (rectangle rule to the next row).
fn measured_cum_wh(rows: &[dataset::Row]) -> Vec<f64> {
    let mut cum = vec![0.0f64; rows.len()];
    for i in 1..rows.len() {
        let dt = (rows[i].time_s - rows[i - 1].time_s).max(0.0);
        cum[i] = cum[i - 1] + rows[i - 1].voltage_v * rows[i - 1].current_a * dt / 3600.0;
    }
    cum
}

/// One model's forecast along the trajectory split at sample `k` (the live point) into what
/// the calibration weighs, before and after it, with each sample's energy.
fn model_raw(
    fc: &dronewatt::mission::forecast::MissionForecast,
    traj: &Trajectory,
    k: usize,
    vehicle_kg: f64,
) -> ModelRaw {
    let (mut first_wh, mut rest_wh) = ([0.0; 5], [0.0; 5]);
    let mut prev = 0.0;
    let mut sample_wh = Vec::with_capacity(fc.cum_p50_wh.len());
    for (j, &c) in fc.cum_p50_wh.iter().enumerate() {
        let e = c - prev;
        prev = c;
        sample_wh.push(e);
        let ph = phase_of(&traj.samples[j]);
        let x = if j <= k { &mut first_wh } else { &mut rest_wh };
        x[ph] += e;
        let [up, down] =
            dronewatt::mission::forecast::vertical_work_w(&traj.samples[j], vehicle_kg);
        x[3] += up * traj.dt_s / 3600.0;
        x[4] += down * traj.dt_s / 3600.0;
    }
    ModelRaw {
        name: fc.model.clone(),
        total_wh: fc.energy_p50_wh,
        first_wh,
        rest_wh,
        planned_left_s: fc.remaining_from(k, None, 0.0).time_s,
        sample_wh,
    }
}

pub(crate) fn prepare(
    f: &Flight,
    geometry: &Flight,
    ground: bool,
    cfg: &Config,
    models: &mut [Box<dyn PowerModel>],
) -> anyhow::Result<Prepared> {
    let plan = flight_plan(f, geometry)?;
    let wind = if ground {
        ground_wind(f)
    } else {
        Wind::default()
    };
    let cond = Conditions {
        wind,
        payload_g: f.payload_g,
        speed_m_s: Some(f.speed_m_s),
        rate_hz: cfg.telemetry.rate_hz,
    };
    let traj = fly(&plan, &cfg.forecast.kinematics, &cond);
    let mut fcs = Vec::new();
    for m in models.iter_mut() {
        let cal = Calibration::uncorrected(m.name());
        fcs.push(forecast(
            &traj,
            std::slice::from_mut(m),
            &cal,
            cfg.telemetry.window,
            dronewatt::mission::MODEL_STRIDE,
        ));
    }
    let rows = &f.rows;
    let cum = measured_cum_wh(rows);
    let measured_wh = cum.last().copied().unwrap_or(0.0);
    let on = |r: &dataset::Row| r.voltage_v * r.current_a > AIRBORNE_W;
    let i0 = rows
        .iter()
        .position(on)
        .with_context(|| format!("flight {}: never above {AIRBORNE_W} W", f.flight))?;
    let i1 = rows.iter().rposition(on).unwrap_or(i0);
    let t_half = 0.5 * (rows[i0].time_s + rows[i1].time_s);
    let ih = rows.iter().position(|r| r.time_s >= t_half).unwrap_or(i1);
    let home = plan.home;
    let mut k = 0usize;
    let horizon = (LOCATE_HORIZON_S / traj.dt_s) as usize;
    for r in &rows[i0..=ih] {
        let (e, n) = enu_of(&home, r.lat_deg, r.lon_deg);
        k = traj.locate(
            k,
            horizon,
            [e as f32, n as f32, (r.alt_m - home.alt_m) as f32],
        );
    }
    let so_far = cum[ih];
    let vehicle_kg = VehicleProfile::m100().mass_kg(0.0);
    let raw = fcs
        .into_iter()
        .map(|fc| model_raw(&fc, &traj, k, vehicle_kg))
        .collect();
    let gcs_left = gcs_left_s(&traj, k, f.speed_m_s, &cfg.forecast.kinematics);
    let span = rows[ih].time_s - rows[i0].time_s;
    let live_mean_w = if span > 0.0 {
        (cum[ih] - cum[i0]) * 3600.0 / span
    } else {
        0.0
    };
    let air_s = rows[i1].time_s - rows[i0].time_s;
    let flight_mean_w = if air_s > 0.0 {
        (cum[i1] - cum[i0]) * 3600.0 / air_s
    } else {
        0.0
    };
    Ok(Prepared {
        flight: f.flight,
        route: f.route.clone(),
        speed_m_s: f.speed_m_s,
        payload_g: f.payload_g,
        altitude: f.altitude_text.clone(),
        geometry_from: geometry.flight,
        waypoints: plan.items.len().saturating_sub(3),
        wind,
        measured_s: rows.last().map_or(0.0, |r| r.time_s),
        measured_wh,
        traj,
        home,
        raw,
        live_k: k,
        live_gcs_left_s: gcs_left,
        live_so_far_wh: so_far,
        live_airborne_so_far_wh: cum[ih] - cum[i0],
        live_rest_wh: measured_wh - so_far,
        live_rows: [i0, ih, i1],
        cum_wh: cum,
        live_mean_w,
        airborne_s: air_s,
        live_t_s: span,
        flight_mean_w,
    })
}

/// The correction for flight `flight`: median measured/forecast of model `mi` over the
/// `k` training flights numbered closest before it (flight numbers follow the calendar;
/// `k` = 0: all of them), never the flight itself; all other training flights when fewer
/// than 5 come before it. The vehicle, its battery and the season drift (the test flights
/// fly in autumn, most training flights in summer): the recent flights say more.
fn recent_scale(train: &[Prepared], mi: usize, ks: &Terms, flight: u32, k: usize) -> f64 {
    let mut before: Vec<&Prepared> = train.iter().filter(|p| p.flight < flight).collect();
    if before.len() < 5 {
        before = train.iter().filter(|p| p.flight != flight).collect();
    }
    before.sort_by_key(|p| std::cmp::Reverse(p.flight));
    let take = if k == 0 {
        before.len()
    } else {
        k.min(before.len())
    };
    let mut r: Vec<f64> = before[..take]
        .iter()
        .map(|p| p.measured_wh / phased_wh(p, mi, ks).max(1e-9))
        .collect();
    median(&mut r)
}

/// Model `mi`'s forecast of flight `p` with phase weights `ks`, Wh.
fn phased_wh(p: &Prepared, mi: usize, ks: &Terms) -> f64 {
    let m = &p.raw[mi];
    dot5(ks, &m.first_wh) + dot5(ks, &m.rest_wh)
}

/// The ways the forecast's [`Terms`] may be weighted, each row one fitted weight shared
/// by the terms the row sums; `plan-eval` keeps the one with the smallest rolling-
/// validation error on the training flights. One way today:
/// - `vertical work`: one weight on the model's power everywhere plus one on the climbing
///   work m·g·v_z, defined for any climb, vertical or slanted.
///
/// A weight per phase (vertical climb, vertical descent, the rest) fits the training
/// flights as well or slightly better, but says nothing about a slanted climb: every
/// training route climbs only vertically, so the training flights cannot tell the two
/// apart on what matters for a new route (R7 climbs on slanted legs), and only the
/// climbing work carries over. The choice is made on that physics, not on the test flights.
pub const BASES: [(&str, &[Terms]); 1] = [(
    "vertical work",
    &[[1.0, 1.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0, 0.0]],
)];

/// Weights for model `mi`: least squares over the training flights' two halves (energy
/// to the live point, energy after it), each relative to its measured energy, so the
/// forecast's split between climb, descent and the rest follows what the training
/// flights drew. Unweighted model power when the system is singular (a phase never flown).
fn phase_weights(train: &[Prepared], mi: usize, rows: &[Terms]) -> Terms {
    let kk = rows.len();
    let mut ata = nalgebra::DMatrix::<f64>::zeros(kk, kk);
    let mut atb = nalgebra::DVector::<f64>::zeros(kk);
    for p in train {
        let m = &p.raw[mi];
        for (x, y) in [(m.first_wh, p.live_so_far_wh), (m.rest_wh, p.live_rest_wh)] {
            if y <= 0.0 {
                continue;
            }
            let v = nalgebra::DVector::from_iterator(kk, rows.iter().map(|r| dot5(r, &x) / y));
            ata += &v * v.transpose();
            atb += v;
        }
    }
    let plain = [1.0, 1.0, 1.0, 0.0, 0.0];
    match ata.try_inverse() {
        Some(inv) => {
            let k = inv * atb;
            let mut w = [0.0; 5];
            for (r, kr) in rows.iter().zip(k.iter()) {
                for j in 0..5 {
                    w[j] += r[j] * kr;
                }
            }
            if w.iter().all(|v| v.is_finite()) && w[..3].iter().all(|v| *v > 0.0) {
                w
            } else {
                plain
            }
        }
        None => plain,
    }
}

/// Whether model `name` may carry the fitted correction: only the vehicle's own models
/// (`_cal`: they run only with its calibrated profile) when any ran, since a correction of a
/// published model would follow that model onto every other vehicle (with this vehicle's
/// mass in the climbing work); any model when none of its own ran.
fn may_carry(name: &str, all: &[String]) -> bool {
    name.ends_with("_cal") || !all.iter().any(|n| n.ends_with("_cal"))
}

/// How many recent training flights the correction may be fitted on (0 = all).
const RECENT_CHOICES: [usize; 5] = [5, 10, 20, 40, 0];

/// Model `mi`'s member fitted with weighting `rows`: the weights by least squares on the
/// halves ([`phase_weights`]), the window `k` of recent flights with the smallest median
/// rolling-validation error, and the scale from the latest `k` training flights (for plans
/// flown after them). Also the candidate it makes: its median and per-flight rolling errors.
fn fit_member(train: &[Prepared], mi: usize, rows: &[Terms]) -> Candidate {
    let ks = phase_weights(train, mi, rows);
    let mut best: (f64, usize, Vec<f64>) = (f64::INFINITY, 0, Vec::new());
    for &k in &RECENT_CHOICES {
        let e: Vec<f64> = train
            .iter()
            .map(|p| {
                100.0
                    * (p.measured_wh
                        / (phased_wh(p, mi, &ks) * recent_scale(train, mi, &ks, p.flight, k))
                            .max(1e-9)
                        - 1.0)
                        .abs()
            })
            .collect();
        let m = median(&mut e.clone());
        if m < best.0 {
            best = (m, k, e);
        }
    }
    let (err, k, errors) = best;
    let latest = train.iter().map(|p| p.flight).max().unwrap_or(0) + 1;
    let name = train
        .first()
        .map_or(String::new(), |p| p.raw[mi].name.clone());
    let member = Member {
        model: name,
        scale: recent_scale(train, mi, &ks, latest, k),
        recent_flights: k,
        phase_scale: [ks[0], ks[1], ks[2]],
        climb_work: [ks[3], ks[4]],
    };
    Candidate {
        err,
        member,
        errors,
    }
}

/// Each member's scale for flight `flight`: fitted on the training flights before it.
pub(crate) fn rolling_scales(train: &[Prepared], cal: &Calibration, flight: u32) -> Vec<f64> {
    let index = |name: &str| {
        train
            .first()
            .and_then(|p| p.raw.iter().position(|m| m.name == name))
    };
    cal.members
        .iter()
        .map(|c| {
            index(&c.model).map_or(c.scale, |mi| {
                recent_scale(train, mi, &c.weights(), flight, c.recent_flights)
            })
        })
        .collect()
}

/// The P90 ratio and live weight for `members`, from the training flights forecast with
/// the members' rolling scales: the 90th percentile of measured over forecast, and the
/// live weight of 0, ¼, ½, ¾, 1 with the smallest median live error.
pub(crate) fn finish(train: &[Prepared], members: Vec<Member>) -> Calibration {
    let mut cal = Calibration {
        members,
        p90_ratio: 1.0,
        live_weight: 0.0,
        vehicle_kg: VehicleProfile::m100().mass_kg(0.0),
    };
    let scales: Vec<Vec<f64>> = train
        .iter()
        .map(|p| rolling_scales(train, &cal, p.flight))
        .collect();
    let mut res: Vec<f64> = train
        .iter()
        .zip(&scales)
        .map(|(p, sc)| p.measured_wh / score(p, &cal, sc, 0.0).p50_wh.max(1e-9))
        .collect();
    cal.p90_ratio = quantile(&mut res, 0.9).max(1.0);
    let mut best_w = (f64::INFINITY, 0.0);
    for w in [0.0, 0.25, 0.5, 0.75, 1.0] {
        cal.live_weight = w;
        let mut e: Vec<f64> = train
            .iter()
            .zip(&scales)
            .map(|(p, sc)| score(p, &cal, sc, 0.0).live_err_pct)
            .collect();
        let m = median(&mut e);
        if m < best_w.0 {
            best_w = (m, w);
        }
    }
    cal.live_weight = best_w.1;
    cal
}

/// Paired bootstrap resamples of the training flights in [`tie_share`].
pub(crate) const BOOTSTRAP: usize = 4000;
/// A model ties with the best when its median error is no larger than the best's in at
/// least this share of the resamples (a one-sided 5 % test cannot tell them apart).
pub(crate) const TIE_SHARE: f64 = 0.05;

/// How far errors `e` (per training flight, %) tie with the best's `best`: resample the
/// flights with replacement, both models on the same flights, and return the share of
/// resamples in which `e`'s median is no larger (a tie from [`TIE_SHARE`] up). Seeded: the
/// same flights give the same answer.
fn tie_share(e: &[f64], best: &[f64]) -> f64 {
    use rand::{Rng, SeedableRng};
    let n = e.len().min(best.len());
    if n == 0 {
        return 0.0;
    }
    let mut rng = rand::rngs::StdRng::seed_from_u64(0x64_77_61_74_74);
    let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
    let mut no_worse = 0usize;
    for _ in 0..BOOTSTRAP {
        for j in 0..n {
            let i = rng.random_range(0..n);
            (a[j], b[j]) = (e[i], best[i]);
        }
        if median(&mut a) <= median(&mut b) {
            no_worse += 1;
        }
    }
    no_worse as f64 / BOOTSTRAP as f64
}

/// Fit the correction on training flights only, by rolling validation: each training
/// flight is forecast with the correction fitted on the training flights before it
/// ([`recent_scale`]). Every model gets its member ([`fit_member`]); the best of the
/// vehicle's own (`_cal`) models, when any ran ([`may_carry`]), and every one of them that
/// ties with it ([`tie_share`]) are the members, ordered by error; then their P90 ratio and
/// live weight ([`finish`]).
///
/// Why a tie is kept rather than decided: nearly every training flight flies one route, so
/// a model's small lead there is noise (the leaders swapped under a change as small as one
/// kinematics default) and says nothing of a route none of them flew, where models of
/// different structure err differently; their mean hedges that.
pub(crate) fn fit(train: &[Prepared]) -> Fitted {
    let names: Vec<String> = train
        .first()
        .map(|p| p.raw.iter().map(|m| m.name.clone()).collect())
        .unwrap_or_default();
    let mut per_model: Vec<(String, f64, f64)> = names
        .iter()
        .map(|n| (n.clone(), 0.0, f64::INFINITY))
        .collect();
    let mut per_basis = Vec::new();
    // (best error, basis, its candidates)
    let mut best: (f64, usize, Vec<Candidate>) = (f64::INFINITY, 0, Vec::new());
    for (bi, (basis, rows)) in BASES.iter().enumerate() {
        let mut cands = Vec::new();
        for (mi, pm) in per_model.iter_mut().enumerate() {
            let c = fit_member(train, mi, rows);
            if c.err < pm.2 {
                (pm.1, pm.2) = (c.member.recent_flights as f64, c.err);
            }
            if may_carry(&names[mi], &names) {
                cands.push(c);
            }
        }
        cands.sort_by(|a, b| a.err.total_cmp(&b.err));
        let basis_best = cands.first().map_or(f64::INFINITY, |c| c.err);
        per_basis.push((basis.to_string(), basis_best));
        if basis_best < best.0 {
            best = (basis_best, bi, cands);
        }
    }
    let (_, bi, cands) = best;
    let lead = cands.first().map(|c| c.errors.clone()).unwrap_or_default();
    let ties: Vec<(String, f64)> = cands
        .iter()
        .map(|c| (c.member.model.clone(), tie_share(&c.errors, &lead)))
        .collect();
    let members: Vec<Member> = cands
        .into_iter()
        .zip(&ties)
        .filter(|(_, t)| t.1 >= TIE_SHARE)
        .map(|(c, _)| c.member)
        .collect();
    Fitted {
        cal: finish(train, members),
        basis: BASES[bi].0.to_string(),
        per_model,
        per_basis,
        ties,
    }
}

/// A model's member and its median and per-flight rolling errors (%), a candidate of [`fit`].
pub(crate) struct Candidate {
    pub(crate) err: f64,
    pub(crate) member: Member,
    pub(crate) errors: Vec<f64>,
}

/// What [`fit`] found.
pub(crate) struct Fitted {
    pub(crate) cal: Calibration,
    /// The [`BASES`] entry kept.
    pub(crate) basis: String,
    /// Per model: its best number of recent flights, its median error (%).
    pub(crate) per_model: Vec<(String, f64, f64)>,
    /// Per basis: its best median error (%), any model.
    pub(crate) per_basis: Vec<(String, f64)>,
    /// Per candidate model of the basis kept: its [`tie_share`] with the best.
    pub(crate) ties: Vec<(String, f64)>,
}
