//! The markdown table `battery-eval` prints and the book includes: the pack model's figures
//! on the data set's flights beside its targets and the baselines.

use super::*;

/// The printed table: per figure the training and test medians, the target and the truth.
pub fn table(r: &BatteryEvalReport) -> String {
    let mut s = String::new();
    let (a, b) = (&r.train, &r.test);
    header(&mut s, r);
    energy_rows(&mut s, a, b);
    voltage_rows(&mut s, a, b);
    crossing_rows(&mut s, a, b);
    landing_rows(&mut s, a, b);
    crossing_counts(&mut s, a, b);
    s
}

/// What was scored and how: the data, the flights, the carry-over, the forecasts' power,
/// the relaxation fit; then the columns' header.
fn header(s: &mut String, r: &BatteryEvalReport) {
    let (a, b) = (&r.train, &r.test);
    let _ = writeln!(s, "battery-eval: TB48D pack model, shipped constants (fitted on training flights by lab/scripts/battery/fit.py)");
    let _ = writeln!(s, "data: {}", r.data);
    let _ = writeln!(
        s,
        "flights under load (rest V at both ends): training {} ({}), test {} ({}): {:?}",
        a.n_flights, a.n_rest, b.n_flights, b.n_rest, r.test_flights
    );
    let _ = writeln!(s, "heat proxy carried over {}", r.heat_carry_over);
    let _ = writeln!(s, "voltage forecasts: {}", r.power_profile);
    let x = &r.relax;
    let _ = writeln!(
        s,
        "end rest V relaxation v += k·slope + c: shipped k = {:.2} s, c = {:.1} mV; refit here on {} training pairs k = {:.2} s, c = {:.1} mV; test pairs error {:?} mV",
        x.shipped_k_s,
        1e3 * x.shipped_c_v,
        x.n_pairs,
        x.refit_k_s,
        1e3 * x.refit_c_v,
        x.test_pairs_err_v.iter().map(|e| (e * 1e3).round()).collect::<Vec<_>>()
    );
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "{:<62} {:>9} {:>9} {:>8} {:<7} truth",
        "figure (median over flights of |error|)", "train", "test", "target", ""
    );
}

/// One figure's row: the training and test medians, the target (if `key` has one) and
/// whether the test median meets it, and what the figure is scored against.
fn row(s: &mut String, name: &str, key: &str, tr: f64, te: f64, truth: &str) {
    let target = |k: &str| TARGETS.iter().find(|t| t.0 == k).map(|t| t.1);
    let (tg, ok) = match target(key) {
        Some(t) => (format!("≤ {t:.2}"), if te <= t { "ok" } else { "MISSED" }),
        None => (String::new(), ""),
    };
    let _ = writeln!(s, "{name:<62} {tr:>9.3} {te:>9.3} {tg:>8} {ok:<7} {truth}");
}

/// Energy between the rest voltages and the start energy, beside the autopilots' rules.
fn energy_rows(s: &mut String, a: &SetSummary, b: &SetSummary) {
    row(
        s,
        "energy between rest voltages, OCV curve (Wh)",
        "ocv_energy_mae_wh",
        a.ocv_energy_mae_wh,
        b.ocv_energy_mae_wh,
        "measured ∫V·I",
    );
    row(
        s,
        "  baseline PX4 linear 3.6→4.05 V/cell × 129.96 Wh (Wh)",
        "",
        a.px4_36_energy_mae_wh,
        b.px4_36_energy_mae_wh,
        "measured ∫V·I",
    );
    row(
        s,
        "  baseline PX4 older 3.5→4.05 V/cell rule (Wh)",
        "",
        a.px4_35_energy_mae_wh,
        b.px4_35_energy_mae_wh,
        "measured ∫V·I",
    );
    row(
        s,
        "end rest V from start rest V + measured energy (V)",
        "ocv_end_v_mae_v",
        a.ocv_end_v_mae_v,
        b.ocv_end_v_mae_v,
        "end rest V (relaxation-corrected)",
    );
    row(
        s,
        "  baseline full pack at take-off, 129.96 Wh (start Wh)",
        "",
        a.full_pack_start_energy_err_wh,
        b.full_pack_start_energy_err_wh,
        "our OCV curve at start rest V (model-based)",
    );
    row(
        s,
        "  baseline PX4 SoC × 129.96 Wh at start (Wh)",
        "",
        a.px4_start_energy_err_wh,
        b.px4_start_energy_err_wh,
        "our OCV curve at start rest V (model-based)",
    );
    row(
        s,
        "  baseline ArduPilot full at boot, 5700 mAh (mAh)",
        "",
        a.ardupilot_start_mah_err,
        b.ardupilot_start_mah_err,
        "our OCV curve at start rest V (model-based)",
    );
}

/// The loaded voltage: open loop, the online estimator, the lowest voltage forecast.
fn voltage_rows(s: &mut String, a: &SetSummary, b: &SetSummary) {
    row(
        s,
        "loaded V RMSE, open loop, I > 3 A (V)",
        "ecm_median_rmse_v",
        a.ecm_median_rmse_v,
        b.ecm_median_rmse_v,
        "measured V",
    );
    row(
        s,
        "loaded V RMSE, online estimator, one-step a-priori (V)",
        "",
        a.online_onestep_rmse_v,
        b.online_onestep_rmse_v,
        "measured V",
    );
    row(
        s,
        "loaded V RMSE, online, 10 s ahead with measured current (V)",
        "",
        a.online_10s_rmse_v,
        b.online_10s_rmse_v,
        "measured V",
    );
    row(
        s,
        "lowest loaded V, pre-flight, the plan's power (V)",
        "preflight_plan_min_v_mae",
        a.preflight_plan_min_v_mae,
        b.preflight_plan_min_v_mae,
        "measured lowest V (I > 3 A)",
    );
    row(
        s,
        "lowest loaded V, pre-flight, measured power (V)",
        "",
        a.preflight_min_v_mae,
        b.preflight_min_v_mae,
        "measured lowest V (I > 3 A)",
    );
    row(
        s,
        "lowest loaded V, pre-flight, 5-s-averaged power (V)",
        "",
        a.preflight_ma5_min_v_mae,
        b.preflight_ma5_min_v_mae,
        "measured lowest V (I > 3 A)",
    );
    row(
        s,
        "lowest loaded V from half time, measured power (V)",
        "halftime_min_v_mae",
        a.halftime_min_v_mae,
        b.halftime_min_v_mae,
        "measured lowest V after half time",
    );
    row(
        s,
        "lowest loaded V from half time, the plan's rest (V)",
        "",
        a.halftime_plan_min_v_mae,
        b.halftime_plan_min_v_mae,
        "measured lowest V after half time",
    );
}

/// The first 3.5 V/cell crossing: forecast, beside the autopilots' warnings.
fn crossing_rows(s: &mut String, a: &SetSummary, b: &SetSummary) {
    row(
        s,
        "first 3.5 V/cell crossing from half time (s)",
        "",
        a.cross35_halftime_mae_s,
        b.cross35_halftime_mae_s,
        "measured first crossing (I > 3 A)",
    );
    row(
        s,
        "first 3.5 V/cell crossing, pre-flight (s)",
        "",
        a.cross35_preflight_mae_s,
        b.cross35_preflight_mae_s,
        "measured first crossing (I > 3 A)",
    );
    row(
        s,
        "  baseline PX4 low warning, SoC < 15 % (s)",
        "",
        a.cross35_px4_low_mae_s,
        b.cross35_px4_low_mae_s,
        "measured first crossing (I > 3 A)",
    );
    row(
        s,
        "  baseline ArduPilot failsafe, 10 s under 21.0 V (s)",
        "",
        a.cross35_ardupilot_fs_mae_s,
        b.cross35_ardupilot_fs_mae_s,
        "measured first crossing (I > 3 A)",
    );
}

/// At the last in-flight sample: the resting voltage read under load and the energy left.
fn landing_rows(s: &mut String, a: &SetSummary, b: &SetSummary) {
    row(
        s,
        "rest V read at the last in-flight sample, ours (V)",
        "",
        a.rest_under_load_ours_mae_v,
        b.rest_under_load_ours_mae_v,
        "end rest V (relaxation-corrected)",
    );
    row(
        s,
        "  baseline PX4 (V/cell + R·I, RLS R, τ 1 s) (V)",
        "",
        a.rest_under_load_px4_mae_v,
        b.rest_under_load_px4_mae_v,
        "end rest V (relaxation-corrected)",
    );
    row(
        s,
        "  baseline ArduPilot (voltage_resting_estimate) (V)",
        "",
        a.rest_under_load_ardupilot_mae_v,
        b.rest_under_load_ardupilot_mae_v,
        "end rest V (relaxation-corrected)",
    );
    let landing = "our OCV curve at end rest V (model-based)";
    row(
        s,
        "energy left at the last in-flight sample, ours (Wh)",
        "",
        a.landing_energy_ours_mae_wh,
        b.landing_energy_ours_mae_wh,
        landing,
    );
    row(
        s,
        "  baseline PX4 SoC (RLS, 2 s start, fused) × 129.96 Wh (Wh)",
        "",
        a.landing_energy_px4_mae_wh,
        b.landing_energy_px4_mae_wh,
        landing,
    );
    row(
        s,
        "  baseline ArduPilot full at boot − mAh × 129.96 Wh (Wh)",
        "",
        a.landing_energy_ardupilot_mae_wh,
        b.landing_energy_ardupilot_mae_wh,
        landing,
    );
    row(
        s,
        "  baseline full pack at take-off − energy used (Wh)",
        "",
        a.landing_energy_full_pack_mae_wh,
        b.landing_energy_full_pack_mae_wh,
        landing,
    );
}

/// How many flights cross 3.5 V/cell, and how many each forecast and rule missed.
fn crossing_counts(s: &mut String, a: &SetSummary, b: &SetSummary) {
    for (name, x) in [("training", a), ("test", b)] {
        let _ = writeln!(
            s,
            "3.5 V/cell crossings, {name}: {} flights cross; from half time {} cross after it, {} not forecast at all; pre-flight {} not forecast at all; PX4's low warning never raised on {}, ArduPilot's failsafe never on {}",
            x.n_cross, x.n_cross_after_half, x.cross35_halftime_missed, x.cross35_preflight_missed,
            x.cross35_px4_low_missed, x.cross35_ardupilot_fs_missed
        );
    }
}
