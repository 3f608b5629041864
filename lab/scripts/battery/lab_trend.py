#!/usr/bin/env python3
"""The choice of `src/battery/trend.rs` on ProgPy's fit packs (issue 44): a Python port of the
trend (V = a + b*t + c*I, exponentially weighted, from SKIP s after take-off; the dip; the
slope scaled to the power), alone or with the circuit's crossing, scored like
progpy_score.py (time to BATT_LOW_VOLT at 25/50/75 % of the way).

  progpy_score.py --dir DIR --set fit --bin OLD_BIN --json circuit.json   # the circuit alone
  lab_trend.py --dir DIR --circuit circuit.json [--set fit]

Choose on the fit set only; the score set is scored once, with progpy_score.py.
"""
import argparse
import glob
import json
import math
import os
import statistics
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from progpy_score import FRACS, readings  # noqa: E402

TB48D_AH = 103.37364527025169 / 22.8


class Trend:
    def __init__(self, tau, ridge=1e-3):
        self.tau, self.ridge = tau, ridge
        self.S, self.r = np.zeros((3, 3)), np.zeros(3)
        self.t, self.d, self.pw, self.n, self.coef = None, 0.0, 0.0, 0, None

    def add(self, t, v, i):
        if self.t is not None:
            dt = t - self.t
            k = math.exp(-dt / self.tau)
            self.S *= k
            self.r *= k
            self.d *= k
            kp = math.exp(-dt / 30.0)
            self.pw = kp * self.pw + (1 - kp) * v * i
        else:
            self.pw = v * i
        self.t = t
        x = np.array([1.0, t, i])
        if self.coef is not None and self.n >= 10:
            self.d = max(self.d, -(v - x @ self.coef))
        self.S += np.outer(x, x)
        self.r += x * v
        self.n += 1
        S = self.S.copy()
        S[2, 2] += self.ridge * S[0, 0]
        try:
            self.coef = np.linalg.solve(S, self.r)
        except np.linalg.LinAlgError:
            self.coef = None

    def ttl(self, low, p, dip=True):
        if self.n < 10 or self.coef is None:
            return None
        a, b, c = self.coef
        c = min(c, 0.0)
        p = max(p, self.pw)
        slope = b * p / max(self.pw, 1e-3)
        if slope >= -1e-9:
            return None
        return max((a + b * self.t + c * p / low - (self.d if dip else 0.0) - low) / -slope, 0.0)


def trend_errors(d, set_, tau, skip, dip):
    out = {}
    for path in sorted(glob.glob(os.path.join(d, "*.truth.json"))):
        tr = json.load(open(path))
        if tr["set"] != set_ or tr["t_cross"] is None:
            continue
        rows = readings(path.replace(".truth.json", ".tlog"))
        t_first = rows[0][0]
        t0, tc = tr["t_takeoff"], tr["t_cross"]
        loaded = 3.0 * min(max(tr["cap_mah"] / 1000.0 / TB48D_AH, 0.05), 1.0)
        qs = [t0 + q * (tc - t0) for q in FRACS]
        tt, o = Trend(tau), {}
        for t, v, i in rows:
            t -= t_first
            for j, tq in enumerate(qs):
                if j not in o and t >= tq - 1e-9:
                    p = tt.ttl(tr["low_v"], tt.pw, dip)
                    o[j] = None if p is None else (p - (tc - tq)) / (tc - tq)
            if t > qs[-1]:
                break
            if t >= t0 + skip and i >= loaded:
                tt.add(t, v, i)
        out[tr["name"]] = [o.get(j) for j in range(3)]
    return out


def combine(rule, t, m):
    if t is None or m is None:
        return t if t is not None else m
    if rule == "trend":
        return t
    if rule == "sooner":
        return min(t, m)
    if rule == "geo":
        return math.sqrt((1 + t) * (1 + m)) - 1
    return min(t, float(rule[3:]) * (1 + m) - 1)  # capN: the trend capped at N x the circuit's


def summary(errs):
    h = [e for e in errs if e is not None]
    return {"forecasts": len(errs), "missing": len(errs) - len(h),
            "median_abs_pct": round(100 * statistics.median([abs(e) for e in h])),
            "late_over_25pct": int(sum(e > 0.25 for e in h)), "worst_late_pct": round(100 * float(max(h)))}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--dir", required=True)
    ap.add_argument("--circuit", required=True, help="progpy_score.py --json of the circuit alone")
    ap.add_argument("--set", default="fit")
    a = ap.parse_args()
    circuit = {f["name"]: f["ttl"] for f in json.load(open(a.circuit))["per_flight"]}
    for tau in (120.0, 240.0):
        for dip in (False, True):
            te = trend_errors(a.dir, a.set, tau, 10.0, dip)
            for rule in ("trend", "sooner", "geo", "cap2", "cap3"):
                errs = [combine(rule, tl[j], circuit[n].get(str(q)))
                        for n, tl in te.items() for j, q in enumerate(FRACS)]
                print(json.dumps({"memory_s": tau, "dip": dip, "rule": rule, **summary(errs)}))


if __name__ == "__main__":
    main()
