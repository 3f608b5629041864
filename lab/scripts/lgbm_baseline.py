#!/usr/bin/env python3
"""LightGBM baseline beside the LSTM: what a data scientist would try first.

Same windows and split as `dronewatt-lab train`: the features are exported by the binary
itself (hidden `dronewatt-lab train --export-csv FILE`: each window's newest sample plus
copies lagged 1, 3 and 9 samples, built by the same loader the LSTM trains on), the
test flights (268-273, 276-279) are only scored, ground tests (routes A*) are left out.

    python3 -m venv /tmp/venv-lgbm && /tmp/venv-lgbm/bin/pip install lightgbm pandas scikit-learn
    target/debug/dronewatt-lab train --export-csv /tmp/windows.csv

(The CSV's `fold` column, the flight's cross-validation fold, is not a feature:
`lab/scripts/lgbm_cv.py` tunes on those folds; nor are its `phys_*_w` columns, the physics
models' estimates, which `lgbm_cv.py --physics` adds.)
    /tmp/venv-lgbm/bin/python lab/scripts/lgbm_baseline.py /tmp/windows.csv [TARGET_LAG]

TARGET_LAG (samples, default 0) scores the estimate against the measured power that many
samples before each window's newest, as `dronewatt-lab train --target-lag` does for the LSTM
(rows whose lagged sample lies across a telemetry gap are dropped).

The CSV is cut from the data set: write it to a temp dir, never commit it.
"""
import sys

import lightgbm as lgb
import numpy as np
import pandas as pd

IN_FLIGHT_W = 100.0  # same threshold as the LSTM's in-flight MAPE


def main(path, lag=0):
    df = pd.read_csv(path)
    # `phys_*_w` (the physics models' estimates) are `lgbm_cv.py --physics`'s, not this baseline's.
    feats = [c for c in df.columns
             if c not in ("flight", "route", "test", "fold", "t_s", "measured_w") and not c.startswith("phys_")]
    if lag:
        g = df.groupby("flight")
        target, t_back = g.measured_w.shift(lag), g.t_s.shift(lag)
        ok = (np.abs(df.t_s - t_back - 0.1 * lag) < 1e-3) & target.notna()
        df = df.assign(measured_w=target)[ok]
    pool = df[(df.test == 0) & (~df.route.str.startswith("A"))]
    flights = np.array(sorted(pool.flight.unique()))
    rng = np.random.default_rng(7)
    val_flights = set(rng.choice(flights, size=max(1, round(0.12 * len(flights))), replace=False))
    train = pool[~pool.flight.isin(val_flights)]
    val = pool[pool.flight.isin(val_flights)]
    test = df[df.test == 1]
    model = lgb.LGBMRegressor(n_estimators=2000, learning_rate=0.05, num_leaves=63, subsample=0.8,
                              subsample_freq=1, colsample_bytree=0.8, random_state=7, verbose=-1)
    model.fit(train[feats], train.measured_w, eval_set=[(val[feats], val.measured_w)],
              eval_metric="l1", callbacks=[lgb.early_stopping(50, verbose=False)])
    pred = model.predict(test[feats])
    err = pred - test.measured_w.to_numpy()
    inflight = test.measured_w.to_numpy() >= IN_FLIGHT_W
    mape = 100 * np.mean(np.abs(err[inflight] / test.measured_w.to_numpy()[inflight]))
    t = test.assign(pred=pred, abs_err=np.abs(err))
    per = t.groupby("flight").apply(
        lambda g: pd.Series({"mae_w": g.abs_err.mean(),
                             "energy_error_pct": 100 * abs(g.pred.sum() - g.measured_w.sum()) / g.measured_w.sum()}))
    print(per.round(2).to_string())
    f276 = per.mae_w.get(276, float("nan"))
    print(f"LightGBM ({model.best_iteration_} trees, target lag {lag}): test MAE {np.mean(np.abs(err)):.1f} W, "
          f"flight 276 MAE {f276:.1f} W, in-flight MAPE {mape:.2f} %, "
          f"energy error {per.energy_error_pct.mean():.2f} %")


if __name__ == "__main__":
    if len(sys.argv) not in (2, 3):
        sys.exit(__doc__)
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) == 3 else 0)
