#!/usr/bin/env python3
"""Write the book's results tables (docs/src/generated/*.md) from the commands' --json.

The tables in the book are never typed by hand: a refit changes the JSON, this script
rewrites the tables, and `make docs` builds them in. The generated files are committed,
so the book builds without the data set.

    scripts/docs-tables.py                 # run the commands (binary + data set needed)
    scripts/docs-tables.py --if-available  # what `make docs` runs: refresh when the binary is
                                           # up to date with src/ and the data set is there,
                                           # else keep the committed tables (with a note)
    scripts/docs-tables.py --no-eval       # skip `eval --split cvar`
    scripts/docs-tables.py --from-json DIR # read DIR/battery-eval.json, DIR/plan-eval.json,
                                           # DIR/eval-cvar.json instead of running anything
    scripts/docs-tables.py --check         # write nothing: fail when a committed table or a
                                           # figure in the README's "Headline figures" is not
                                           # what the commands print now (`make test` runs it
                                           # with --if-available)

The README's headline figures are prose, written by hand, so they are checked instead of
written: `readme_claims` says, per command, which figure must stand there and how it is
rounded.

The LightGBM tables (lgbm-cv.md, lgbm-test.md) are always written from the committed
docs/src/generated/lgbm-cv.json (`lab/scripts/lgbm_cv.py`'s --json; half an hour to tune, so
not rerun here) and, for the LSTM's rows, the model cards and `cv.csv` of
config/models/lstm-m100 (shipped) and config/models/lstm-m100-h128 (the paper's network).

The binary is $DRONEWATT_BIN, else ${CARGO_TARGET_DIR:-target}/debug/dronewatt-lab, the lab's
(build it with `make docs-tables`, which runs `cargo build --locked --bin dronewatt-lab` first). The data
set is $DRONEWATT_DATA, else ../shared/data/m100/flights.csv.gz. Each command's JSON is
also kept in ${CARGO_TARGET_DIR:-target}/docs-json/ for a later --from-json.
"""

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

from docs_tables_common import OUT, ROOT, f, header, note, table
from docs_tables_spec import spec_tables

# (file stem, command line after the binary). All three take ~9 s together in a dev build.
COMMANDS = {
    "battery-eval": ["battery-eval", "--json", "-"],
    "plan-eval": ["plan-eval", "--json", "-"],
    "eval-cvar": ["eval", "--split", "cvar", "--json", "-"],
}


# ---------------------------------------------------------------- battery-eval

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


# ---------------------------------------------------------------- plan-eval

def plan_eval_flights(r):
    rows = []
    for x in r["test_flights"]:
        g = x["payload_g"]
        rows.append([
            x["flight"], x["route"], f"{x['speed_m_s']:g}", f"{g:g}", x["altitude"], x["geometry_from"],
            f"{x['airborne_s']:.0f} / {x['planned_s']:.0f}",
            f(x["measured_wh"]), f(x["p50_wh"]), f(x["p90_wh"]), f(x["preflight_err_pct"]),
            "yes" if x["p90_covers"] else "no", f(x["baseline_preflight_err_pct"]),
            f(x["live_measured_rest_wh"]), f(x["live_forecast_rest_wh"]), f(x["live_err_pct"]),
            f(x["baseline_gcs_err_pct"]), f(x["baseline_err_pct"]),
        ])
    md = header("plan-eval --json -")
    md += table(["flight", "route", "m/s", "g", "alt m", "waypoints from", "airborne / planned s",
                 "measured Wh", "P50 Wh", "P90 Wh", "pre-flight err %", "P90 covers",
                 "baseline pre-flight err %", "rest measured Wh", "rest forecast Wh", "live err %",
                 "baseline live err %, ground station's clock", "baseline live err %, dronewatt's clock"], rows)
    return md


def plan_eval_targets(r):
    te, tr = r["test"], r["training"]

    def met(ok, extra=""):
        return ("met" if ok else "**missed**") + extra

    worst = max(r["test_flights"], key=lambda x: x["preflight_err_pct"])
    worst_at = ": " + worst["route"] + " flight " + str(worst["flight"])
    rows = [
        ["pre-flight median error", "≤ 3 %",
         f"**{te['preflight_median_err_pct']:.2f} %** ({met(te['preflight_median_err_pct'] <= 3)})",
         f"{tr['preflight_median_err_pct']:.2f} %"],
        ["pre-flight max error", "≤ 8 %",
         f"**{te['preflight_max_err_pct']:.2f} %** ({met(te['preflight_max_err_pct'] <= 8, worst_at)})",
         f"{tr['preflight_max_err_pct']:.1f} %"],
        ["P90 covers measured", "≥ 85 %",
         f"**{te['p90_coverage_pct']:.0f} %** ({met(te['p90_coverage_pct'] >= 85)})",
         f"{tr['p90_coverage_pct']:.0f} %"],
        ["live at 50 %, remaining-energy median error (issue 25)", "≤ 1.5 %",
         f"**{te['live_median_err_pct']:.2f} %** ({met(te['live_median_err_pct'] <= 1.5)})",
         f"{tr['live_median_err_pct']:.2f} %"],
        ["baseline live, the ground station's clock", "2×",
         f"{te['baseline_gcs_live_median_err_pct']:.1f} % (dronewatt **{te['live_advantage_gcs']:.0f}×**: {met(te['live_advantage_gcs'] >= 2)})",
         f"{tr['baseline_gcs_live_median_err_pct']:.1f} % ({tr['live_advantage_gcs']:.0f}×)"],
        ["baseline live, dronewatt's clock (issue 25)", "1.5×",
         f"{te['baseline_live_median_err_pct']:.2f} % (dronewatt **{te['live_advantage']:.1f}×**: {met(te['live_advantage'] >= 1.5)})",
         f"{tr['baseline_live_median_err_pct']:.2f} % ({tr['live_advantage']:.1f}×)"],
        ["baseline pre-flight median error", "2×",
         f"{te['baseline_preflight_median_err_pct']:.2f} % (dronewatt **{te['preflight_advantage']:.1f}×**: {met(te['preflight_advantage'] >= 2)})",
         f"{tr['baseline_preflight_median_err_pct']:.2f} % ({tr['preflight_advantage']:.1f}×)"],
    ]
    md = header("plan-eval --json -")
    md += (f"Fit on {tr['flights']} training flights, scored on {te['flights']} test flights.\n\n")
    md += table(["", "target", "test flights", "training flights"], rows)
    return md


def plan_eval_members(r):
    rows = []
    for m in r.get("members_alone", []):
        t = m["test"]
        rows.append([f"`{m['model']}`", f"{m['training_err_pct']:.2f}", f"{m['tie_share_pct']:.0f} %",
                     f"{t['preflight_median_err_pct']:.2f}", f"{t['preflight_max_err_pct']:.2f}",
                     f"{t['p90_coverage_pct']:.0f} %", f"{t['live_median_err_pct']:.2f}",
                     f"{t['baseline_live_median_err_pct']:.2f}"])
    te = r["test"]
    rows.append(["**the members' mean (shipped)**", f"{r['training']['preflight_median_err_pct']:.2f}", "—",
                 f"**{te['preflight_median_err_pct']:.2f}**", f"{te['preflight_max_err_pct']:.2f}",
                 f"{te['p90_coverage_pct']:.0f} %", f"**{te['live_median_err_pct']:.2f}**",
                 f"{te['baseline_live_median_err_pct']:.2f}"])
    md = header("plan-eval --json -")
    md += table(["member", "training median err %", "resamples no worse than the best",
                 "test pre-flight median %", "test pre-flight max %", "test P90 covers",
                 "test live median %", "baseline live (dronewatt's clock) %"], rows)
    return md


def plan_eval_routes(r):
    """The live forecast at half time per route against both baselines' clocks, the test
    flights beside the training flights' rolling validation."""
    routes = r.get("routes")
    if not routes:
        return None

    def cell(x):
        if not x:
            return ["—", "—", "—"]
        return [f"{x['live_median_err_pct']:.2f} % ({x['flights']})",
                f"{x['baseline_gcs_live_median_err_pct']:.1f} % ({x['live_advantage_gcs']:.1f}×)",
                f"{x['baseline_live_median_err_pct']:.2f} % ({x['live_advantage']:.1f}×)"]
    rows = [[rs["route"]] + cell(rs.get("test")) + cell(rs.get("training")) for rs in routes]
    md = header("plan-eval --json -")
    md += ("Live at 50 %, median error of the remaining energy per route (flights), and each baseline "
           "(mean power so far × the time left) with the ground station's clock and with dronewatt's "
           "(dronewatt's advantage); training flights by rolling validation.\n\n")
    md += table(["route", "test: dronewatt", "test: baseline, ground station's clock",
                 "test: baseline, dronewatt's clock", "training: dronewatt",
                 "training: baseline, ground station's clock", "training: baseline, dronewatt's clock"], rows)
    return md


# ---------------------------------------------------------------- eval (optional)

def eval_cvar(r):
    """Every model's mean scores over the test flights (`eval --split cvar --json -`)."""
    models = r.get("models") if isinstance(r, dict) else None
    if not isinstance(models, dict) or not models:
        return None
    rows = sorted(models.items(), key=lambda kv: kv[1]["mae_w"])
    md = header("eval --split cvar --json -")
    md += (f"Mean over the test flights {', '.join(str(x) for x in r.get('flights', []))}, "
           f"scored over {r.get('scored_over', 'in_flight').replace('_', '-')} windows "
           "(in flight: measured power > 100 W), best MAE first.\n\n")
    md += table(["model", "MAE (W)", "RMSE (W)", "in-flight MAPE %", "energy error %"],
                [[f"`{n}`", f(m["mae_w"], 1), f(m["rmse_w"], 1), f(m["mape_pct"], 1), f(m["energy_err_pct"], 1)]
                 for n, m in rows])
    return md


def best(models, published):
    """The physics model with the lowest MAE: calibrated (`_cal`) or published."""
    rows = [(k, v) for k, v in models.items()
            if k != "lstm" and k.endswith("_cal") != published]
    return min(rows, key=lambda kv: kv[1]["mae_w"])[1] if rows else None


def readme_claims(name, r):
    """The strings the README's headline figures must hold for this command's JSON."""
    if name == "plan-eval":
        t = r["test"]
        return [f"**{t['preflight_median_err_pct']:.2f} %**", f"(max {t['preflight_max_err_pct']:.2f} %)",
                f"P90 covers {t['p90_coverage_pct']:.0f} %", f"**{t['live_median_err_pct']:.2f} %**",
                f"{t['live_advantage_gcs']:.0f}×", f"**{t['live_advantage']:.1f}×**"]
    if name == "battery-eval":
        t = r["test"]
        return [f"**{t['ocv_energy_mae_wh']:.2f} Wh**", f"**{t['px4_36_energy_mae_wh']:.1f} Wh**",
                f"({t['full_pack_start_energy_err_wh']:.0f} Wh", f"**{1e3 * t['ocv_end_v_mae_v']:.0f} mV**",
                f"**{t['ecm_median_rmse_v']:.3f} V**", f"**{t['halftime_min_v_mae']:.3f} V**",
                f"{t['preflight_plan_min_v_mae']:.3f} V", f"**{t['landing_energy_ours_mae_wh']:.2f} Wh**",
                f"**{t['landing_energy_px4_mae_wh']:.1f} Wh**", f"{t['landing_energy_ardupilot_mae_wh']:.0f} Wh"]
    if name == "eval-cvar":
        m = r["models"]
        out = [f"**{m['lstm']['mape_pct']:.1f} %**", f"energy error {m['lstm']['energy_err_pct']:.1f} %"]
        for published in (False, True):
            b = best(m, published)
            if b:
                out.append(f"{b['mape_pct']:.1f} %")
        return out
    return []


def headline(readme):
    """The README's "Headline figures" section."""
    text = readme.read_text()
    start = text.find("## Headline figures")
    end = text.find("\n## ", start + 1)
    return text[start:end if end > 0 else len(text)] if start >= 0 else ""


# ---------------------------------------------------------------- LightGBM CV (committed JSON)

# `lab/scripts/lgbm_cv.py` tunes LightGBM on the LSTM's by-flight folds (half an hour on one
# core, so it is not run here): its JSON, figures only, is committed beside the tables.
LGBM_JSON = OUT / "lgbm-cv.json"
LSTM_DIR = ROOT / "config" / "models" / "lstm-m100"
LSTM_CARD = LSTM_DIR / "card.toml"
PAPER_CARD = ROOT / "config" / "models" / "lstm-m100-h128" / "card.toml"


# The ensembles shipped before this card's, by how their recipe differs from the card's (the
# labels `changes` gives) and their number of members: their rows stay in `cv.csv`, named for
# when they shipped (all on 2026-11-26, newest first).
REPLACED = {
    ((), 4): "shipped before this one",
    (("the final readout",), 3): "shipped before that",
    (("the absolute loss", "the final readout"), 3): "shipped first",
}


def lstm_cv_rows():
    """The LSTM's rows of the shipped model's `cv.csv` (`train --cv 5 --seed 7`, on LightGBM's
    folds): (name, {mae_w, mape_in_flight_pct, energy_error_pct: {mean, median}}). The row
    whose network and training match the card is the shipped one; the others are named by how
    they differ from it."""
    import csv
    import tomllib
    path = LSTM_DIR / "cv.csv"
    try:
        rows = list(csv.DictReader(path.open()))
        card = tomllib.loads(LSTM_CARD.read_text())
    except (OSError, tomllib.TOMLDecodeError) as e:
        note(f"{path}: no LSTM CV rows ({e})")
        return []
    train = card.get("training", {})
    shipped = {"hidden": str(card.get("hidden")), "stride": str(train.get("stride")),
               "relative_loss": float(train.get("relative_loss", 0)),
               "plateau_decay": float(train.get("plateau_decay", 1)),
               "members": 1 + len(card.get("members", [])), "target_lag": int(card.get("target_lag", 0)),
               "readout": card.get("readout", "final"), "trees": "trees" in card}

    def changes(r):
        # Columns added later (absent in older rows): the loss's relative weight, the plateau decay,
        # the target lag, the readout.
        c = []
        if r["stride"] != shipped["stride"]:
            c.append(f"stride {r['stride']}")
        lam = float(r.get("relative_loss") or 0)
        if lam != shipped["relative_loss"]:
            c.append(f"relative loss λ {lam:g}" if lam else "the absolute loss")
        if float(r.get("plateau_decay") or 1) != shipped["plateau_decay"]:
            c.append(f"plateau decay {float(r.get('plateau_decay') or 1):g}")
        if r.get("target_lag") and int(r["target_lag"]) != shipped["target_lag"]:
            c.append(f"target lag {int(r['target_lag'])} ({int(r['target_lag']) / 10:g} s)")
        if (r.get("readout") or "Final").lower() != shipped["readout"]:
            c.append(f"the {r['readout'].lower()} readout")
        return c

    out = []
    for r in rows:
        seeds = r.get("init_seeds", "").split(";")
        c = changes(r)
        replaced = REPLACED.get((tuple(c), len(seeds)))
        if r["hidden"] != shipped["hidden"]:
            name = (f"LSTM, one network × {r['hidden']} cells, stride {r['stride']} "
                    "(the paper's network, shipped before the ensembles)")
        elif len(seeds) > 1:
            base = f"LSTM, ensemble of {len(seeds)} × {r['hidden']} cells"
            if not c and len(seeds) == shipped["members"]:
                loss = f", relative loss λ {shipped['relative_loss']:g}" if shipped["relative_loss"] else ""
                readout = ", the instant readout" if shipped["readout"] != "final" else ""
                what = "shipped, in the blend below" if shipped["trees"] else "shipped"
                name = f"{base}, stride {r['stride']}{loss}{readout} ({what})"
            elif replaced:
                name = f"{base}, stride {r['stride']}{''.join(', ' + x for x in c)} ({replaced}, replaced)"
            else:
                what = ", ".join(c) if c else "the shipped recipe otherwise"
                name = f"{base}, {what} (candidate, not shipped)"
        elif not c:
            name = f"LSTM, its first member alone ({r['hidden']} cells, stride {r['stride']})"
        elif replaced := next((v for (k, _), v in REPLACED.items() if k == tuple(c)), None):
            name = f"LSTM, the ensemble {replaced}: its first member alone"
        else:
            name = f"LSTM, the first member (init seed {seeds[0]}) with {', '.join(c)} (candidate, not shipped)"
        stat = {k: {"mean": float(r[f"avg_{k}"]), "median": float(r[f"median_{k}"])}
                for k in ("mape_in_flight_pct", "energy_error_pct")}
        stat["mae_w"] = {"mean": float(r["avg_mae_w"]), "median": float(r["median_mae_w"])}
        out.append((name, stat))
        if shipped["trees"] and name.endswith("(shipped, in the blend below)"):
            out.extend(blend_cv_rows(card))
    return out


BLEND_JSON = OUT / "blend-cv.json"
# The blend shipped before this one (the four-member ensemble with the same trees, at 0.7).
BLEND_REPLACED_JSON = OUT / "blend-cv-four.json"


def blend_cv_rows(card):
    """The shipped blend's out-of-fold row (`lab/scripts/blend_cv.py --json`, committed as
    docs/src/generated/blend-cv.json), and the replaced blend's (`blend-cv-four.json`): the
    network's share chosen for each fold on the others."""
    import statistics
    out = []
    for path, shipped in ((BLEND_JSON, True), (BLEND_REPLACED_JSON, False)):
        try:
            b = json.loads(path.read_text())
        except OSError as e:
            note(f"{path}: no blend CV row ({e})")
            continue
        folds = b["folds"]
        shares = "/".join(f"{x['weight_lstm']:g}" for x in folds)
        stat = {k: {"mean": statistics.mean(x["blend"][k] for x in folds),
                    "median": statistics.median(x["blend"][k] for x in folds)}
                for k in ("mae_w", "mape_in_flight_pct", "energy_error_pct")}
        if shipped:
            name = (f"**the shipped model: that ensemble blended with LightGBM #0 on its inputs, out of fold "
                    f"(network's share {shares} a fold, chosen on the others; {card['trees']['weight_lstm']:g} "
                    f"on all, shipped; `{path.name}`)**")
        else:
            name = (f"the ensemble of four blended with the same trees, out of fold (share {shares} a fold; "
                    f"{b['weight_lstm_pooled']:g} on all; shipped before this one, replaced; `{path.name}`)")
        out.append((name, stat))
    return out


def lgbm_header():
    return ("<!-- Generated by scripts/docs-tables.py from docs/src/generated/lgbm-cv.json "
            "(`lab/scripts/lgbm_cv.py`). Do not edit: run `make docs-tables`. -->\n\n")


def lgbm_cv(r):
    """The CV table: every configuration on the training flights' folds, best CV MAE first."""
    rows = sorted(r.get("configs", []), key=lambda c: c["mae_w"]["mean"])
    if not rows:
        return None
    md = lgbm_header()
    sizes = ", ".join(str(n) for n in r.get("fold_flights", []))
    md += (f"{r['folds']}-fold by-flight cross-validation on the {r['training_flights']} training flights "
           f"(folds of {sizes} flights: `offline::data::cv_folds`, the folds `dronewatt-lab train --cv "
           f"{r['folds']} --seed 7` validates the LSTM on), target lag {r['target_lag']} samples "
           f"({r['target_lag'] / 10:.1f} s). Mean over the held-out folds, median in brackets; MAE over "
           "every window, MAPE over in-flight windows (measured ≥ 100 W), energy error per flight, "
           "averaged. Rule, fixed before the run: the lowest mean CV MAE chooses the configuration and "
           f"its tree count. Every configuration, #0 included, trains on every 2nd window of its flights "
           "with bagging 0.5 and a tree count chosen on the folds, every 25 up to 40 / learning rate (“cap”: "
           "the best was the last tried); the untuned row is `lgbm_baseline.py`'s recipe (every window, "
           "bagging 0.8, early stopping on 12 % of the fold's training flights, trees per fold). "
           f"Wall time {r['wall_s'] / 60:.0f} min on one core for the {len(rows)} configurations × "
           f"{r['folds']} folds (`{r['command']}`, windows from `{r['export']}`)"
           + (f", {r['untuned']['wall_s'] / 60:.0f} min for the untuned row" if r.get("untuned") else "")
           + ".\n\n")
    head = ["configuration", "leaves", "learning rate", "min data in leaf", "feature fraction", "L2",
            "trees", "CV MAE (W)", "CV MAPE %", "CV energy error %"]

    def cells(c):
        return [f(c["mae_w"]["mean"]) + f" ({f(c['mae_w']['median'])})",
                f(c["mape_in_flight_pct"]["mean"]) + f" ({f(c['mape_in_flight_pct']['median'])})",
                f(c["energy_error_pct"]["mean"]) + f" ({f(c['energy_error_pct']['median'])})"]
    body = []
    for c in rows:
        p = c["params"]
        name = f"#{c['index']}" + (" (baseline's parameters)" if c["index"] == 0 else "")
        if c["index"] == r.get("chosen"):
            name = f"**{name}, chosen**"
        body.append([name, p["num_leaves"], p["learning_rate"], p["min_data_in_leaf"], p["feature_fraction"],
                     p["lambda_l2"], f"{c['trees']}" + (" (cap)" if c["trees"] == c.get("max_trees") else "")]
                    + cells(c))
    u = r.get("untuned")
    if u:
        body.append(["untuned (`lgbm_baseline.py`'s recipe)", 63, 0.05, 20, 0.8, 0,
                     "/".join(str(t) for t in u["trees"])] + cells(u))
    for name, c in lstm_cv_rows():
        body.append([name, "", "", "", "", "", ""] + cells(c))
    md += table(head, body)
    md += ("\nThe LSTM rows are `config/models/lstm-m100/cv.csv`, from the shipped model's recipe "
           "with `--cv 5 --seed 7` (the command in its model card): on each fold every member is "
           "early-stopped on an inner validation split of that fold's training flights (`--val-frac`, "
           "by flight, seeded), never on the held-out fold, and the held-out flights are scored as the "
           "model card scores the test flights, every window through the live chain; the first "
           "member alone is scored on the same folds beside the ensemble, and the paper's network "
           "(`config/models/lstm-m100-h128`'s recipe) is cross-validated on the same folds too. "
           "The candidates (rows marked so) are the shipped recipe with one flag changed "
           "(`--stride`, `--plateau-decay`, `--relative-loss`, `--target-lag`, `--readout`), screened as one network "
           "(init seed 7, the ensemble's first member) and, where the screen passed its rule, as the "
           "ensemble; the rules and the order they ran in are in the model card. A row at another target "
           "lag answers a different question (the estimate for an older instant) and compares with "
           "LightGBM at that lag (`lgbm-lags.md`), not with the rows above at 0.3 s. "
           "Each ensemble's cross-validation ran as two processes (`--cv-folds`), joined by "
           "`lab/scripts/merge-cv.py`.\n")
    return md


def lgbm_test(r):
    """The test table: the CV-chosen LightGBM, the untuned one, the shipped LSTM's card."""
    t = r.get("test")
    if not t:
        return None
    md = lgbm_header()
    md += (f"Test flights {', '.join(str(x) for x in t['test_flights'])}, scored once with the configuration "
           f"cross-validation chose (trained on every training flight; `{t['command']}`), all windows, "
           f"target lag {r['target_lag'] / 10:.1f} s. MAE pooled over the test windows, in-flight MAPE "
           "pooled, energy error averaged over the flights, as the model card scores the LSTM.\n\n")
    rows = []
    tu = t["tuned"]
    rows.append([f"LightGBM + lags, tuned on the folds (#{tu['index']}, {tu['trees']} trees)", f(tu["mae_w"], 1),
                 f(tu["flight_276_mae_w"], 1), f(tu["mape_in_flight_pct"]), f(tu["energy_error_pct"])])
    un = t["untuned"]
    rows.append([f"LightGBM + lags, untuned (`lgbm_baseline.py`, {un['trees']} trees)", f(un["mae_w"], 1),
                 f(un["flight_276_mae_w"], 1), f(un["mape_in_flight_pct"]), f(un["energy_error_pct"])])
    import tomllib
    for what, card in (("shipped (model card)", LSTM_CARD),
                       ("the paper's network, shipped before (its card)", PAPER_CARD)):
        try:
            c = tomllib.loads(card.read_text())
            n = 1 + len(c.get("members", []))
            net = f"ensemble of {n} × {c['hidden']} cells" if n > 1 else f"{c['layers']} × {c['hidden']} cells"
            lam = c.get("training", {}).get("relative_loss", 0)
            net += f", relative loss λ {lam:g}" if lam else ""
            net += f", the {c['readout']} readout" if c.get("readout", "final") != "final" else ""
            if "trees" in c:
                net += f", blended with LightGBM (network's share {c['trees']['weight_lstm']:g})"
            m = c["metrics"]
            rows.append([f"LSTM, {net}, {what}", f(m["mae_w"], 1), f(m["flight_276_mae_w"], 1),
                         f(m["mape_in_flight_pct"]), f(m["energy_error_pct"])])
        except (OSError, KeyError) as e:
            note(f"{card}: no LSTM row ({e})")
    md += table(["model", "test MAE (W)", "flight 276 MAE (W)", "in-flight MAPE %", "energy error %"], rows)
    return md


LGBM_LAGS_JSON = OUT / "lgbm-lags.json"


def lag_set(lags):
    """1, 3, 9 / 1, 3–7, 9 / 1, 3–19: a sorted set of lags, runs as ranges."""
    runs, start = [], lags[0]
    for a, b in zip(lags, lags[1:] + [None]):
        if b != a + 1:
            runs.append(f"{start}" if start == a else f"{start}–{a}")
            start = b
    return ", ".join(runs)


def lgbm_lags(r):
    """LightGBM's chosen configuration at other target lags and with more feature lags (issue 25's
    fair-peer check): how much each model gains from the samples after and before the instant."""
    runs = r.get("runs", [])
    if not runs:
        return None
    md = ("<!-- Generated by scripts/docs-tables.py from docs/src/generated/lgbm-lags.json "
          "(`lab/scripts/lgbm_cv.py --only 0`). Do not edit: run `make docs-tables`. -->\n\n")
    md += (f"{r['what']}: {r['folds']}-fold by-flight cross-validation on the LSTM's folds, the same rule "
           f"for the tree count (`{r['command']}`, windows from `{r['export']}`). The target lag L is the "
           "estimate's instant, L samples before the newest. The export holds the newest sample and its copies "
           "lagged 1, 3 and 9 samples; `--lags N` (N > 3) adds the lags 4 to N, shifted within each flight, so "
           "lag 2 is never among them: the column lists the lags each row saw, and what they hold around "
           "the instant (the LSTM's window of 10 sees all L after it and 9 − L before). "
           "Inputs: `paper`, the 21 features as exported (longitude, latitude, altitude above sea level); `home`, "
           "the LSTM's (`--features home` at export); `+ physics`, with the seven physics models' estimates of "
           "the window at published parameters (`--physics`). "
           "Mean over the held-out folds, median in brackets.\n\n")
    body = []
    for x in runs:
        lag, n = x["target_lag"], x["feature_lags"]
        # The export holds lags 1, 3 and 9; `--lags N` shifts in 4..N (lag 2 is never among them).
        lags = sorted({0, 1, 3, 9} | set(range(4, n + 1)))
        after = sum(1 for k in lags if k < lag)
        before = [k - lag for k in lags if k > lag]
        seen = ("the instant" if lag in lags else "not the instant") + f", {after} of {lag} after"
        seen += f", {len(before)} before (up to {max(before)})" if before else ", none before"
        body.append([f"{lag} ({lag / 10:g} s)", lag_set(lags[1:]), x.get("inputs", "paper"), seen,
                     f"{x['trees']}" + (" (cap)" if x["trees"] == x.get("max_trees") else ""),
                     f(x["mae_w"]["mean"]) + f" ({f(x['mae_w']['median'])})",
                     f(x["mape_in_flight_pct"]["mean"]) + f" ({f(x['mape_in_flight_pct']['median'])})",
                     f(x["energy_error_pct"]["mean"]) + f" ({f(x['energy_error_pct']['median'])})",
                     f"{x['wall_s'] / 60:.1f}"])
    md += table(["target lag", "lags seen", "inputs", "around the instant", "trees", "CV MAE (W)",
                 "CV MAPE %", "CV energy error %", "wall (min, one core)"], body)
    return md


def lgbm_tables(check=False):
    """Write the LightGBM tables (with `check`: write nothing, return the stale ones)."""
    stale = []
    if not LGBM_JSON.exists():
        note(f"{LGBM_JSON.relative_to(ROOT)} absent: LightGBM tables kept as committed")
        return stale
    r = json.loads(LGBM_JSON.read_text())
    jobs = [("lgbm-cv.md", lgbm_cv, r), ("lgbm-test.md", lgbm_test, r)]
    if LGBM_LAGS_JSON.exists():
        jobs.append(("lgbm-lags.md", lgbm_lags, json.loads(LGBM_LAGS_JSON.read_text())))
    for fname, fn, r in jobs:
        md = fn(r)
        if md is None:
            note(f"nothing for {fname} in its JSON, not written")
            continue
        if check:
            if not (OUT / fname).exists() or (OUT / fname).read_text() != md:
                stale.append(f"{(OUT / fname).relative_to(ROOT)} differs from its JSON and the LSTM's card")
            continue
        (OUT / fname).write_text(md)
        note(f"wrote {(OUT / fname).relative_to(ROOT)}")
    return stale


WRITERS = {
    "battery-eval": [("battery-eval.md", battery_eval), ("battery-params.md", battery_params)],
    "plan-eval": [("plan-eval-flights.md", plan_eval_flights), ("plan-eval-targets.md", plan_eval_targets),
                  ("plan-eval-members.md", plan_eval_members), ("plan-eval-routes.md", plan_eval_routes)],
    "eval-cvar": [("eval-cvar.md", eval_cvar)],
}


def up_to_date(binary):
    """The binary is newer than every source file it is built from."""
    t = binary.stat().st_mtime
    for d in ("src", "lab/src"):
        for p in (ROOT / d).rglob("*"):
            if p.is_file() and p.stat().st_mtime > t:
                return False
    for p in (ROOT / "Cargo.toml", ROOT / "lab" / "Cargo.toml", ROOT / "Cargo.lock"):
        if p.exists() and p.stat().st_mtime > t:
            return False
    return True


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--from-json", metavar="DIR", type=Path)
    ap.add_argument("--if-available", action="store_true")
    ap.add_argument("--no-eval", action="store_true", help="skip `eval --split cvar` (a few seconds)")
    ap.add_argument("--check", action="store_true",
                    help="write nothing; fail when a committed table or a README headline figure is stale")
    a = ap.parse_args()

    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    cache = target / "docs-json"
    binary = Path(os.environ.get("DRONEWATT_BIN", target / "debug" / "dronewatt-lab"))
    data = Path(os.environ.get("DRONEWATT_DATA", ROOT.parent / "shared" / "data" / "m100" / "flights.csv.gz"))

    # from the committed JSON: needs neither the binary nor the data set
    lgbm_stale = lgbm_tables(check=a.check) + spec_tables(check=a.check)
    wanted = ["battery-eval", "plan-eval"] + ([] if a.no_eval else ["eval-cvar"])
    results = {}
    if a.from_json:
        for name in wanted:
            p = a.from_json / f"{name}.json"
            if p.exists():
                results[name] = json.loads(p.read_text())
            else:
                note(f"{p} missing: {name} tables kept as committed")
    else:
        why = None
        if not binary.exists():
            why = f"{binary} not built (make docs-tables builds it)"
        elif not data.exists():
            why = f"the data set {data} is absent (set DRONEWATT_DATA)"
        elif a.if_available and not up_to_date(binary):
            why = f"{binary} is older than src/ (make docs-tables rebuilds it)"
        if why:
            if a.if_available:
                note(f"{why}: keeping the committed tables in {OUT.relative_to(ROOT)}")
                for s in lgbm_stale:
                    note(f"stale: {s}")
                return 1 if lgbm_stale else 0
            note(why)
            return 1
        cache.mkdir(parents=True, exist_ok=True)
        env = dict(os.environ, DRONEWATT_DATA=str(data), DRONEWATT_HOME="off")
        for name in wanted:
            note(f"running dronewatt-lab {' '.join(COMMANDS[name])}")
            p = subprocess.run([str(binary)] + COMMANDS[name], cwd=ROOT, env=env,
                               capture_output=True, text=True)
            if p.returncode != 0:
                note(f"dronewatt-lab {name} failed ({p.returncode}):\n{p.stderr[-2000:]}")
                if a.if_available:
                    continue
                return 1
            (cache / f"{name}.json").write_text(p.stdout)
            results[name] = json.loads(p.stdout)

    OUT.mkdir(parents=True, exist_ok=True)
    stale = list(lgbm_stale)
    for name, r in results.items():
        for fname, fn in WRITERS[name]:
            md = fn(r)
            if md is None:
                note(f"{name}: JSON shape not recognised, {fname} not written")
                continue
            if a.check:
                if not (OUT / fname).exists() or (OUT / fname).read_text() != md:
                    stale.append(f"{(OUT / fname).relative_to(ROOT)} differs from `dronewatt-lab {name} --json`")
                continue
            (OUT / fname).write_text(md)
            note(f"wrote {(OUT / fname).relative_to(ROOT)}")
    # The README's headline figures are hand-written prose: checked, never written.
    head = headline(ROOT / "README.md")
    for name, r in results.items():
        for claim in readme_claims(name, r):
            if claim not in head:
                stale.append(f"README.md, Headline figures: `{claim}` (from `dronewatt-lab {name} --json`) is not there")
    for s in stale:
        note(f"stale: {s}")
    if stale:
        note("refresh with `make docs-tables` and edit the README's headline figures to match")
        return 1
    note(f"the tables and the README's headline figures match {', '.join(results) or 'nothing (no JSON)'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
