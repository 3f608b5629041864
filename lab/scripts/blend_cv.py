#!/usr/bin/env python3
"""Out-of-fold blend of the LSTM and LightGBM on the same by-flight folds (issue 25).

Would the mean of two model families beat either? Both are cross-validated on the folds of
`--cv 5 --seed 7` (`offline::data::cv_folds`), and each writes its held-out windows'
estimates:

    DIR=/tmp/oof   # the shipped recipe (the model card's command) with --cv and --cv-predictions
    dronewatt-lab train ...card's flags... --cv 5 --seed 7 --cv-predictions --out $DIR   # 40 min, 2 processes
    dronewatt-lab train --export-csv /tmp/windows.csv --cv 5 --seed 7 --target-lag 3
    lab/scripts/lgbm_cv.py cv /tmp/windows.csv --json /tmp/l.json --only 0 --oof /tmp/lgbm-oof.csv
    lab/scripts/blend_cv.py $DIR /tmp/lgbm-oof.csv --lag 3 [--json out.json]

The windows are joined on flight and instant: the LSTM's rows are the instant its estimate
is for, LightGBM's the window's newest sample (its target is the measured power `--lag`
samples earlier); rows whose measured power disagrees are dropped and counted. The blend
is `w * lstm + (1 - w) * lgbm`, w on a grid 0, 0.05, ..., 1, chosen for each fold on the
other folds' windows (lowest pooled MAE), so no fold picks its own weight; the weight to ship
(`weight_lstm_pooled`) is chosen the same way on every fold's windows at once.

Every figure is computed here the same way for all three (per fold, then the mean over
folds): MAE over every window, MAPE over in-flight windows (measured >= 100 W), energy
error |sum(estimate) - sum(measured)| / sum(measured) per flight, averaged over the fold's
flights (`lgbm_cv.py`'s `scores`, which it imports). Training flights only: the script refuses
a test flight.

`--bias` studies the energy error, each flight's bias sum(blend)/sum(measured) - 1 at the
shipped weight: its spread, how much of it lies between days, whether a flight's first half
says anything of its second (in-flight windows), its correlation with what the data set
records per flight, and what MAE and MAPE would be left if every flight's bias were known
and divided out (an oracle: the within-flight error floor). It reads the per-flight columns
of the data set ($DRONEWATT_DATA, else ../shared/data/m100/flights.csv.gz). `--write-blend`
writes the joined out-of-fold windows with the blend (a temp file: it is cut from the data
set; `lab/scripts/mission/lab_live.py --oof` reads it).

Runs in `lgbm_cv.py`'s environment (numpy, pandas, lightgbm).
"""
import argparse
import glob
import json
import os
import sys

import numpy as np
import pandas as pd

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from lgbm_cv import IN_FLIGHT_W, scores as lgbm_scores  # noqa: E402  (the same metrics as LightGBM's CV)

TEST_FLIGHTS = {268, 269, 270, 271, 272, 273, 276, 277, 278, 279}
GRID = np.round(np.arange(0, 1.0001, 0.05), 2)
KEYS = ("mae_w", "mape_in_flight_pct", "energy_error_pct")


def scores(d, pred):
    s = lgbm_scores(d, pred)
    return {k: s[k] for k in KEYS}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("lstm_dirs", nargs="+", help="folders holding cv-predictions-*.csv, then LightGBM's --oof CSV")
    ap.add_argument("--lag", type=int, default=3, help="the target lag both were trained with, samples")
    ap.add_argument("--json", help="write the figures (no data rows) here")
    ap.add_argument("--bias", action="store_true", help="study the blend's per-flight bias (the energy error)")
    ap.add_argument("--write-blend", metavar="CSV", help="write the joined windows with the blend (temp dir)")
    a = ap.parse_args()
    *dirs, lgbm_path = a.lstm_dirs
    files = sorted(f for d in dirs for f in glob.glob(os.path.join(d, "cv-predictions-*.csv")))
    if not files:
        sys.exit(f"{', '.join(dirs)}: no cv-predictions-*.csv (train --cv K --cv-predictions)")
    lstm = pd.concat([pd.read_csv(f) for f in files])
    lstm = lstm[np.isfinite(lstm.pred_w) & np.isfinite(lstm.measured_w)]
    gbm = pd.read_csv(lgbm_path)
    bad = (set(lstm.flight) | set(gbm.flight)) & TEST_FLIGHTS
    if bad:
        sys.exit(f"test flights {sorted(bad)} in the input: this study reads training flights only")
    # LightGBM's row time is the window's newest sample; its estimate is for `lag` samples before.
    gbm = gbm.assign(key=np.round(10 * gbm.t_s).astype(int) - a.lag)
    lstm = lstm.assign(key=np.round(10 * lstm.t_s).astype(int))
    j = lstm.merge(gbm[["flight", "key", "fold", "measured_w", "pred_w"]], on=["flight", "key"],
                   suffixes=("", "_gbm"))
    agree = (np.abs(j.measured_w - j.measured_w_gbm) < 0.01) & (j.fold == j.fold_gbm)
    print(f"{len(lstm)} LSTM windows, {len(gbm)} LightGBM windows, {len(j)} joined, "
          f"{int((~agree).sum())} dropped (measured power or fold disagree)")
    j = j[agree]
    folds = sorted(j.fold.unique())
    out = {"command": "lab/scripts/blend_cv.py DIR... lgbm-oof.csv --lag %d" % a.lag, "windows": int(len(j)),
           "flights": int(j.flight.nunique()), "folds": [], "grid": GRID.tolist()}
    rows = {"lstm": [], "lgbm": [], "blend": []}
    for k in folds:
        rest = j[j.fold != k]
        w = min(GRID, key=lambda w: float(np.mean(np.abs(w * rest.pred_w + (1 - w) * rest.pred_w_gbm
                                                         - rest.measured_w))))
        d = j[j.fold == k]
        s = {"lstm": scores(d, d.pred_w.to_numpy()), "lgbm": scores(d, d.pred_w_gbm.to_numpy()),
             "blend": scores(d, (w * d.pred_w + (1 - w) * d.pred_w_gbm).to_numpy())}
        for name in rows:
            rows[name].append(s[name])
        out["folds"].append({"fold": int(k), "weight_lstm": float(w), "flights": int(d.flight.nunique()), **s})
    # The weight to ship: chosen on every training flight's out-of-fold windows at once.
    pooled = min(GRID, key=lambda w: float(np.mean(np.abs(w * j.pred_w + (1 - w) * j.pred_w_gbm - j.measured_w))))
    out["weight_lstm_pooled"] = float(pooled)
    print(f"the weight to ship (lowest pooled out-of-fold MAE, every fold): {pooled:.2f}")
    corr = float(np.corrcoef(j.pred_w - j.measured_w, j.pred_w_gbm - j.measured_w)[0, 1])
    out["error_correlation"] = corr
    print(f"correlation of the two models' errors: {corr:.3f}")
    print("| 5-fold CV, out of fold | weight of the LSTM | MAE (W) | MAPE | energy error |")
    print("|---|---|---|---|---|")
    out["mean"] = {}
    for name in rows:
        m = {key: float(np.mean([r[key] for r in rows[name]])) for key in rows[name][0]}
        out["mean"][name] = m
        wts = ";".join(f"{f['weight_lstm']:.2f}" for f in out["folds"]) if name == "blend" else "–"
        print(f"| {name} | {wts} | {m['mae_w']:.2f} | {m['mape_in_flight_pct']:.3f} % | "
              f"{m['energy_error_pct']:.2f} % |")
    blend = pooled * j.pred_w + (1 - pooled) * j.pred_w_gbm
    if a.write_blend:
        j.assign(blend_w=blend)[["flight", "fold", "t_s", "measured_w", "pred_w", "pred_w_gbm", "blend_w"]].to_csv(
            a.write_blend, index=False, float_format="%.3f")
    if a.bias:
        out["bias"] = bias_study(j.assign(blend_w=blend), pooled)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=1)
            fh.write("\n")


def flight_table():
    """One row per flight from the data set itself (the official flights.csv has these columns)."""
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    path = os.environ.get("DRONEWATT_DATA") or os.path.join(root, "..", "shared", "data", "m100", "flights.csv.gz")
    if not os.path.exists(path):
        sys.exit(f"{path}: no such file (set DRONEWATT_DATA to the data set's flights.csv)")
    cols = ["flight", "date", "time_day", "route", "payload", "speed", "altitude", "battery_voltage"]
    raw = pd.read_csv(path, usecols=cols, low_memory=False)
    t = raw.groupby("flight").first()
    hm = t.time_day.astype(str).str.split(":", expand=True).astype(float)
    return t.assign(hour=hm[0] + hm[1] / 60, start_v=t.battery_voltage)


def bias_study(j, w):
    """The energy error's structure: see the module's docstring (`--bias`)."""
    j = j.sort_values(["flight", "key"])
    per = j.groupby("flight").agg(meas=("measured_w", "sum"), est=("blend_w", "sum"))
    per["bias_pct"] = 100 * (per.est / per.meas - 1)
    per = per.join(flight_table())
    b = per.bias_pct
    day_mean = per.groupby("date").bias_pct.transform("mean")
    between = float(((day_mean - b.mean()) ** 2).sum() / ((b - b.mean()) ** 2).sum())
    within_sd = float((b - day_mean).std())
    halves = []
    for _, x in j[j.measured_w >= IN_FLIGHT_W].groupby("flight"):
        if len(x) >= 100:
            h = len(x) // 2
            halves.append((x.blend_w.iloc[:h].sum() / x.measured_w.iloc[:h].sum(),
                           x.blend_w.iloc[h:].sum() / x.measured_w.iloc[h:].sum()))
    halves = np.asarray(halves)
    r_halves = float(np.corrcoef(halves[:, 0], halves[:, 1])[0, 1])
    covar = {c: float(np.corrcoef(pd.to_numeric(per[c], errors="coerce").fillna(0), b)[0, 1]) for c in ["payload", "speed", "altitude", "hour", "start_v"]}
    # the oracle: each flight's estimate divided by its own bias, then the usual figures per fold
    scale = j.flight.map(per.est / per.meas)
    oracle = [scores(d, (d.blend_w / scale[d.index]).to_numpy()) for _, d in j.groupby("fold")]
    plain = [scores(d, d.blend_w.to_numpy()) for _, d in j.groupby("fold")]
    mean = lambda rows, k: float(np.mean([r[k] for r in rows]))  # noqa: E731
    res = {"weight_lstm": float(w), "flights": int(len(per)), "days": int(per.date.nunique()),
           "mean_bias_pct": float(b.mean()), "sd_bias_pct": float(b.std()), "mean_abs_bias_pct": float(b.abs().mean()),
           "between_days_share": between, "within_day_sd_pct": within_sd, "r_first_second_half": r_halves,
           "flights_halves": int(len(halves)), "r_with": covar,
           "plain": {k: mean(plain, k) for k in KEYS}, "oracle_bias_removed": {k: mean(oracle, k) for k in KEYS}}
    print(f"\nThe blend's per-flight bias (the shipped weight {w:.2f} on every fold, {res['flights']} flights on {res['days']} days): mean "
          f"{res['mean_bias_pct']:+.2f} %, sd {res['sd_bias_pct']:.2f} %, mean |bias| {res['mean_abs_bias_pct']:.2f} %")
    print(f"- between days: {100 * between:.0f} % of its variance; sd within a day {within_sd:.2f} %")
    print(f"- a flight's first half against its second (in-flight windows, {len(halves)} flights): r = {r_halves:.2f}")
    print("- correlation with " + ", ".join(f"{k} {v:+.2f}" for k, v in covar.items()))
    p, o = res["plain"], res["oracle_bias_removed"]
    print(f"- each flight's bias divided out (oracle): MAE {p['mae_w']:.2f} -> {o['mae_w']:.2f} W, "
          f"MAPE {p['mape_in_flight_pct']:.3f} -> {o['mape_in_flight_pct']:.3f} %, energy {p['energy_error_pct']:.2f} -> "
          f"{o['energy_error_pct']:.2f} %")
    return res


if __name__ == "__main__":
    main()
