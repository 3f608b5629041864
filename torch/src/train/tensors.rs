//! A flight's windows as training tensors: the raw inputs and targets, their scaling, the
//! splits, and the loss (pinball for the band, relative weights for the mean).

use super::*;

/// The raw inputs and targets of one flight's windows whose target sample (`lag` before
/// the newest) carries a measured power.
pub(crate) fn flight_data(f: &FlightWindows, set: FeatureSet, t: usize, lag: usize) -> FlightData {
    let mut d = FlightData::default();
    for w in &f.windows {
        if let Some(p) = w.back(lag).measured_w.filter(|p| p.is_finite()) {
            push_inputs(w, set, t, &mut d.x);
            d.y.push(p);
        }
    }
    d
}

/// Stack these flights' windows (every `stride`-th) into raw inputs and targets.
pub(super) fn gather(
    flights: &[u32],
    per_flight: &BTreeMap<u32, FlightData>,
    t: usize,
    stride: usize,
) -> (Vec<f32>, Vec<f32>) {
    let (mut x, mut y) = (Vec::new(), Vec::new());
    let w = t * N_FEATURES;
    for f in flights {
        if let Some(d) = per_flight.get(f) {
            for i in (0..d.y.len()).step_by(stride.max(1)) {
                x.extend_from_slice(&d.x[i * w..(i + 1) * w]);
                y.push(d.y[i]);
            }
        }
    }
    (x, y)
}

/// Mean/std of every input over the training windows, and the target scale.
pub(super) fn fit_scaling(x: &[f32], y: &[f32]) -> Scaling {
    let n = (x.len() / N_FEATURES).max(1) as f64;
    let mut sum = [0f64; N_FEATURES];
    let mut sq = [0f64; N_FEATURES];
    for row in x.chunks(N_FEATURES) {
        for (f, v) in row.iter().enumerate() {
            sum[f] += *v as f64;
            sq[f] += (*v as f64) * (*v as f64);
        }
    }
    let mean: Vec<f32> = sum.iter().map(|s| (s / n) as f32).collect();
    let std: Vec<f32> = (0..N_FEATURES)
        .map(|f| {
            let var = (sq[f] / n - (sum[f] / n).powi(2)).max(0.0);
            let s = var.sqrt() as f32;
            if s > 1e-6 {
                s
            } else {
                1.0
            }
        })
        .collect();
    let max_p = y.iter().cloned().fold(1.0f32, f32::max);
    Scaling {
        mean,
        std,
        power_scale_w: 1.2 * max_p,
    }
}

/// Standardised `[n, T, 21]` inputs and scaled `[n]` targets on `device`.
pub(crate) fn to_tensors(
    x: &[f32],
    y: &[f32],
    s: &Scaling,
    t: usize,
    device: Device,
) -> (Tensor, Tensor) {
    let n = y.len() as i64;
    let mean = Tensor::from_slice(&s.mean).view([1, 1, N_FEATURES as i64]);
    let std = Tensor::from_slice(&s.std).view([1, 1, N_FEATURES as i64]);
    let xt = ((Tensor::from_slice(x).view([n, t as i64, N_FEATURES as i64]) - mean) / std)
        .to_device(device);
    let yt = (Tensor::from_slice(y) / s.power_scale_w as f64).to_device(device);
    (xt, yt)
}

/// Pinball loss of `pred` at quantile `q` against `y` (both `[n]`), mean.
pub(super) fn pinball(pred: &Tensor, y: &Tensor, q: f64) -> Tensor {
    let e = y - pred;
    (&e * q).maximum(&(&e * (q - 1.0))).mean(Kind::Float)
}

/// The training loss of network outputs `out` (`[n, 3]`) against scaled targets `y`; `w`
/// (`[n]`, mean 1) weights the point estimate's term window by window (`--relative-loss`).
pub(crate) fn loss_fn(out: &Tensor, y: &Tensor, w: Option<&Tensor>) -> Tensor {
    let point = match w {
        None => pinball(&out.select(1, 0), y, 0.5),
        Some(w) => {
            let e = y - out.select(1, 0);
            ((&e * 0.5).maximum(&(&e * -0.5)) * w).mean(Kind::Float)
        }
    };
    2.0 * point
        + pinball(&out.select(1, 1), y, BAND_Q.0 as f64)
        + pinball(&out.select(1, 2), y, BAND_Q.1 as f64)
}

/// Per-window weights of the point loss for `--relative-loss` λ over targets `y` (W). In
/// flight (`P ≥ IN_FLIGHT_W`, the windows in-flight MAPE counts): `(1 − λ) + λ · P̄ / P`,
/// `P̄` the in-flight windows' harmonic mean, so their weights average 1 and λ = 1 is the
/// relative error's loss. On the ground (motors off or idling, where a percentage means
/// nothing) 1: the absolute loss. `None` for λ = 0.
pub(crate) fn relative_weights(y: &[f32], lambda: f64) -> Option<Vec<f32>> {
    if lambda == 0.0 || y.is_empty() {
        return None;
    }
    let in_flight = |p: f32| f64::from(p) >= dronewatt::offline::metrics::IN_FLIGHT_W;
    let (n, inv_sum) = y
        .iter()
        .filter(|&&p| in_flight(p))
        .fold((0usize, 0.0f64), |(n, s), &p| {
            (n + 1, s + 1.0 / f64::from(p))
        });
    let p_bar = if n > 0 { n as f64 / inv_sum } else { 0.0 };
    Some(
        y.iter()
            .map(|&p| {
                if in_flight(p) {
                    ((1.0 - lambda) + lambda * p_bar / f64::from(p)) as f32
                } else {
                    1.0
                }
            })
            .collect(),
    )
}

/// The windows one split trains and early-stops on, standardised, as tensors on the device:
/// built once per split and shared by every member of an ensemble.
pub(crate) struct SplitTensors {
    pub(crate) scaling: Scaling,
    pub(super) x: Tensor,
    pub(super) y: Tensor,
    pub(super) vx: Tensor,
    pub(super) vy: Tensor,
    /// The point loss's per-window weights (`--relative-loss`), when not all 1.
    pub(super) weights: Option<Tensor>,
    /// Training windows.
    pub(crate) n: usize,
}

/// Gather `train` flights' windows (every `--stride`-th) and `val` flights' (every 2nd),
/// fit the scaling on the training windows and move both to `device`.
pub(crate) fn split_tensors(
    args: &TrainArgs,
    train: &[u32],
    val: &[u32],
    per_flight: &BTreeMap<u32, FlightData>,
    t: usize,
    device: Device,
    label: &str,
) -> anyhow::Result<SplitTensors> {
    let (xr, yr) = gather(train, per_flight, t, args.stride);
    let (xv, yv) = gather(val, per_flight, t, 2);
    anyhow::ensure!(
        !yr.is_empty() && !yv.is_empty(),
        "{label}: no training or validation windows"
    );
    let scaling = fit_scaling(&xr, &yr);
    let weights =
        relative_weights(&yr, args.relative_loss).map(|w| Tensor::from_slice(&w).to_device(device));
    let (x, y) = to_tensors(&xr, &yr, &scaling, t, device);
    let (vx, vy) = to_tensors(&xv, &yv, &scaling, t, device);
    Ok(SplitTensors {
        scaling,
        x,
        y,
        vx,
        vy,
        weights,
        n: yr.len(),
    })
}
