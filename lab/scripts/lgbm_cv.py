#!/usr/bin/env python3
"""LightGBM tuned on the LSTM's by-flight folds (issue 25, item 2).

The windows come from `dronewatt-lab train --export-csv FILE --cv 5 --seed 7 --target-lag 3`
(hidden flag; `dronewatt` hands `train` to `dronewatt-torch`): the same features as
`lab/scripts/lgbm_baseline.py`, plus a `fold` column, the flight's fold of
`offline::data::cv_folds`, the folds `dronewatt-lab train --cv 5 --seed 7` validates the LSTM on
(-1: not a training flight; the test flights 268-273, 276-279 are -1).

    python3 -m venv /tmp/venv-lgbm && /tmp/venv-lgbm/bin/pip install lightgbm pandas numpy scikit-learn
    target/debug/dronewatt-lab train --export-csv /tmp/windows.csv --cv 5 --seed 7 --target-lag 3
    lab/scripts/lgbm_cv.py cv      /tmp/windows.csv --json /tmp/lgbm-cv.json  # 18 min, one core
    lab/scripts/lgbm_cv.py untuned /tmp/windows.csv --json /tmp/lgbm-cv.json  # the baseline, same folds
    lab/scripts/lgbm_cv.py test    /tmp/windows.csv --json /tmp/lgbm-cv.json  # once

    lab/scripts/lgbm_cv.py cv /tmp/windows.csv --json /tmp/lgbm-l9.json --only 0 --lags 9  # #0, 10-sample window
    lab/scripts/lgbm_cv.py fit /tmp/windows.csv --json /tmp/lgbm-cv.json --save trees.txt  # for a card's `trees`

`--lags N` gives every row the samples up to N steps back but 2 (the export holds 1, 3 and 9; 4 to N are
shifted here within each flight, missing across a gap): with N = 9 LightGBM sees the LSTM's
10-sample window but its lag 2. `--lag L` sets the target lag, as the LSTM's card does: at L = 3 the
export's lags 1 and 3 reach the target instant, so a larger L needs N >= L to see it at all.
`--physics` adds the export's `phys_<model>_w` columns, each physics model's estimate of the
window with the vehicle's published parameters (nothing fitted on any flight, so no fold
leaks into another), as features: a physics-informed LightGBM.
`--relative` weights each training window as the LSTM's `--relative-loss 1` does (in flight
P̄ / P, P̄ the in-flight targets' harmonic mean; the ground 1); the tree count is still chosen
on the unweighted MAE. `fit` and `test` read `relative` from the JSON.
`--only I,...` runs only those configurations of the search below; `--oof FILE` writes the
held-out windows' estimates (flight, fold, the window's newest sample's time, the measured
power at the target lag, the estimate) beside `dronewatt-lab train --cv-predictions`'s.

`cv` and `untuned` touch the training flights only: each configuration trains on K-1 folds and is
scored on the held-out one. `test` reads the configuration `cv` chose from the JSON, trains
it once on every training flight and scores the test flights once; it also scores the
untuned baseline (`lgbm_baseline.py`'s recipe) there for comparison.
(LightGBM's scikit-learn interface, which that recipe uses, needs scikit-learn.)

The search, fixed before it ran:
- configuration 0 is the baseline's parameters (63 leaves, learning rate 0.05, feature
  fraction 0.8, no L2, LightGBM's min_data_in_leaf 20); configurations 1-15 are drawn
  without replacement (numpy default_rng(25)) from num_leaves {15, 31, 63, 127, 255} x
  learning_rate {0.05, 0.1, 0.2} x min_data_in_leaf {20, 100, 400} x feature_fraction
  {0.5, 0.8, 1.0} x lambda_l2 {0, 1, 10};
- every configuration: L2 objective, bagging fraction 0.5 every iteration, every 2nd
  window of each training flight (neighbouring windows overlap by 9 of 10 samples; this
  halves the cost, and the final fit uses the same rows rule), seed 7, one thread;
- the number of trees is tuned too, on a grid: every 25 trees up to 40 / learning_rate
  (800 at 0.05), one fit per fold, scored at each grid point (no early stopping on the
  held-out fold: the tree count is chosen on the mean over folds, never per fold).
- The rule: the (configuration, trees) with the lowest MAE averaged over the K held-out
  folds wins; MAPE and energy error are reported beside it, not used to choose.

Metrics (as `lgbm_baseline.py` and the accuracy page's all-window table): MAE over every
window, MAPE over in-flight windows (measured >= 100 W), energy error |sum(pred) -
sum(measured)| / sum(measured) per flight, averaged over the flights; per fold in CV.

The CSV is cut from the data set: write it to a temp dir, never commit it. The JSON holds
figures only (no data rows).
"""
import argparse
import json
import sys
import time
from pathlib import Path

import lightgbm as lgb
import numpy as np
import pandas as pd

IN_FLIGHT_W = 100.0  # same threshold as lgbm_baseline.py
META = ("flight", "route", "test", "fold", "t_s", "measured_w")
SEED = 7
STRIDE = 2
BAGGING = 0.5
TREE_STEP = 25
GRID = {
    "num_leaves": [15, 31, 63, 127, 255],
    "learning_rate": [0.05, 0.1, 0.2],
    "min_data_in_leaf": [20, 100, 400],
    "feature_fraction": [0.5, 0.8, 1.0],
    "lambda_l2": [0, 1, 10],
}
BASELINE = {"num_leaves": 63, "learning_rate": 0.05, "min_data_in_leaf": 20, "feature_fraction": 0.8,
            "lambda_l2": 0}
N_DRAWN = 15


def configs():
    keys = list(GRID)
    space = [dict(zip(keys, v)) for v in np.array(np.meshgrid(*[range(len(GRID[k])) for k in keys],
                                                              indexing="ij")).reshape(len(keys), -1).T]
    picks = np.random.default_rng(25).choice(len(space), size=N_DRAWN + 1, replace=False)
    out = [dict(BASELINE)]
    for i in picks:
        c = {k: GRID[k][int(space[i][k])] for k in keys}
        if c != BASELINE and len(out) <= N_DRAWN:
            out.append(c)
    return out


def max_trees(lr):
    return int(round(40 / lr / TREE_STEP)) * TREE_STEP


def load(path, lag, lags=3, physics=False):
    df = pd.read_csv(path)
    phys = [c for c in df.columns if c.startswith("phys_")]
    if not physics:
        df = df.drop(columns=phys)
    elif not phys:
        sys.exit("--physics: the CSV has no phys_*_w columns: export again with this binary")
    base = [c for c in df.columns if c not in META and "_lag" not in c and not c.startswith("phys_")]
    if lags > 3:  # the export holds lags 1, 3, 9; 4..N are shifted here, within each flight, NaN across a gap
        g = df.groupby("flight")
        extra = {}
        for k in range(4, lags + 1):
            gap = np.abs(df.t_s - g.t_s.shift(k) - 0.1 * k) >= 1e-3
            for c in base:
                extra[f"{c}_lag{k}"] = g[c].shift(k).mask(gap)
        df = pd.concat([df, pd.DataFrame(extra)], axis=1)
    feats = [c for c in df.columns if c not in META]
    if lag:  # as lgbm_baseline.py
        g = df.groupby("flight")
        target, t_back = g.measured_w.shift(lag), g.t_s.shift(lag)
        ok = (np.abs(df.t_s - t_back - 0.1 * lag) < 1e-3) & target.notna()
        df = df.assign(measured_w=target)[ok]
    pool = df[(df.test == 0) & (~df.route.str.startswith("A"))]
    if set(pool.flight) != set(df.flight[df.fold >= 0]):
        sys.exit("the fold column does not cover the training pool: export again with this binary")
    return df, feats


def relative_weights(y):
    """The LSTM's `--relative-loss 1` weights (torch/src/train/mod.rs `relative_weights`): in
    flight (>= IN_FLIGHT_W) P̄ / P, P̄ the in-flight targets' harmonic mean, so they average 1;
    on the ground 1."""
    fl = y >= IN_FLIGHT_W
    p_bar = fl.sum() / np.sum(1.0 / y[fl]) if fl.any() else 0.0
    return np.where(fl, p_bar / np.where(fl, y, 1.0), 1.0)


def dataset(tr, feats, relative):
    y = tr.measured_w.to_numpy()
    return lgb.Dataset(tr[feats].to_numpy(np.float32), y, weight=relative_weights(y) if relative else None,
                       feature_name=feats, params={"feature_pre_filter": False, "verbose": -1}, free_raw_data=False)


def strided(d):
    return d[d.groupby("flight").cumcount() % STRIDE == 0]


def lgb_params(c):
    return dict(objective="regression", metric="l1", bagging_fraction=BAGGING, bagging_freq=1, seed=SEED,
                num_threads=1, verbose=-1, feature_pre_filter=False, **c)


def scores(d, pred):
    y = d.measured_w.to_numpy()
    err = pred - y
    fl = y >= IN_FLIGHT_W
    t = pd.DataFrame({"flight": d.flight.to_numpy(), "pred": pred, "y": y})
    s = t.groupby("flight")[["pred", "y"]].sum()
    energy = 100 * np.abs(s.pred - s.y) / s.y
    f276 = t[t.flight == 276]
    return {"mae_w": float(np.mean(np.abs(err))),
            "mape_in_flight_pct": float(100 * np.mean(np.abs(err[fl] / y[fl]))),
            "energy_error_pct": float(energy.mean()),
            "flight_276_mae_w": float(np.mean(np.abs(f276.pred - f276.y))) if len(f276) else None,
            "flights": int(len(s)), "windows": int(len(y))}


def summary(per_fold):
    out = {}
    for key in ("mae_w", "mape_in_flight_pct", "energy_error_pct"):
        v = np.array([f[key] for f in per_fold])
        out[key] = {"mean": float(v.mean()), "median": float(np.median(v)), "folds": [float(x) for x in v]}
    return out


def untuned_fit(train, feats):
    """lgbm_baseline.py's recipe: every window, early stopping on 12 % of the flights given."""
    flights = np.array(sorted(train.flight.unique()))
    rng = np.random.default_rng(7)
    val_flights = set(rng.choice(flights, size=max(1, round(0.12 * len(flights))), replace=False))
    tr, va = train[~train.flight.isin(val_flights)], train[train.flight.isin(val_flights)]
    model = lgb.LGBMRegressor(n_estimators=2000, learning_rate=0.05, num_leaves=63, subsample=0.8,
                              subsample_freq=1, colsample_bytree=0.8, random_state=7, verbose=-1,
                              n_jobs=1)
    model.fit(tr[feats], tr.measured_w, eval_set=[(va[feats], va.measured_w)], eval_metric="l1",
              callbacks=[lgb.early_stopping(50, verbose=False)])
    return model


def run_cv(a):
    started = time.time()
    df, feats = load(a.csv, a.lag, a.lags, a.physics)
    pool = df[df.fold >= 0]
    k = int(pool.fold.max()) + 1
    cs = list(enumerate(configs()))
    if a.only is not None:
        cs = [cs[int(i)] for i in a.only.split(",")]
    data = []
    for fold in range(k):
        tr, va = strided(pool[pool.fold != fold]), pool[pool.fold == fold]
        dtr = dataset(tr, feats, a.relative)
        dva = dtr.create_valid(va[feats].to_numpy(np.float32), va.measured_w.to_numpy())
        data.append((dtr, dva, va))
    print(f"{len(pool.flight.unique())} training flights, {k} folds, {len(cs)} configurations, "
          f"target lag {a.lag}, feature lags 1-{a.lags}{', physics estimates' if a.physics else ''}", flush=True)
    out = {"command": "lab/scripts/lgbm_cv.py cv windows.csv --json FILE",
           "export": f"dronewatt-lab train --export-csv windows.csv --cv {k} --seed 7 --target-lag {a.lag}",
           "target_lag": a.lag, "feature_lags": a.lags, "physics": a.physics, "relative": a.relative, "folds": k, "training_flights": int(pool.flight.nunique()),
           "fold_flights": [int(pool[pool.fold == f].flight.nunique()) for f in range(k)],
           "rule": "lowest MAE averaged over the held-out folds (configuration and tree count)",
           "search": __doc__.split("The search, fixed before it ran:")[1].split("Metrics")[0].strip(),
           "configs": []}
    for ci, (index, c) in enumerate(cs):
        if a.budget_s and time.time() - started > a.budget_s:
            print(f"time budget spent: configurations {', '.join(str(i) for i, _ in cs[ci:])} not run", flush=True)
            break
        t0 = time.time()
        n_max = max_trees(c["learning_rate"])
        curves, boosters = [], []
        for dtr, dva, va in data:
            ev = {}
            b = lgb.train(lgb_params(c), dtr, n_max, valid_sets=[dva], valid_names=["v"],
                          callbacks=[lgb.record_evaluation(ev)])
            curves.append(np.array(ev["v"]["l1"]))
            boosters.append(b)
        grid = np.arange(TREE_STEP, n_max + 1, TREE_STEP)
        mean_curve = np.mean([cv[grid - 1] for cv in curves], axis=0)
        n_best = int(grid[np.argmin(mean_curve)])
        preds = [b.predict(va[feats].to_numpy(np.float32), num_iteration=n_best)
                 for b, (_, _, va) in zip(boosters, data)]
        per_fold = [scores(va, p) for p, (_, _, va) in zip(preds, data)]
        if a.oof:  # every held-out window's estimate at the chosen tree count, for a blend study
            oof = pd.concat([va[["flight", "fold", "t_s", "measured_w"]].assign(pred_w=p)
                             for p, (_, _, va) in zip(preds, data)])
            oof.to_csv(a.oof, index=False, float_format="%.3f")
        row = {"index": index, "params": c, "max_trees": n_max, "trees": n_best,
               "wall_s": round(time.time() - t0, 1), **summary(per_fold)}
        out["configs"].append(row)
        print(f"[{index:2}] {c} trees {n_best}/{n_max}: CV MAE {row['mae_w']['mean']:.2f} W, "
              f"MAPE {row['mape_in_flight_pct']['mean']:.2f} %, energy {row['energy_error_pct']['mean']:.2f} % "
              f"({row['wall_s']:.0f} s)", flush=True)
        best = min(out["configs"], key=lambda r: r["mae_w"]["mean"])
        out["chosen"] = best["index"]
        out["wall_s"] = round(time.time() - started, 1)
        Path(a.json).write_text(json.dumps(out, indent=1) + "\n")
    out["wall_s"] = round(time.time() - started, 1)
    Path(a.json).write_text(json.dumps(out, indent=1) + "\n")
    print_table(out)


def run_untuned(a):
    """The untuned baseline (lgbm_baseline.py's recipe) on the same folds, added to the JSON."""
    out = json.loads(Path(a.json).read_text())
    started = time.time()
    df, feats = load(a.csv, out["target_lag"], out.get("feature_lags", 3), out.get("physics", False))
    pool = df[df.fold >= 0]
    per_fold, trees = [], []
    for fold in range(out["folds"]):
        m = untuned_fit(pool[pool.fold != fold], feats)
        va = pool[pool.fold == fold]
        per_fold.append(scores(va, m.predict(va[feats])))
        trees.append(int(m.best_iteration_))
        print(f"untuned fold {fold}: MAE {per_fold[-1]['mae_w']:.2f} W, {trees[-1]} trees", flush=True)
    out["untuned"] = {"command": "lab/scripts/lgbm_cv.py untuned windows.csv --json FILE",
                      "recipe": "lgbm_baseline.py: every window, 63 leaves, learning rate 0.05, bagging 0.8, "
                                "feature fraction 0.8, early stopping (50) on 12 % of the fold's training flights",
                      "trees": trees, "wall_s": round(time.time() - started, 1), **summary(per_fold)}
    Path(a.json).write_text(json.dumps(out, indent=1) + "\n")
    print_table(out)


def print_table(out):
    print(f"\n{out['folds']}-fold by-flight CV, target lag {out['target_lag']} "
          f"(means over folds; medians in brackets):")
    print("| # | leaves | lr | min leaf | feat. frac. | L2 | trees | MAE (W) | MAPE | energy error |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in sorted(out["configs"], key=lambda r: r["mae_w"]["mean"]):
        p = r["params"]
        mark = " **chosen**" if r["index"] == out.get("chosen") else ""
        print(f"| {r['index']}{mark} | {p['num_leaves']} | {p['learning_rate']} | {p['min_data_in_leaf']} | "
              f"{p['feature_fraction']} | {p['lambda_l2']} | {r['trees']} | {r['mae_w']['mean']:.2f} "
              f"({r['mae_w']['median']:.2f}) | {r['mape_in_flight_pct']['mean']:.2f} % | "
              f"{r['energy_error_pct']['mean']:.2f} % |")
    if "untuned" in out:
        u = out["untuned"]
        print(f"| untuned (baseline recipe) | 63 | 0.05 | 20 | 0.8 | 0 | {u['trees']} | {u['mae_w']['mean']:.2f} "
              f"({u['mae_w']['median']:.2f}) | {u['mape_in_flight_pct']['mean']:.2f} % | "
              f"{u['energy_error_pct']['mean']:.2f} % |")
    print(f"wall time {out['wall_s']:.0f} s")


def run_test(a):
    out = json.loads(Path(a.json).read_text())
    if "test" in out:
        sys.exit(f"{a.json} already holds the test score: the test split is scored once")
    started = time.time()
    df, feats = load(a.csv, out["target_lag"], out.get("feature_lags", 3), out.get("physics", False))
    pool, test = df[df.fold >= 0], df[df.test == 1]
    best = next(r for r in out["configs"] if r["index"] == out["chosen"])
    tr = strided(pool)
    b = lgb.train(lgb_params(best["params"]), dataset(tr, feats, out.get("relative", False)), best["trees"])
    tuned = scores(test, b.predict(test[feats].to_numpy(np.float32)))
    tuned_s = round(time.time() - started, 1)
    t0 = time.time()
    m = untuned_fit(pool, feats)
    untuned = scores(test, m.predict(test[feats]))
    untuned["trees"] = int(m.best_iteration_)
    out["test"] = {"command": "lab/scripts/lgbm_cv.py test windows.csv --json FILE",
                   "test_flights": sorted(int(f) for f in test.flight.unique()),
                   "tuned": {"index": best["index"], "params": best["params"], "trees": best["trees"],
                             "fit_s": tuned_s, **tuned},
                   "untuned": {"fit_s": round(time.time() - t0, 1), **untuned}}
    Path(a.json).write_text(json.dumps(out, indent=1) + "\n")
    for name in ("tuned", "untuned"):
        s = out["test"][name]
        print(f"{name}: test MAE {s['mae_w']:.1f} W, flight 276 MAE {s['flight_276_mae_w']:.1f} W, "
              f"in-flight MAPE {s['mape_in_flight_pct']:.2f} %, energy error {s['energy_error_pct']:.2f} %")


def run_fit(a):
    """The chosen configuration fitted once on every training flight, saved as LightGBM's text
    model for the LSTM's card (`trees`): the test flights are neither fitted nor scored."""
    if not a.save:
        sys.exit("fit: --save FILE names the text model to write")
    out = json.loads(Path(a.json).read_text())
    df, feats = load(a.csv, out["target_lag"], out.get("feature_lags", 3), out.get("physics", False))
    if out.get("feature_lags", 3) > 3 or out.get("physics", False):
        sys.exit("fit: dronewatt's evaluator reads the export's lags 1, 3 and 9 only (no --lags N > 3, no --physics)")
    best = next(r for r in out["configs"] if r["index"] == out["chosen"])
    tr = strided(df[df.fold >= 0])
    started = time.time()
    b = lgb.train(lgb_params(best["params"]), dataset(tr, feats, out.get("relative", False)), best["trees"])
    b.save_model(a.save)
    print(f"{a.save}: configuration {best['index']}, {best['trees']} trees, target lag {out['target_lag']} "
          f"(blend only into a card with this target_lag), {len(tr)} windows of "
          f"{tr.flight.nunique()} training flights, {time.time() - started:.0f} s")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("step", choices=["cv", "untuned", "test", "fit"])
    ap.add_argument("csv")
    ap.add_argument("--json", required=True, help="results (figures only); `test` reads `cv`'s choice here")
    ap.add_argument("--lag", type=int, default=3, help="target lag, samples (cv; test takes cv's)")
    ap.add_argument("--lags", type=int, default=3,
                    help="cv: feature lags up to N (the export holds 1, 3 and 9; 4..N are shifted within each flight)")
    ap.add_argument("--physics", action="store_true",
                    help="cv: add the physics models' estimates of each window (published parameters, the "
                         "export's phys_*_w columns) as features")
    ap.add_argument("--relative", action="store_true",
                    help="cv: weight each training window as the LSTM's --relative-loss 1 does (in flight P̄/P, "
                         "ground 1); `fit` reads it from the JSON")
    ap.add_argument("--oof", help="cv: write each held-out window's estimate (the last configuration run) to "
                                  "this CSV; cut from the data set, never commit it")
    ap.add_argument("--save", help="fit: write the fitted trees (LightGBM's text model) here")
    ap.add_argument("--only", help="cv: run only these configurations (comma-separated indices)")
    ap.add_argument("--budget-s", type=float, default=0, help="cv: start no configuration after this many s")
    a = ap.parse_args()
    {"cv": run_cv, "untuned": run_untuned, "test": run_test, "fit": run_fit}[a.step](a)


if __name__ == "__main__":
    main()
