//! Ensembles: networks that differ only in their initial weights (one `--seed`, several
//! `--init-seed`), trained on the same flights with the same scaling, whose mean is the
//! estimate. The kernel averages their outputs ([`dronewatt::model::lstm::LstmModel`],
//! `card.members`). `train --init-seed A,B,...` trains one (and `--cv` scores one per fold);
//! `train --ensemble DIR,DIR,...` assembles networks trained apart.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::Context;
use tch::Device;

use dronewatt::model::card::{ModelCard, WeightsFormat};
use dronewatt_lab::train::TrainArgs;

use super::{split_tensors, train_split, FlightData, Hyper, RunOutcome, Scaling};

/// One trained network of an ensemble: its init seed and its run.
pub(super) type Member = (u64, RunOutcome);

/// The init seeds `args` asks for: `--init-seed`'s, else `--seed`.
pub(super) fn init_seeds(args: &TrainArgs) -> Vec<u64> {
    if args.init_seed.is_empty() {
        vec![args.seed]
    } else {
        args.init_seed.clone()
    }
}

/// Train one network per init seed on the same flights: the scaling (the same for every
/// member: it depends on the flights only), each member's seed and run, and the training
/// windows a member saw. The windows are gathered and moved to the device once.
#[allow(clippy::too_many_arguments)]
pub(super) fn train_members(
    args: &TrainArgs,
    train: &[u32],
    val: &[u32],
    per_flight: &BTreeMap<u32, FlightData>,
    hp: Hyper,
    t: usize,
    device: Device,
    label: &str,
) -> anyhow::Result<(Scaling, Vec<Member>, usize)> {
    let seeds = init_seeds(args);
    let data = split_tensors(args, train, val, per_flight, t, device, label)?;
    let mut members = Vec::with_capacity(seeds.len());
    for &s in &seeds {
        let label = if seeds.len() > 1 {
            format!("{label} member {s}")
        } else {
            label.to_string()
        };
        members.push((s, train_split(args, s, &data, hp, device, &label)?));
    }
    Ok((data.scaling, members, data.n))
}

/// Save the members' weights into `dir`: `model.safetensors` for one network,
/// `member-SEED.safetensors` each for an ensemble. The file names, first member first.
pub(super) fn save_members(dir: &Path, members: &[Member]) -> anyhow::Result<Vec<String>> {
    let mut files = Vec::with_capacity(members.len());
    for (seed, outcome) in members {
        let name = if members.len() == 1 {
            "model.safetensors".to_string()
        } else {
            format!("member-{seed}.safetensors")
        };
        outcome
            .vs
            .save(dir.join(&name))
            .with_context(|| format!("{}: cannot save weights", dir.join(&name).display()))?;
        files.push(name);
    }
    Ok(files)
}

/// Record in `card` (written for the first member) the ensemble's members and the first
/// member's init seed.
pub(super) fn describe(
    card: &mut ModelCard,
    args: &TrainArgs,
    members: &[Member],
    files: &[String],
) {
    card.members = files.iter().skip(1).cloned().collect();
    card.training.init_seed = members.first().map(|m| m.0).filter(|&s| s != args.seed);
}

/// Write the ensemble of `members` (model folders) into `out`: the first member's card with
/// every member's weights beside it (`member-N.safetensors`, N its init seed) listed in
/// `members`. Fails, naming the folder and the field, when two members differ in anything
/// but their weights.
pub fn assemble(members: &[PathBuf], out: &Path) -> anyhow::Result<ModelCard> {
    anyhow::ensure!(
        members.len() >= 2,
        "--ensemble needs at least two model folders, got {}",
        members.len()
    );
    let cards: Vec<ModelCard> = members
        .iter()
        .map(|m| ModelCard::load(&m.join("card.toml")))
        .collect::<anyhow::Result<_>>()?;
    let first = &cards[0];
    for (dir, c) in members.iter().zip(&cards).skip(1) {
        let differs = [
            ("feature_set", c.feature_set != first.feature_set),
            ("window", c.window != first.window),
            ("rate_hz", c.rate_hz != first.rate_hz),
            ("target_lag", c.target_lag != first.target_lag),
            ("readout", c.readout != first.readout),
            ("feature_mean", c.feature_mean != first.feature_mean),
            ("feature_std", c.feature_std != first.feature_std),
            ("power_scale_w", c.power_scale_w != first.power_scale_w),
            ("hidden", c.hidden != first.hidden),
            ("layers", c.layers != first.layers),
            ("band_quantiles", c.band_quantiles != first.band_quantiles),
            (
                "training.relative_loss",
                c.training.relative_loss != first.training.relative_loss,
            ),
            (
                "training.plateau_decay",
                c.training.plateau_decay != first.training.plateau_decay,
            ),
            (
                "training.train_flights",
                c.training.train_flights != first.training.train_flights,
            ),
            (
                "training.validation_flights",
                c.training.validation_flights != first.training.validation_flights,
            ),
        ];
        if let Some((field, _)) = differs.iter().find(|(_, d)| *d) {
            anyhow::bail!(
                "{}: `{field}` differs from {}'s: ensemble members must differ only in their weights (train them with one --seed and different --init-seed)",
                dir.join("card.toml").display(),
                members[0].display()
            );
        }
    }
    std::fs::create_dir_all(out)
        .with_context(|| format!("{}: cannot create output folder", out.display()))?;
    let mut files = Vec::new();
    for (dir, c) in members.iter().zip(&cards) {
        anyhow::ensure!(
            c.weights_format == WeightsFormat::Safetensors && c.members.is_empty(),
            "{}: a member must be one network in safetensors",
            dir.display()
        );
        let seed = c.training.init_seed.unwrap_or(c.training.seed);
        let name = format!("member-{seed}.safetensors");
        anyhow::ensure!(
            !files.contains(&name),
            "{}: two members with init seed {seed}",
            dir.display()
        );
        let from = dir.join(&c.weights);
        std::fs::copy(&from, out.join(&name))
            .with_context(|| format!("{}: cannot copy into {}", from.display(), out.display()))?;
        files.push(name);
    }
    let mut card = first.clone();
    card.weights = files.remove(0);
    card.members = files;
    card.band_widen_w = 0.0;
    card.metrics = None;
    card.validation_metrics = None;
    card.training.train_time_s = cards.iter().map(|c| c.training.train_time_s).sum();
    card.save(&out.join("card.toml"))?;
    println!(
        "ensemble of {} members written to {}",
        members.len(),
        out.display()
    );
    Ok(card)
}
