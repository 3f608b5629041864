//! dronewatt's libtorch half: the paper's network in tch ([`Net`]), LSTM training
//! ([`train`]), and the libtorch backends of [`dronewatt::model::lstm::LstmModel`]
//! (TorchScript modules; any model on CUDA). `dronewatt` itself never loads libtorch; the
//! `dronewatt-torch` binary is the same command line with these registered ([`install`]),
//! and `dronewatt` hands it the commands that need them.

use std::path::Path;

use anyhow::Context;
use dronewatt::features::N_FEATURES;
use dronewatt::model::card::{ModelCard, WeightsFormat};
use dronewatt::model::lstm::ExternalNet;
use tch::nn::{self, Module, RNN};
use tch::{Device, Kind, Tensor};

pub mod finetune;
pub mod train;

/// Register the libtorch parts with `dronewatt`: the trainer and the loader of TorchScript
/// and CUDA models. Call once, first thing.
pub fn install() {
    dronewatt_lab::train::set_trainer(train::run);
    dronewatt::offline::learn::set_fine_tuner(finetune::fine_tune);
    dronewatt::model::lstm::set_external_loader(load);
}

/// The paper's network: two stacked bidirectional LSTM layers, dropout, dense, tanh.
#[derive(Debug)]
pub struct Net {
    lstm: nn::LSTM,
    head: nn::Linear,
    dropout: f64,
    /// The window step whose top-layer states the head reads (`None`: the final ones).
    readout: Option<i64>,
}

impl Net {
    /// Build the network's variables under `p` (`p/lstm`, `p/head`). `readout`: the window
    /// step whose top-layer states (both directions) the head reads, `None` for the final
    /// ones ([`dronewatt::model::card::ModelCard::readout_step`]).
    pub fn new(
        p: &nn::Path,
        hidden: i64,
        layers: i64,
        dropout: f64,
        readout: Option<usize>,
    ) -> Net {
        let cfg = nn::RNNConfig {
            num_layers: layers,
            bidirectional: true,
            batch_first: true,
            ..Default::default()
        };
        let lstm = nn::lstm(p / "lstm", N_FEATURES as i64, hidden, cfg);
        let head = nn::linear(p / "head", 2 * hidden, 3, Default::default());
        Net {
            lstm,
            head,
            dropout,
            readout: readout.map(|r| r as i64),
        }
    }

    /// `x`: `[batch, T, 21]` standardised → `[batch, 3]` tanh-scaled (point, low, high).
    /// `train` turns dropout on.
    pub fn forward_t(&self, x: &Tensor, train: bool) -> Tensor {
        let (out, nn::LSTMState((h, _))) = self.lstm.seq(x);
        let last = match self.readout {
            // out: [batch, T, 2 × hidden], each step's forward and backward states.
            Some(r) => out.select(1, r.min(out.size()[1] - 1)),
            None => {
                // h: [layers × 2, batch, hidden]; the last two are the top layer's
                // forward/backward.
                let n = h.size()[0];
                Tensor::cat(&[h.get(n - 2), h.get(n - 1)], 1)
            }
        };
        self.head.forward(&last.dropout(self.dropout, train)).tanh()
    }
}

/// A network on libtorch. (One per loaded model, made once: the size difference between the
/// variants costs nothing worth a box.)
#[allow(clippy::large_enum_variant)]
enum Backend {
    Native { _vs: nn::VarStore, net: Net },
    Script(tch::CModule),
}

/// [`ExternalNet`] on libtorch: our own network from `.safetensors`, or a TorchScript module.
pub struct TorchNet {
    backend: Backend,
    device: Device,
}

impl TorchNet {
    /// Load `weights` as `card` describes them, on `device`.
    pub fn load(weights: &Path, card: &ModelCard, device: Device) -> anyhow::Result<TorchNet> {
        let backend = match card.weights_format {
            WeightsFormat::Safetensors => {
                let mut vs = nn::VarStore::new(device);
                let net = Net::new(
                    &vs.root(),
                    card.hidden,
                    card.layers,
                    card.training.dropout,
                    card.readout_step(),
                );
                vs.load(weights)
                    .with_context(|| format!("{}: cannot load LSTM weights", weights.display()))?;
                Backend::Native { _vs: vs, net }
            }
            WeightsFormat::Torchscript => {
                let mut m = tch::CModule::load_on_device(weights, device).with_context(|| {
                    format!("{}: cannot load TorchScript module", weights.display())
                })?;
                m.set_eval();
                Backend::Script(m)
            }
        };
        Ok(TorchNet { backend, device })
    }
}

impl ExternalNet for TorchNet {
    fn forward(&mut self, x: &[f32], b: usize, t: usize) -> anyhow::Result<(Vec<f32>, usize)> {
        // One intra-op thread (per OS thread, so here, where inference runs): this network
        // is small, and at batch 1 a thread team costs more than it gains.
        tch::set_num_threads(1);
        let x = Tensor::from_slice(x)
            .view([b as i64, t as i64, N_FEATURES as i64])
            .to_device(self.device);
        let y = tch::no_grad(|| match &self.backend {
            Backend::Native { net, .. } => Ok(net.forward_t(&x, false)),
            Backend::Script(m) => m.forward_ts(&[&x]),
        })?;
        let y = y.to_device(Device::Cpu).to_kind(Kind::Float).contiguous();
        let cols = if y.dim() == 2 {
            y.size()[1] as usize
        } else {
            1
        };
        Ok((Vec::<f32>::try_from(y.view([-1]))?, cols))
    }

    fn describe(&self) -> String {
        let what = match self.backend {
            Backend::Native { .. } => "network",
            Backend::Script(_) => "TorchScript module",
        };
        format!("libtorch ({what}, {:?})", self.device)
    }
}

/// The loader `dronewatt-torch` registers: TorchScript always on libtorch; our own weights
/// on libtorch only where CUDA is available (on the CPU the hand-written kernel is faster).
pub fn load(weights: &Path, card: &ModelCard) -> anyhow::Result<Option<Box<dyn ExternalNet>>> {
    let device = Device::cuda_if_available();
    if card.weights_format == WeightsFormat::Torchscript || device != Device::Cpu {
        return Ok(Some(Box::new(TorchNet::load(weights, card, device)?)));
    }
    Ok(None)
}

/// A loader that puts every model on libtorch (CPU): benchmarks and the checks of the
/// kernel against libtorch.
pub fn load_on_libtorch(
    weights: &Path,
    card: &ModelCard,
) -> anyhow::Result<Option<Box<dyn ExternalNet>>> {
    Ok(Some(Box::new(TorchNet::load(weights, card, Device::Cpu)?)))
}
