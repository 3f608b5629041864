#!/usr/bin/env python3
"""ProgPy's own prognoser as a baseline on the ProgPy flights (issue 44): its UKF state
estimator and unscented-transform predictor, on the flight's own cell model (the truth's model
class: an advantage neither dronewatt nor PX4 has), started from the flight's true start state
(`charged_to` at the truth's start charge and rest: a second advantage), fed the log's per-cell
voltage and current at 1 Hz, and asked at 25/50/75 % of the way from take-off to the crossing
when the cell falls under BATT_LOW_VOLT (ProgPy's EOD event with VEOD = the threshold a cell),
flying on at the last 30 s's mean power.

  progpy_prognoser.py --dir DIR [--set score] [--json OUT]

Prints (and writes) the same summary as progpy_score.py's, and per-flight errors.
"""
import argparse
import glob
import json
import os
import statistics
import sys

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, here)
sys.path.insert(0, os.path.join(here, "..", "..", "..", "tests", "peers"))
from progpy_score import FRACS, readings, summarise  # noqa: E402
import progpy_flights as pf  # noqa: E402
from progpy.state_estimators import UnscentedKalmanFilter  # noqa: E402
from progpy.predictors import UnscentedTransformPredictor  # noqa: E402


def prognose(tr, rows):
    """{frac: (forecast − truth) / truth} for one flight."""
    cell = pf.charged_to(tr["cell"], tr["soc0"])
    for _ in range(int(tr["rest_s"])):
        cell.step(0.0, 1.0)
    m = cell.m
    m.parameters["VEOD"] = tr["low_v"] / tr["s"]
    s, p = tr["s"], tr["p"]
    t_first = rows[0][0]
    filt = UnscentedKalmanFilter(m, cell.x, t0=0.0)
    t0, tc = tr["t_takeoff"], tr["t_cross"]
    qs = {q: t0 + q * (tc - t0) for q in FRACS}
    out, last, recent = {}, None, []
    for t, v, i in rows:
        t -= t_first
        if len(out) == len(FRACS):
            break
        recent = [(tt, w) for tt, w in recent if tt > t - 30.0] + [(t, v * i / (s * p))]
        if last is None or t - last >= 1.0 - 1e-9:
            if last is not None:
                y = m.output(filt.x.mean)
                filt.estimate(t, m.InputContainer({"i": i / p}), m.OutputContainer({"t": y["t"], "v": v / s}))
            last = t
        for q, tq in qs.items():
            if q not in out and t >= tq - 1e-9:
                pw = statistics.mean(w for _, w in recent)

                def load(_t, x=None, pw=pw):
                    vv = m.output(x)["v"] if x is not None else 3.6
                    return m.InputContainer({"i": pw / max(float(vv), 1.0)})
                res = predictor_run(m, filt, load)
                truth = tc - tq
                out[q] = None if res is None else (res - truth) / truth
    return out


def predictor_run(m, filt, load):
    pred = UnscentedTransformPredictor(m)
    r = pred.predict(filt.x, load, dt=1.0, horizon=3600.0, save_freq=600.0, events=["EOD"])
    toe = r.time_of_event.mean.get("EOD")
    if toe is None or not toe == toe:
        return None
    return float(toe)  # from now: the predictor starts at t0 = 0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--dir", required=True)
    ap.add_argument("--set", default="score")
    ap.add_argument("--json", default=None)
    ap.add_argument("--only", default=None, help="one flight's name")
    a = ap.parse_args()
    fl = []
    for path in sorted(glob.glob(os.path.join(a.dir, "*.truth.json"))):
        tr = json.load(open(path))
        if tr["set"] != a.set or tr["t_cross"] is None or (a.only and tr["name"] != a.only):
            continue
        rows = readings(path.replace(".truth.json", ".tlog"))
        f = {"name": tr["name"], "ttl": prognose(tr, rows)}
        print(json.dumps(f), flush=True)
        fl.append(f)
    res = {"flights": len(fl), "set": a.set, "progpy_prognoser": summarise(fl), "per_flight": fl}
    print(json.dumps(res["progpy_prognoser"], indent=1))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(res, f, indent=1)


if __name__ == "__main__":
    main()
