#!/usr/bin/env python3
"""Folds by day instead of by flight: how much does a new day, or a kind of flight the fit
has not seen, cost? (docs/src/accuracy.md, "A held-out day")

Flights flown on one day share its weather, its packs and its kind of mission, so a
by-flight fold keeps a held-out flight's neighbours in the fit. Here the 18 training days
are dealt into 5 groups (largest day first, to the group with the fewest flights), and
LightGBM #0 (`lgbm_cv.py`'s configuration 0, 600 trees, strided 2, seed 7) is scored on
both kinds of folds, overall and per route:

    dronewatt-lab train --features home --export-csv /tmp/home.csv --cv 5 --seed 7 --target-lag 3
    lab/scripts/dayfold.py cv /tmp/home.csv --out /tmp/dayfold        # ~3 min, one thread

`cv` also writes, for the group that holds the hover day (route H; the first group),
`flights-fit.txt` (the other groups' flights, for `train --flights`), `flights-held.txt`
and `held-lgbm.csv` (LightGBM fitted on the others, on every held-out window). The LSTM
then gets the same split, and `blend` scores the network, the trees, round 10's blend
(0.7 / 0.3; the shipped one is 0.65 / 0.35 since round 11) and the blend with the trees
only where the vehicle moves:

    dronewatt-lab train $FLAGS --init-seed 7 --flights $(cat /tmp/dayfold/flights-fit.txt) --out /tmp/dayfold/m7
    for f in $(tr , ' ' < /tmp/dayfold/flights-held.txt); do
      dronewatt replay flights.csv.gz --flight $f --speed max -q --data-dir off \\
        --model /tmp/dayfold/m7 --json /tmp/dayfold/replay/$f.jsonl; done
    lab/scripts/dayfold.py blend /tmp/dayfold

(`FLAGS`: the network's command in the model card without `--init-seed` and `--out`.) The
network's estimate at replay row t is for t - 0.3 s (the card's target lag), LightGBM's row
is the window's newest sample; rows are joined on flight and time and kept where both say
the same measured power.

`inputs` scores LightGBM #0 on both kinds of folds with inputs that could carry a route's
identity taken out or made heading-invariant (round 11's screen; ~25 min, one thread):

    lab/scripts/dayfold.py inputs /tmp/home.csv [--json /tmp/inputs.json]

`routes` asks whether a physics input makes the trees extrapolate to a route no training
flight flies (screen P): LightGBM #0 plain, with the physics models' estimates as inputs, and
on the residual over a linear stack of them, by flight and with each training route but R1
held out in turn (~15 min, one thread):

    lab/scripts/dayfold.py routes /tmp/home.csv [--json /tmp/routes.json]

Training flights only: the script refuses a test flight. Needs numpy, pandas and lightgbm
(`lgbm_cv.py`'s environment).
"""
import argparse
import glob
import json
import os
import sys

import numpy as np
import pandas as pd

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import lgbm_cv as L  # noqa: E402  (the same rows, configuration and metrics)
from blend_cv import KEYS, TEST_FLIGHTS, flight_table  # noqa: E402

GROUPS = 5
LAG = 3
TREES = 600
WEIGHT_LSTM = 0.7  # round 10's share, as its screen ran (the card's is 0.65 since round 11)


def day_groups(pool):
    """Each training day to one of GROUPS groups: largest day first, to the emptiest group."""
    per_day = pool.groupby("date").flight.nunique().sort_values(ascending=False, kind="stable")
    load, group = [0] * GROUPS, {}
    for day, n in per_day.items():
        g = int(np.argmin(load))
        group[day], load[g] = g, load[g] + n
    return pool.date.map(group), load


def training_pool(csv):
    """The export's training windows with their day group (`day_fold`), and the input names."""
    df, feats = L.load(csv, LAG)
    pool = df[df.fold >= 0].copy()
    if set(pool.flight) & TEST_FLIGHTS:
        sys.exit("a test flight in the training pool: export again")
    pool["date"] = pool.flight.map(flight_table().date)
    pool["day_fold"], load = day_groups(pool)
    return pool, feats, load


def fit_predict(train, held, feats):
    b = L.lgb.train(L.lgb_params(L.configs()[0]), L.dataset(L.strided(train), feats, False), TREES)
    return b.predict(held[feats].to_numpy(np.float32))


def pooled(rows, key):
    """A route's figure over the folds it appears in: the folds' figures weighted by windows
    (exact for MAE; for MAPE, a mean over in-flight windows, and the energy error, a mean over
    flights, an approximation)."""
    w = np.array([r["windows"] for r in rows], float)
    return float(np.average([r[key] for r in rows], weights=w))


def run_cv(a):
    pool, feats, load = training_pool(a.csv)
    os.makedirs(a.out, exist_ok=True)
    out = {"command": "lab/scripts/dayfold.py cv windows.csv", "flights_per_day_group": load, "folds": {}}
    print(f"{pool.flight.nunique()} training flights on {pool.date.nunique()} days; day groups of {load} flights")
    for name, col in (("by flight", "fold"), ("by day", "day_fold")):
        per_fold, per_route = [], {}
        for k in range(GROUPS):
            held = pool[pool[col] == k]
            pred = fit_predict(pool[pool[col] != k], held, feats)
            per_fold.append(L.scores(held, pred))
            for route in sorted(held.route.unique()):
                m = (held.route == route).to_numpy()
                per_route.setdefault(route, []).append(L.scores(held[m], pred[m]))
            if col == "day_fold" and k == 0:
                held[["flight", "route", "t_s", "measured_w"]].assign(
                    pred_w=pred, speed=np.sqrt(held.velocity_x ** 2 + held.velocity_y ** 2 + held.velocity_z ** 2)
                ).to_csv(os.path.join(a.out, "held-lgbm.csv"), index=False, float_format="%.3f")
                for f, flights in (("flights-held.txt", held.flight), ("flights-fit.txt", pool.flight[pool[col] != k])):
                    with open(os.path.join(a.out, f), "w") as fh:
                        fh.write(",".join(str(x) for x in sorted(flights.unique())))
        res = {key: float(np.mean([r[key] for r in per_fold])) for key in L.summary(per_fold)}
        res["routes"] = {r: {key: pooled(v, key) for key in KEYS}
                         for r, v in per_route.items()}
        out["folds"][name] = res
        print(f"{name}: MAE {res['mae_w']:.2f} W, MAPE {res['mape_in_flight_pct']:.3f} %, energy "
              f"{res['energy_error_pct']:.2f} %; " + "; ".join(
                  f"{r} {v['mape_in_flight_pct']:.2f} % / {v['energy_error_pct']:.2f} %"
                  for r, v in res["routes"].items() if r in ("H", "R1")) + " (route: pooled MAPE / energy)")
    with open(os.path.join(a.out, "dayfold.json"), "w") as fh:
        json.dump(out, fh, indent=1)
        fh.write("\n")


LAG_SUFFIXES = ("", "_lag1", "_lag3", "_lag9")


def add_heading_invariant(p):
    """Add to `p`, per lag: roll and pitch from the quaternion (its yaw dropped), the horizontal velocity
    as forward and lateral in the yaw frame, and the wind's angle (deg from north) relative to
    the yaw as its sine and cosine. The rotation is atan2(v_y, v_x) - yaw, the convention the
    velocity and the quaternion share (ROS: ENU and FLU to ENU); the flights cannot check it,
    since the M100's yaw does not follow its track on them."""
    for s in LAG_SUFFIXES:
        x, y, z, w = (p[f"orientation_{c}{s}"].to_numpy() for c in "xyzw")
        yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
        p[f"roll{s}"] = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
        p[f"pitch{s}"] = np.arcsin(np.clip(2 * (w * y - z * x), -1, 1))
        vx, vy = p[f"velocity_x{s}"].to_numpy(), p[f"velocity_y{s}"].to_numpy()
        speed, angle = np.hypot(vx, vy), np.arctan2(vy, vx) - yaw
        p[f"v_fwd{s}"], p[f"v_lat{s}"] = speed * np.cos(angle), speed * np.sin(angle)
        wind = np.radians(90 - p[f"wind_angle{s}"].to_numpy()) - yaw
        p[f"wind_rel_sin{s}"], p[f"wind_rel_cos{s}"] = np.sin(wind), np.cos(wind)


def run_inputs(a):
    pool, feats, _ = training_pool(a.csv)
    missing = [f"wind_angle{s}" for s in LAG_SUFFIXES if f"wind_angle{s}" not in feats]
    if missing:
        sys.exit(f"{a.csv}: no {', '.join(missing)}: this step needs the home export at lags 0, 1, 3, 9")
    add_heading_invariant(pool)

    def without(*names):
        return [f for f in feats if not f.startswith(names)]
    invariant = without("orientation_", "velocity_x", "velocity_y", "wind_angle") + [
        f"{n}{s}" for s in LAG_SUFFIXES for n in ("roll", "pitch", "v_fwd", "v_lat", "wind_rel_sin", "wind_rel_cos")]
    variants = {"the home inputs": feats, "without the wind's angle": without("wind_angle"),
                "without the distance to home": without("home_distance_m"),
                "without either": without("wind_angle", "home_distance_m"), "heading-invariant": invariant}
    out = {"command": "lab/scripts/dayfold.py inputs windows.csv", "variants": {}}
    print("| LightGBM #0, 600 trees | inputs | by flight: MAE / MAPE / energy | by day: MAE / MAPE / energy |")
    print("|---|---|---|---|")
    for name, fs in variants.items():
        res = {}
        for kind, col in (("by flight", "fold"), ("by day", "day_fold")):
            per = []
            for k in range(GROUPS):
                held = pool[pool[col] == k]
                per.append(L.scores(held, fit_predict(pool[pool[col] != k], held, fs)))
            res[kind] = {key: float(np.mean([r[key] for r in per])) for key in KEYS}
        out["variants"][name] = {"inputs": len(fs), **res}
        print(f"| {name} | {len(fs)} | " + " | ".join(
            f"{v['mae_w']:.2f} W / {v['mape_in_flight_pct']:.3f} % / {v['energy_error_pct']:.2f} %"
            for v in res.values()) + " |", flush=True)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=1)
            fh.write("\n")


PHYSICS_KINDS = ("plain", "physics inputs", "physics residual")


def run_routes(a):
    """Screen P (report only): does a physics input make the trees extrapolate to a route none
    of their training flights flies? LightGBM #0 plain, with the seven physics estimates as
    inputs, and on the residual over a linear stack of them (least squares on the fit part's
    in-flight windows), on the by-flight folds and with each training route but R1 held out
    in turn. The rule, written before it ran, is in docs/src/accuracy.md ("A held-out day")."""
    df, feats = L.load(a.csv, LAG, physics=True)
    pool = df[df.fold >= 0].copy()
    if set(pool.flight) & TEST_FLIGHTS:
        sys.exit("a test flight in the training pool: export again")
    phys = [c for c in feats if c.startswith("phys_")]
    base = [c for c in feats if not c.startswith("phys_")]
    def design(d):
        return np.column_stack([d[phys].to_numpy(float), np.ones(len(d))])

    def predict(kind, fit, held):
        if kind == "plain":
            return fit_predict(fit, held, base)
        if kind == "physics inputs":
            return fit_predict(fit, held, base + phys)
        x, y = design(fit), fit.measured_w.to_numpy()
        fl = y >= L.IN_FLIGHT_W
        coef = np.linalg.lstsq(x[fl], y[fl], rcond=None)[0]
        return design(held) @ coef + fit_predict(fit.assign(measured_w=y - x @ coef), held, base)

    routes = sorted(r for r in pool.route.unique() if r != "R1")
    splits = {"by flight": [(pool.fold != k, pool.fold == k) for k in range(GROUPS)],
              "route held out": [(pool.route != r, pool.route == r) for r in routes]}
    print(f"{pool.flight.nunique()} training flights; held out in turn: " + ", ".join(
        f"{r} ({pool.flight[pool.route == r].nunique()} flights)" for r in routes), flush=True)
    out = {"command": "lab/scripts/dayfold.py routes windows.csv", "routes_held_out": routes, "kinds": {}}
    for kind in PHYSICS_KINDS:
        res = {}
        for name, folds in splits.items():
            per = [L.scores(pool[h], predict(kind, pool[f], pool[h])) for f, h in folds]
            if name == "by flight":
                res[name] = {key: float(np.mean([r[key] for r in per])) for key in KEYS}
            else:
                res[name] = {key: pooled(per, key) for key in KEYS}
                res[name]["routes"] = {r: {key: s[key] for key in KEYS} for r, s in zip(routes, per)}
        out["kinds"][kind] = res
        print(f"| {kind} | " + " | ".join(
            f"{res[n]['mae_w']:.2f} W / {res[n]['mape_in_flight_pct']:.3f} % / {res[n]['energy_error_pct']:.2f} %"
            for n in splits) + " | " + ", ".join(
            f"{r} {v['mape_in_flight_pct']:.2f} %" for r, v in res["route held out"]["routes"].items()) + " |",
            flush=True)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=1)
            fh.write("\n")


def run_blend(a):
    rows = []
    for path in sorted(glob.glob(os.path.join(a.out, "replay", "*.jsonl"))):
        flight = int(os.path.basename(path).split(".")[0])
        if flight in TEST_FLIGHTS:
            sys.exit(f"{path}: flight {flight} is a test flight")
        with open(path) as fh:
            for line in fh:
                x = json.loads(line)
                if x.get("type") == "estimate" and "lstm" in x.get("models", {}):
                    rows.append((flight, round(10 * x["t"]), x["measured_w"], x["models"]["lstm"]))
    if not rows:
        sys.exit(f"{a.out}/replay: no replay with the network's estimates (see the module's docstring)")
    r = pd.DataFrame(rows, columns=["flight", "key", "measured", "lstm"])
    measured = r.set_index(["flight", "key"]).measured
    g = pd.read_csv(os.path.join(a.out, "held-lgbm.csv"))
    g["key"] = np.round(10 * g.t_s).astype(int)
    j = g.merge(r[["flight", "key", "lstm"]], on=["flight", "key"])
    at_instant = measured.reindex(list(zip(j.flight, j.key - LAG))).to_numpy()
    agree = np.abs(at_instant - j.measured_w) < 0.01
    print(f"{len(g)} held-out windows, {len(j)} joined, {int((~agree).sum())} dropped (measured power disagrees)")
    j = j[agree]
    blend = WEIGHT_LSTM * j.lstm + (1 - WEIGHT_LSTM) * j.pred_w
    cands = {"network": j.lstm, "trees": j.pred_w, "blend 0.7": blend,
             "blend where moving (speed >= 1 m/s), else the network": np.where(j.speed >= 1.0, blend, j.lstm)}
    print("| held-out day group | route | MAE (W) | in-flight MAPE | energy error |\n|---|---|---|---|---|")
    for route in sorted(j.route.unique()):
        d = j.route == route
        for name, est in cands.items():
            s = L.scores(j[d], np.asarray(est)[d.to_numpy()])
            print(f"| {name} | {route} ({s['flights']} flights) | {s['mae_w']:.1f} | "
                  f"{s['mape_in_flight_pct']:.2f} % | {s['energy_error_pct']:.2f} % |")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("step", choices=["cv", "blend", "inputs", "routes"])
    ap.add_argument("csv", nargs="?", help="cv, inputs, routes: the home export (train --export-csv)")
    ap.add_argument("--out", default="/tmp/dayfold", help="working folder (default /tmp/dayfold)")
    ap.add_argument("--json", help="inputs, routes: write the figures (no data rows) here")
    a = ap.parse_args()
    if a.step == "blend" and a.csv:
        a.out = a.csv  # `blend DIR`
    if a.step in ("cv", "inputs", "routes") and not a.csv:
        ap.error(f"{a.step} needs the export CSV")
    {"cv": run_cv, "blend": run_blend, "inputs": run_inputs, "routes": run_routes}[a.step](a)


if __name__ == "__main__":
    main()
