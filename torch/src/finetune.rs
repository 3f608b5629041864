//! `dronewatt learn --fine-tune`: the LSTM fine-tuned for a vehicle from the shipped M100
//! weights ([`dronewatt::offline::learn::FineTuneJob`]).
//!
//! The windows are the training logs' through the live feature path (what `learn` hands
//! over); the network starts from the shipped weights and keeps the shipped model's input
//! standardisation and target scale (the weights were learned on them), so the card written
//! beside the new weights carries the same normalisation. Adam at a small learning rate,
//! the training loss of `train` (pinball point + band heads), a few epochs; after each, the
//! MAE on the held-out logs' windows; the epoch with the lowest is kept, and the shipped
//! weights themselves (epoch 0) when no epoch beats them. The weights are written as
//! `.safetensors` (same variable names as `train`), which the lean binary's `CpuLstm`
//! reads.

use std::time::Instant;

use anyhow::Context;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use tch::nn::{self, OptimizerConfig};
use tch::{Device, Tensor};

use dronewatt::model::card::{ModelCard, WeightsFormat};
use dronewatt::offline::data::FlightWindows;
use dronewatt::offline::learn::{FineTuneJob, FineTuned};

use crate::train::tensors::{flight_data, loss_fn, to_tensors};
use crate::train::{validate, Scaling};
use crate::Net;

/// Name of the fine-tuned model (in the JSON lines, the tables and the profile's forecast).
pub const NAME: &str = "lstm_ft";
/// Windows a batch.
const BATCH: usize = 64;
const SEED: u64 = 1;

/// Raw inputs and targets of these logs' windows.
fn gather(logs: &[FlightWindows], card: &ModelCard) -> (Vec<f32>, Vec<f32>) {
    let (mut x, mut y) = (Vec::new(), Vec::new());
    for f in logs {
        let d = flight_data(f, card.feature_set, card.window, card.target_lag);
        x.extend(d.x);
        y.extend(d.y);
    }
    (x, y)
}

/// Run one fine-tuning (module docs).
pub fn fine_tune(job: &FineTuneJob) -> anyhow::Result<FineTuned> {
    let started = Instant::now();
    let card_path = job.base.join("card.toml");
    let card = ModelCard::load(&card_path)?;
    anyhow::ensure!(
        card.weights_format == WeightsFormat::Safetensors,
        "{}: only .safetensors weights can be fine-tuned",
        card_path.display()
    );
    let device = Device::cuda_if_available();
    let scaling = Scaling {
        mean: card.feature_mean.clone(),
        std: card.feature_std.clone(),
        power_scale_w: card.power_scale_w,
    };
    let (xr, yr) = gather(job.train, &card);
    let (xv, yv) = gather(job.held_out, &card);
    anyhow::ensure!(
        !yr.is_empty() && !yv.is_empty(),
        "fine-tuning: no training or held-out windows with measured power"
    );
    let (x, y) = to_tensors(&xr, &yr, &scaling, card.window, device);
    let (vx, vy) = to_tensors(&xv, &yv, &scaling, card.window, device);

    tch::manual_seed(SEED as i64);
    let mut vs = nn::VarStore::new(device);
    let net = Net::new(
        &vs.root(),
        card.hidden,
        card.layers,
        job.dropout.unwrap_or(card.training.dropout),
        card.readout_step(),
    );
    // An ensemble (`card.members`) is fine-tuned through its first member, which is
    // cheaper than tuning every member and keeps `learn`'s card one network.
    let weights = job.base.join(&card.weights);
    vs.load(&weights).with_context(|| {
        format!(
            "{}: cannot load the weights to fine-tune",
            weights.display()
        )
    })?;
    let mut opt = nn::Adam::default().build(&vs, job.lr)?;

    let (_, shipped_mae, _) = validate(&net, &vx, &vy, scaling.power_scale_w);
    let snapshot = |vs: &nn::VarStore| -> Vec<Tensor> {
        vs.trainable_variables()
            .iter()
            .map(|v| v.detach().copy())
            .collect()
    };
    let mut best = (shipped_mae, 0usize, snapshot(&vs));
    let mut rng = rand::rngs::StdRng::seed_from_u64(SEED);
    let mut order: Vec<i64> = (0..yr.len() as i64).collect();
    let (mut steps, mut epochs_run) = (0usize, 0usize);
    let max_steps = job.max_steps.unwrap_or(usize::MAX);
    for epoch in 1..=job.epochs {
        order.shuffle(&mut rng);
        for chunk in order.chunks(BATCH) {
            if steps >= max_steps {
                break;
            }
            let ix = Tensor::from_slice(chunk).to_device(device);
            let out = net.forward_t(&x.index_select(0, &ix), true);
            opt.backward_step(&loss_fn(&out, &y.index_select(0, &ix), None));
            steps += 1;
        }
        epochs_run = epoch;
        let (_, mae, _) = validate(&net, &vx, &vy, scaling.power_scale_w);
        tracing::info!(
            "fine-tuning epoch {epoch}: held-out MAE {mae:.1} W (shipped {shipped_mae:.1} W)"
        );
        if mae < best.0 {
            best = (mae, epoch, snapshot(&vs));
        } else if epoch - best.1 >= job.patience {
            break;
        }
        if steps >= max_steps {
            break;
        }
    }
    let (best_mae, best_epoch, kept) = best;
    tch::no_grad(|| {
        for (v, s) in vs.trainable_variables().iter_mut().zip(&kept) {
            v.copy_(s);
        }
    });
    let weights_out = job.out.join("model.safetensors");
    vs.save(&weights_out).with_context(|| {
        format!(
            "{}: cannot save the fine-tuned weights",
            weights_out.display()
        )
    })?;
    let train_time_s = started.elapsed().as_secs_f64();
    let mut out_card = card.clone();
    out_card.name = NAME.into();
    out_card.weights = "model.safetensors".into();
    // An ensemble's first member is what was fine-tuned: the card is one network's.
    out_card.members.clear();
    // The M100's trees are not tuned to this vehicle: the fine-tuned network runs alone.
    out_card.trees = None;
    out_card.training.init_seed = None;
    out_card.validation_metrics = None;
    out_card.training.data_file = job.logs.join(", ");
    out_card.training.data_sha256 = String::new();
    out_card.training.seed = SEED;
    out_card.training.learning_rate = job.lr;
    out_card.training.dropout = job.dropout.unwrap_or(card.training.dropout);
    out_card.training.batch_size = BATCH;
    out_card.training.epochs_run = epochs_run;
    out_card.training.best_epoch = best_epoch;
    out_card.training.steps = steps;
    out_card.training.stride = 1;
    out_card.training.train_windows = yr.len();
    out_card.training.train_flights = job.train.iter().map(|f| f.flight).collect();
    out_card.training.validation_flights = job.held_out.iter().map(|f| f.flight).collect();
    out_card.training.train_time_s = train_time_s;
    out_card.training.device = format!("{device:?}");
    // Scored on the M100's test flights no more: `learn`'s card has the by-log scores.
    out_card.metrics = None;
    out_card.save(&job.out.join("card.toml"))?;
    Ok(FineTuned {
        epochs_run,
        best_epoch,
        held_out_mae_w: (shipped_mae, best_mae),
        train_windows: yr.len(),
        train_time_s,
    })
}
