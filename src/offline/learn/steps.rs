//! The steps of `dronewatt learn` after the logs are read: the fixed-wing fit, the LSTM's
//! fine-tuning, the held-out scores, the forecast model picked, the profile written.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use super::*;

/// The fixed-wing model fitted on the training windows flown on a wing (20 at least),
/// into the learned profile and the fit's report.
pub(super) fn fit_wing(
    wing0: &physics::fixed_wing::Params,
    wing_train: &[([f64; 4], f64)],
    learned: &mut VehicleProfile,
    fit_report: &mut Vec<crate::offline::fit::FitReport>,
) {
    let wing_fit = crate::model::physics::fixed_wing::fit(wing0, wing_train);
    if let Some(f) = &wing_fit {
        learned.fixed_wing = Some(f.params);
        fit_report.push(crate::offline::fit::FitReport {
            model: "fixed_wing",
            rmse_before_w: f.rmse_before_w,
            rmse_after_w: f.rmse_after_w,
        });
        tracing::info!(
            windows = f.windows,
            "fixed_wing fitted: C_D0 {:.4} → {:.4}, e {:.2} → {:.2}, η {:.2} → {:.2}, P_0 {:.1} → {:.1} W{}",
            wing0.cd0,
            f.params.cd0,
            wing0.oswald_e,
            f.params.oswald_e,
            wing0.eta,
            f.params.eta,
            wing0.offset_w,
            f.params.offset_w,
            if f.clamped.is_empty() {
                String::new()
            } else {
                format!(" (held at the edge of its range: {})", f.clamped.join(", "))
            }
        );
    } else if !wing_train.is_empty() {
        tracing::warn!("{} training windows flown on a wing: too few to fit the fixed-wing model (20 at least)", wing_train.len());
    }
}

/// The LSTM fine-tuned from the shipped (or `--ft-from`) weights on the training logs,
/// early-stopping on the held-out ones: its folder and what the fine-tuning did.
pub(super) fn fine_tune_lstm(
    fine_tune: FineTuner,
    args: &LearnArgs,
    cfg: &Config,
    flights: &[(&PathBuf, FlightWindows, usize)],
    held: &[usize],
    train: &[FlightWindows],
) -> Result<(PathBuf, FineTuned)> {
    use crate::model::lstm::{find_model_dir, resolve_model_path, PAPER_MODEL_DIR};
    let shipped = args
        .ft_from
        .clone()
        .or_else(|| cfg.models.lstm.path.clone())
        .or_else(|| find_model_dir(PAPER_MODEL_DIR))
        .or_else(|| resolve_model_path(None))
        .context("no LSTM model to fine-tune from (give --ft-from)")?;
    let held_windows: Vec<FlightWindows> = held.iter().map(|&i| flights[i].1.clone()).collect();
    let out = args.out.join("lstm");
    std::fs::create_dir_all(&out).with_context(|| format!("{}: cannot create", out.display()))?;
    let train_logs = flights
        .iter()
        .enumerate()
        .filter(|(i, _)| !held.contains(i))
        .map(|(_, (p, _, _))| p.display().to_string())
        .collect();
    let job = FineTuneJob {
        base: &shipped,
        train,
        held_out: &held_windows,
        out: &out,
        epochs: args.ft_epochs,
        max_steps: args.ft_max_steps,
        lr: args.ft_lr,
        patience: args.ft_patience,
        dropout: args.ft_dropout,
        logs: train_logs,
    };
    let done = fine_tune(&job)?;
    tracing::info!(
        "LSTM fine-tuned: {} epoch(s), kept epoch {}, held-out MAE {:.1} → {:.1} W",
        done.epochs_run,
        done.best_epoch,
        done.held_out_mae_w.0,
        done.held_out_mae_w.1
    );
    Ok((out, done))
}

/// The held-out logs and what scoring them needs.
pub(super) struct HeldOut<'a> {
    pub(super) flights: &'a [(&'a PathBuf, FlightWindows, usize)],
    pub(super) wings: &'a [FlightWindows],
    pub(super) held: &'a [usize],
    pub(super) wing0: physics::fixed_wing::Params,
    pub(super) in_flight_w: f64,
}

/// Each held-out log scored before (the base profile) and after (the learned one, with the
/// fine-tuned LSTM where there is one): the rotor models on its windows, the fixed-wing
/// model on its wing samples.
pub(super) fn score_held(
    cfg: &Config,
    base: &VehicleProfile,
    learned: &VehicleProfile,
    tuned_dir: Option<&Path>,
    h: &HeldOut,
) -> Result<Vec<LogScore>> {
    let HeldOut {
        flights,
        wings,
        held,
        wing0,
        in_flight_w,
    } = h;
    let mut scores = Vec::new();
    for &i in held.iter() {
        let (p, f, n) = &flights[i];
        let mut rows = Vec::new();
        if !f.windows.is_empty() {
            let before = score(cfg, base, None, f, *in_flight_w)?;
            let after = score(cfg, learned, tuned_dir, f, *in_flight_w)?;
            rows.extend(before.into_iter().map(|(name, b)| {
                let a = after.iter().find(|(n, _)| *n == name).and_then(|(_, a)| *a);
                (name, b, a)
            }));
        }
        let wing = &wings[i];
        let mask = 2.0 * wing0.offset_w;
        if let Some(b) = wing_score(wing0, mask, wing) {
            let a = wing_score(&learned.fixed_wing.unwrap_or(*wing0), mask, wing);
            rows.push(("fixed_wing".into(), Some(b), a));
        }
        scores.push(LogScore {
            log: p.display().to_string(),
            in_flight_windows: *n,
            rows,
        });
    }
    Ok(scores)
}

/// The learned profile's forecast model: the lowest mean held-out MAPE of the learned
/// models (`tuned`: the LSTM was fine-tuned; `held`: how many logs were held out).
pub(super) fn set_forecast(
    learned: &mut VehicleProfile,
    scores: &[LogScore],
    tuned: bool,
    held: usize,
) {
    let pick = pick_forecast(scores);
    if let Some((name, mape)) = &pick {
        let model = match (name.as_str(), tuned) {
            ("lstm", true) => "lstm_ft".to_string(),
            ("lstm" | "fixed_wing", _) => name.clone(),
            _ => format!("{name}{}", learned.name_suffix()),
        };
        learned.forecast = Some(crate::model::profile::ForecastDefault {
            model,
            why: format!(
                "lowest held-out MAPE of `dronewatt learn`, {mape:.1} % over {} log(s)",
                held
            ),
            scale: Default::default(),
            p90_ratio: None,
        });
    }
}

/// The learned profile, under its header and the training RMSE of each fitted model.
pub(super) fn write_profile(
    profile_path: &Path,
    header: String,
    fit_report: &[crate::offline::fit::FitReport],
    learned: &VehicleProfile,
) -> Result<()> {
    let mut text = header;
    text.push_str("# Training RMSE, W (published → learned):\n");
    for r in fit_report {
        text.push_str(&format!(
            "#   {:<18} {:>8.1} → {:>6.1}\n",
            r.model, r.rmse_before_w, r.rmse_after_w
        ));
    }
    text.push_str(&toml::to_string(learned).context("cannot serialise the learned profile")?);
    std::fs::write(profile_path, text)
        .with_context(|| format!("{}: cannot write", profile_path.display()))?;
    Ok(())
}

/// What `learn` learned, for the profile and the model card.
pub(super) struct Learned<'a> {
    pub(super) base: &'a VehicleProfile,
    pub(super) logs: &'a [PathBuf],
    pub(super) held_out: &'a HeldOut<'a>,
    pub(super) scores: &'a [LogScore],
    pub(super) tuned: Option<&'a FineTuned>,
    pub(super) fit_report: &'a [crate::offline::fit::FitReport],
    pub(super) learned: &'a VehicleProfile,
}

/// The profile (under `header`) and the model card written into `--out`, the held-out
/// table printed, and the profile kept in the vehicle store.
pub(super) fn write_learned(args: &LearnArgs, header: String, l: &Learned) -> Result<()> {
    let Learned {
        base,
        logs,
        held_out,
        scores,
        tuned,
        fit_report,
        learned,
    } = l;
    let profile_path = args.out.join("profile.toml");
    write_profile(&profile_path, header, fit_report, learned)?;
    let card_path = args.out.join("model-card.md");
    let mut card = model_card(
        base,
        logs,
        &held_out
            .flights
            .iter()
            .map(|(_, _, n)| *n)
            .collect::<Vec<_>>(),
        held_out.held,
        scores,
        *tuned,
    );
    if let Some(f) = &learned.forecast {
        card += &format!("\n## Forecast model\n\n`{}`: {} (written to the profile's `[forecast]`; `[energy] model` in the config overrides it, and online selection may still move it on the vehicle's own evidence).\n", f.model, f.why);
    }
    std::fs::write(&card_path, &card)
        .with_context(|| format!("{}: cannot write", card_path.display()))?;
    print!("{}", held_out_table(scores));
    if let Some(f) = &learned.forecast {
        println!("forecast model: {} ({})", f.model, f.why);
    }
    println!(
        "wrote {} and {}",
        profile_path.display(),
        card_path.display()
    );
    if let Some(dir) = crate::vehicle::store::data_dir_from_env(args.data_dir.as_deref()) {
        remember_profile(
            &dir,
            logs,
            &profile_path,
            learned.forecast.as_ref().map(|f| f.model.as_str()),
        );
    }
    Ok(())
}
