//! The LSTM model's forward over one batch of windows: the inputs standardised, the
//! ensemble's members (on two threads for a large batch on the hand-written kernel), the
//! card's trees on the raw inputs, and the blend, in watts. The same figures to the bit
//! however the batch is cut and whichever thread runs a member: each member's outputs
//! are its own, summed in member order.

use super::{push_inputs, tree_rows, within_training_range, Backend, Blend, LstmModel};
use crate::features::N_FEATURES;
use crate::model::card::ModelCard;
use crate::telemetry::window::Window;

/// From this many windows a batch runs the ensemble's members on two threads (the
/// first member and the trees on the caller's, the others on a second): a thread costs
/// tens of µs to start, a member about 20 µs a window. A live window alone, or a few
/// vehicles' at once, stays on one thread.
pub const PARALLEL_WINDOWS: usize = 32;

impl LstmModel {
    /// Run the network on `windows` (one batch); rows of `[point, low, high]` in watts.
    pub fn forward_w(&mut self, windows: &[Window]) -> anyhow::Result<Vec<[f32; 3]>> {
        let t = self.card.window;
        let b = windows.len();
        self.buf.clear();
        for w in windows {
            push_inputs(w, self.card.feature_set, t, &mut self.buf);
        }
        self.raw.clear();
        if self.trees.is_some() {
            self.raw.extend_from_slice(&self.buf);
        }
        // Every window's rows are T × N_FEATURES: the feature of value i is i % N_FEATURES.
        for (i, v) in self.buf.iter_mut().enumerate() {
            let f = i % N_FEATURES;
            *v = (*v - self.card.feature_mean[f]) / self.card.feature_std[f];
        }
        anyhow::ensure!(!self.backends.is_empty(), "lstm: no network loaded");
        self.outs.resize_with(self.backends.len(), Vec::new);
        let parallel = self.backends.len() > 1
            && b >= PARALLEL_WINDOWS
            && self
                .backends
                .iter()
                .all(|k| matches!(k, Backend::Kernel(_)));
        let (x, card, raw) = (&self.buf, &self.card, &self.raw);
        let (first, rest) = self.backends.split_at_mut(1);
        let (out0, outs) = self.outs.split_at_mut(1);
        let trees = self.trees.as_mut();
        let cols = if parallel {
            std::thread::scope(|s| {
                let others = s.spawn(|| run_members(rest, outs, x, b, t));
                let c0 = first[0].forward(x, b, t, &mut out0[0]);
                if let Some(bl) = trees {
                    tree_estimates(bl, card, windows, raw);
                }
                let cs = others
                    .join()
                    .unwrap_or_else(|p| std::panic::resume_unwind(p));
                Ok::<_, anyhow::Error>((c0?, cs?))
            })?
        } else {
            if let Some(bl) = trees {
                tree_estimates(bl, card, windows, raw);
            }
            let c0 = first[0].forward(x, b, t, &mut out0[0])?;
            (c0, run_members(rest, outs, x, b, t)?)
        };
        let (cols, others) = cols;
        for (k, c) in others.iter().enumerate() {
            anyhow::ensure!(
                *c == cols,
                "ensemble member {} gives {c} outputs a window, the first {cols}",
                k + 1
            );
        }
        // The members' mean, summed in member order.
        self.sum.clear();
        self.sum.extend_from_slice(&self.outs[0]);
        for o in &self.outs[1..] {
            for (acc, v) in self.sum.iter_mut().zip(o) {
                *acc += v;
            }
        }
        let n = self.backends.len() as f32;
        if n > 1.0 {
            for v in &mut self.sum {
                *v /= n;
            }
        }
        let s = self.card.power_scale_w;
        let mut rows: Vec<[f32; 3]> = self
            .sum
            .chunks(cols)
            .map(|r| {
                let p = r[0] * s;
                if r.len() >= 3 {
                    [p, (r[1] * s).min(p), (r[2] * s).max(p)]
                } else {
                    [p, p, p]
                }
            })
            .collect();
        if let Some(b) = &self.trees {
            // w × network + (1 − w) × trees; the band moves with the estimate.
            for (r, e) in rows.iter_mut().zip(&b.est) {
                if e.is_finite() {
                    let d = (1.0 - b.weight) * (e - r[0]);
                    for v in r.iter_mut() {
                        *v += d;
                    }
                }
            }
        }
        Ok(rows)
    }
}

/// Members `backends` in order, each into its own `outs`: their column counts.
fn run_members(
    backends: &mut [Backend],
    outs: &mut [Vec<f32>],
    x: &[f32],
    b: usize,
    t: usize,
) -> anyhow::Result<Vec<usize>> {
    backends
        .iter_mut()
        .zip(outs.iter_mut())
        .map(|(k, o)| k.forward(x, b, t, o))
        .collect()
}

/// Each window's tree estimate into `bl.est` (NaN where the newest sample lies outside
/// the training range: the network alone there), from the windows' raw inputs `raw`
/// (`push_inputs`, T rows a window).
fn tree_estimates(bl: &mut Blend, card: &ModelCard, windows: &[Window], raw: &[f32]) {
    bl.est.clear();
    let per = card.window * N_FEATURES;
    for (w, raw) in windows.iter().zip(raw.chunks_exact(per)) {
        // The newest sample as `in_training_range` reads it.
        bl.newest.clear();
        push_inputs(w, card.feature_set, 1, &mut bl.newest);
        bl.est.push(if within_training_range(card, &bl.newest) {
            bl.row.clear();
            bl.row
                .extend(tree_rows(raw, &bl.lags).flatten().map(|v| f64::from(*v)));
            bl.trees.predict(&bl.row) as f32
        } else {
            if !std::mem::replace(&mut bl.told, true) {
                tracing::info!("lstm: inputs outside the training range: the network alone, without its trees, there");
            }
            f32::NAN
        });
    }
}
