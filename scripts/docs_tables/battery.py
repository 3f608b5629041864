"""The `battery-eval` tables: the figures against their targets (battery-eval.md) and the
pack model's parameters (battery-params.md)."""
from .common import f, header, table


# (label, key, digits, truth) in the order `battery-eval` prints them; key of TARGETS
# where the figure has a target. Mirrors src/offline/battery_eval/mod.rs `table`.
BATTERY_ROWS = [
    ("energy between rest voltages, OCV curve (Wh)", "ocv_energy_mae_wh", 2, "measured ∫V·I"),
    ("  baseline PX4 linear 3.6→4.05 V/cell × 129.96 Wh (Wh)", "px4_36_energy_mae_wh", 2, "measured ∫V·I"),
    ("  baseline PX4 older 3.5→4.05 V/cell rule (Wh)", "px4_35_energy_mae_wh", 2, "measured ∫V·I"),
    ("end rest V from start rest V + measured energy (V)", "ocv_end_v_mae_v", 3, "end rest V (relaxation-corrected)"),
    ("  baseline full pack at take-off, 129.96 Wh (start Wh)", "full_pack_start_energy_err_wh", 2, "our OCV curve at start rest V (model-based)"),
    ("  baseline PX4 SoC × 129.96 Wh at start (Wh)", "px4_start_energy_err_wh", 2, "our OCV curve at start rest V (model-based)"),
    ("  baseline ArduPilot full at boot, 5700 mAh (mAh)", "ardupilot_start_mah_err", 0, "our OCV curve at start rest V (model-based)"),
    ("loaded V RMSE, open loop, I > 3 A (V)", "ecm_median_rmse_v", 3, "measured V"),
    ("loaded V RMSE, online estimator, one-step a-priori (V)", "online_onestep_rmse_v", 3, "measured V"),
    ("loaded V RMSE, online, 10 s ahead with measured current (V)", "online_10s_rmse_v", 3, "measured V"),
    ("lowest loaded V, pre-flight, the plan's power (V)", "preflight_plan_min_v_mae", 3, "measured lowest V (I > 3 A)"),
    ("lowest loaded V, pre-flight, measured power (V)", "preflight_min_v_mae", 3, "measured lowest V (I > 3 A)"),
    ("lowest loaded V, pre-flight, 5-s-averaged power (V)", "preflight_ma5_min_v_mae", 3, "measured lowest V (I > 3 A)"),
    ("lowest loaded V from half time, measured power (V)", "halftime_min_v_mae", 3, "measured lowest V after half time"),
    ("lowest loaded V from half time, the plan's rest (V)", "halftime_plan_min_v_mae", 3, "measured lowest V after half time"),
    ("first 3.5 V/cell crossing from half time (s)", "cross35_halftime_mae_s", 1, "measured first crossing (I > 3 A)"),
    ("first 3.5 V/cell crossing, pre-flight (s)", "cross35_preflight_mae_s", 1, "measured first crossing (I > 3 A)"),
    ("  baseline PX4 low warning, SoC < 15 % (s)", "cross35_px4_low_mae_s", 1, "measured first crossing (I > 3 A)"),
    ("  baseline ArduPilot failsafe, 10 s under 21.0 V (s)", "cross35_ardupilot_fs_mae_s", 1, "measured first crossing (I > 3 A)"),
    ("rest V read at the last in-flight sample, ours (V)", "rest_under_load_ours_mae_v", 3, "end rest V (relaxation-corrected)"),
    ("  baseline PX4 (V/cell + R·I, RLS R, τ 1 s) (V)", "rest_under_load_px4_mae_v", 3, "end rest V (relaxation-corrected)"),
    ("  baseline ArduPilot (voltage_resting_estimate) (V)", "rest_under_load_ardupilot_mae_v", 3, "end rest V (relaxation-corrected)"),
    ("energy left at the last in-flight sample, ours (Wh)", "landing_energy_ours_mae_wh", 2, "our OCV curve at end rest V (model-based)"),
    ("  baseline PX4 SoC (RLS, 2 s start, fused) × 129.96 Wh (Wh)", "landing_energy_px4_mae_wh", 2, "our OCV curve at end rest V (model-based)"),
    ("  baseline ArduPilot full at boot − mAh × 129.96 Wh (Wh)", "landing_energy_ardupilot_mae_wh", 2, "our OCV curve at end rest V (model-based)"),
    ("  baseline full pack at take-off − energy used (Wh)", "landing_energy_full_pack_mae_wh", 2, "our OCV curve at end rest V (model-based)"),
]


def battery_eval(r):
    tr, te, targets = r["train"], r["test"], r.get("targets", {})
    rows = []
    for label, key, nd, truth in BATTERY_ROWS:
        base = label.startswith("  ")
        name = ("↳ " + label.strip()) if base else label
        t = targets.get(key)
        if t is None:
            tg, ok = "", ""
        else:
            tg = f"≤ {t:.2f}"
            ok = "met" if te[key] <= t else "**missed**"
        val = f(te[key], nd)
        rows.append([name, f(tr[key], nd), f"**{val}**" if t is not None else val, tg, ok, truth])
    md = header("battery-eval --json -")
    md += (f"Flights under load with a resting voltage at both ends: training {tr['n_flights']} "
           f"({tr['n_rest']}), test {te['n_flights']} ({te['n_rest']}); test flights "
           f"{', '.join(str(x) for x in r['test_flights'])}. Voltage forecasts: {r['power_profile']}. "
           f"Heat proxy carried over {r['heat_carry_over']}.\n\n")
    md += table(["figure (median over flights of \\|error\\|)", "training", "test", "target", "", "truth"], rows)
    md += "\n"
    for name, x in (("training", tr), ("test", te)):
        md += (f"- 3.5 V/cell crossings, {name}: {x['n_cross']} flights cross; from half time "
               f"{x['n_cross_after_half']} cross after it, {x['cross35_halftime_missed']} not forecast at all; "
               f"pre-flight {x['cross35_preflight_missed']} not forecast at all; PX4's low warning never raised "
               f"on {x['cross35_px4_low_missed']}, ArduPilot's failsafe never on {x['cross35_ardupilot_fs_missed']}.\n")
    x = r["relax"]
    errs = ", ".join(f"{1e3 * e:+.0f}" for e in x["test_pairs_err_v"])
    md += (f"- End resting voltage relaxation correction v += k·slope + c: shipped k = {x['shipped_k_s']:.2f} s, "
           f"c = {1e3 * x['shipped_c_v']:.1f} mV; refitted here on {x['n_pairs']} training pairs "
           f"k = {x['refit_k_s']:.2f} s, c = {1e3 * x['refit_c_v']:.1f} mV; test pairs' error {errs} mV.\n")
    return md


def battery_params(r):
    p = r["params"]
    md = header("battery-eval --json -")
    names = {
        "n_cells": ("cells in series", ""),
        "r0_ohm": ("R0, ohmic resistance when warm", "Ω"),
        "r1_ohm": ("R1, polarisation resistance", "Ω"),
        "tau1_s": ("τ1, polarisation time constant", "s"),
        "warm_a": ("a, cold-pack resistance excess", ""),
        "heat_scale_a2s": ("Hs, heat scale", "A²·s"),
        "tau_heat_s": ("τh, heat proxy time constant", "s"),
        "bias_v": ("b, loaded-voltage offset", "V"),
        "lambda": ("RLS forgetting factor", ""),
    }
    rows = []
    for k, v in p.items():
        label, unit = names.get(k, (k, ""))
        val = str(v) if isinstance(v, int) else ("off" if v is None else f"{v:.6g}")
        rows.append([label, f"`{k}`", val, unit])
    md += table(["parameter", "JSON", "value", "unit"], rows)
    cv, ce = r.get("curve_v_cell", []), r.get("curve_energy_wh", [])
    if cv and ce:
        md += "\nThe TB48D OCV table (energy above the 3.30 V/cell floor):\n\n"
        md += table(["V a cell"] + [f"{v:.2f}" for v in cv], [["Wh"] + [f"{e:.1f}" for e in ce]])
    return md
