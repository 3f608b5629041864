//! What `learn` writes beside the profile: the held-out table and the model card.

use super::*;

pub(super) fn held_out_table(scores: &[LogScore]) -> String {
    let mut s = String::new();
    for l in scores {
        s += &format!(
            "held out: {} ({} in-flight windows)\n",
            l.log, l.in_flight_windows
        );
        s += "| model | MAPE % published | MAPE % learned | energy % published | energy % learned |\n|---|---|---|---|---|\n";
        for (name, b, a) in &l.rows {
            let f = |v: Option<f64>| v.map_or("—".to_string(), |v| format!("{v:.1}"));
            s += &format!(
                "| {name} | {} | {} | {} | {} |\n",
                f(b.map(|x| x.mape_pct)),
                f(a.map(|x| x.mape_pct)),
                f(b.map(|x| x.energy_err_pct)),
                f(a.map(|x| x.energy_err_pct))
            );
        }
    }
    s
}

pub(super) fn model_card(
    base: &VehicleProfile,
    logs: &[PathBuf],
    in_flight: &[usize],
    held: &[usize],
    scores: &[LogScore],
    tuned: Option<&FineTuned>,
) -> String {
    let mut s = String::from("# Model card: physics models learned by `dronewatt learn`\n\n");
    s += &format!("Started from the profile **{}**; the physics models' free parameters (see `dronewatt-lab calibrate`) fitted by bounded least squares on the in-flight windows flown on rotors (measured power over {:.0} W: 100 W, or half the hover the profile gives when that is lower) of the training logs; the fixed-wing model's four coefficients (C_D0, e, η, P_0 with the wing's geometry and mass kept) on the windows flown on a wing with the motor running and the airspeed 1.2 × the stall speed or more (`model::physics::fixed_wing::fit`).\n\n", base.name, crate::offline::metrics::in_flight_w_for(base));
    s += "## Learned from\n\n| log | in-flight windows | role |\n|---|---|---|\n";
    for (i, p) in logs.iter().enumerate() {
        s += &format!(
            "| {} | {} | {} |\n",
            p.display(),
            in_flight[i],
            if held.contains(&i) {
                "held out (score)"
            } else {
                "training"
            }
        );
    }
    s += "\n## Inputs\n\nWhat the live link must deliver, as for every physics model: position and velocity (GLOBAL_POSITION_INT or LOCAL_POSITION_NED), attitude (ATTITUDE), acceleration (RAW_IMU/SCALED_IMU/HIGHRES_IMU or attitude), wind where sent (WIND, else none), and for the score and for adaptation the battery's voltage and current (SYS_STATUS or BATTERY_STATUS). No motor outputs, ESC telemetry or throttle.\n\n";
    s += "## Held-out score (whole logs, through the live chain)\n\n";
    s += &held_out_table(scores);
    match tuned {
        Some(t) => {
            s += &format!(
                "\n## LSTM fine-tuned (`lstm_ft`)\n\nFrom the shipped M100 weights, on the training logs' windows (the live feature path, the M100 model's feature normalisation and target scale kept), Adam, early stopping on the held-out logs' MAE: {} epoch(s) run, epoch {} kept ({}), held-out MAE {:.1} W → {:.1} W, {} training windows, {:.0} s. Weights and card in `lstm/` (the profile's `lstm`); its rows in the held-out table above are `lstm` (shipped → fine-tuned). The held-out log also chose the epoch, so its score is optimistic: score an unseen log with `replay --vehicle`.\n",
                t.epochs_run,
                t.best_epoch,
                if t.best_epoch == 0 { "none beat the shipped weights: they are kept" } else { "the lowest held-out MAE" },
                t.held_out_mae_w.0,
                t.held_out_mae_w.1,
                t.train_windows,
                t.train_time_s
            );
        }
        None => s += "\n## Not learned\n\nThe LSTM is not fine-tuned by `learn` without `--fine-tune` (it keeps the M100 weights; online adaptation corrects its output in flight).\n",
    }
    s
}
