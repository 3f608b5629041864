#!/usr/bin/env python3
"""Out-of-fold blend of the LSTM and LightGBM on the same by-flight folds (issue 25).

Would the mean of two model families beat either? Both are cross-validated on the folds of
`--cv 5 --seed 7` (`offline::data::cv_folds`), and each writes its held-out windows'
estimates:

    DIR=/tmp/oof   # the shipped recipe (the model card's command) with --cv and --cv-predictions
    dronewatt train ...card's flags... --cv 5 --seed 7 --cv-predictions --out $DIR   # 40 min, 2 processes
    dronewatt train --export-csv /tmp/windows.csv --cv 5 --seed 7 --target-lag 3
    scripts/lgbm_cv.py cv /tmp/windows.csv --json /tmp/l.json --only 0 --oof /tmp/lgbm-oof.csv
    scripts/blend_cv.py $DIR /tmp/lgbm-oof.csv --lag 3 [--json out.json]

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
a test flight. Runs in `lgbm_cv.py`'s environment (numpy, pandas, lightgbm).
"""
import argparse
import glob
import json
import os
import sys

import numpy as np
import pandas as pd

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from lgbm_cv import scores as lgbm_scores  # noqa: E402  (the same metrics as LightGBM's CV)

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
    out = {"command": "scripts/blend_cv.py DIR... lgbm-oof.csv --lag %d" % a.lag, "windows": int(len(j)),
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
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=1)
            fh.write("\n")


if __name__ == "__main__":
    main()
