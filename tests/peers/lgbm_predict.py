#!/usr/bin/env python3
"""LightGBM itself, the independent evaluator dronewatt's trees (src/model/trees.rs) are
checked against: `lgbm_predict.py MODEL ROWS.csv` prints the model's estimate of each row
of ROWS.csv (a header of input names, then one row of numbers each; `nan` where missing),
one a line, in full precision."""
import sys

import lightgbm as lgb
import numpy as np

model, rows = sys.argv[1], sys.argv[2]
b = lgb.Booster(model_file=model)
with open(rows) as f:
    names = f.readline().strip().split(",")
    if names != b.feature_name():
        sys.exit(f"{rows}: the header is not the model's inputs")
    x = np.array([[float(v) for v in line.split(",")] for line in f if line.strip()], dtype=np.float64)
for p in b.predict(x, num_threads=1):
    print(repr(float(p)))
