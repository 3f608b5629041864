#!/usr/bin/env python3
"""Pre-flight mission energy for planes and quadplanes: `dronewatt plan` against the
simulator (issue 23, "pre-flight mission energy, 10 varied plans (wind included), median
<= 5 %").

Each plan is written as a QGC WPL 110 file, flown by `dronewatt simulate --vehicle plane|
quadplane --plan … --truth …` (the truth: the simulator's own power, integrated) and
forecast by `dronewatt plan … --vehicle plane|quadplane --wind … --payload-g … --json -`
(P50, P90), with the profile's `[forecast]` (model, scale, p90_ratio).

`--set fit` flies the fit plans (never the test ones) and prints that `[forecast]` for each
vehicle: the scale of each model = simulated energy over the model's uncorrected energy
(`models_raw_wh`), summed over the fit plans, on the samples where it runs (the truth split
by the simulator's `vtol` column: the wing where `fw` or a plane, the rotors elsewhere); a
VTOL's rotor model is the published one whose per-plan ratio varies least; the P90 ratio
is the largest simulated/P50 over the fit plans after the scale. `--set test` scores the
held-out plans once with what the profiles hold.

    lab/scripts/plane-mission-eval.py [--set test|fit] [--bin target/debug/dronewatt] [--json OUT]
"""

import argparse
import csv
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile

HOME = (40.4400, -79.9400, 300.0)
R_EARTH = 6_371_000.0


def at(north_m, east_m):
    lat = HOME[0] + math.degrees(north_m / R_EARTH)
    lon = HOME[1] + math.degrees(east_m / (R_EARTH * math.cos(math.radians(HOME[0]))))
    return lat, lon


def waypoints(items, vtol):
    """items: ('wp'|'loiter', north, east, alt[, seconds]); take-off to the first altitude,
    land at home."""
    rows = ["QGC WPL 110", f"0\t1\t0\t16\t0\t0\t0\t0\t{HOME[0]:.7f}\t{HOME[1]:.7f}\t{HOME[2]}\t1"]
    first_alt = items[0][3]
    rows.append(f"1\t0\t3\t{84 if vtol else 22}\t0\t0\t0\t0\t0\t0\t{first_alt}\t1")
    for it in items:
        lat, lon = at(it[1], it[2])
        if it[0] == "loiter":
            rows.append(f"{len(rows) - 1}\t0\t3\t19\t{it[4]}\t0\t0\t0\t{lat:.7f}\t{lon:.7f}\t{it[3]}\t1")
        else:
            rows.append(f"{len(rows) - 1}\t0\t3\t16\t0\t0\t0\t0\t{lat:.7f}\t{lon:.7f}\t{it[3]}\t1")
    rows.append(f"{len(rows) - 1}\t0\t3\t{85 if vtol else 21}\t0\t0\t0\t0\t{HOME[0]:.7f}\t{HOME[1]:.7f}\t0\t1")
    return "\n".join(rows) + "\n"


# (name, vehicle, items, wind m/s, wind from deg, payload g, seed)
TEST = [
    ("p1 square 1 km", "plane", [("wp", 1000, 0, 60), ("wp", 1000, 1000, 60), ("wp", 0, 1000, 60)], 0.0, 0, 0, 11),
    ("p2 out-back 3 km, headwind out", "plane", [("wp", 3000, 0, 80)], 6.0, 0, 0, 12),
    ("p3 survey legs", "plane", [("wp", 800, 0, 100), ("wp", 800, 300, 100), ("wp", 0, 300, 100), ("wp", 0, 600, 100), ("wp", 800, 600, 100)], 4.0, 90, 300, 13),
    ("p4 loiter 120 s", "plane", [("wp", 1500, 500, 70), ("loiter", 1500, 500, 70, 120)], 3.0, 225, 0, 14),
    ("p5 high 150 m, crosswind", "plane", [("wp", 2000, -800, 150), ("wp", 500, -1500, 150)], 7.0, 270, 200, 15),
    ("p6 short hop", "plane", [("wp", 500, 200, 40)], 2.0, 45, 0, 16),
    ("p7 long 6 km triangle", "plane", [("wp", 2500, 0, 90), ("wp", 1200, 2200, 90)], 5.0, 180, 400, 17),
    ("p8 two loiters, climb", "plane", [("loiter", 700, 0, 60, 60), ("wp", 1400, 700, 120), ("loiter", 1400, 700, 120, 90)], 4.0, 315, 0, 18),
    ("q1 quadplane out-back", "quadplane", [("wp", 2500, 0, 60)], 4.0, 0, 500, 19),
    ("q2 quadplane loop, loiter", "quadplane", [("wp", 1200, 800, 80), ("loiter", 1200, 800, 80, 60), ("wp", 0, 1500, 80)], 6.0, 120, 0, 20),
]

FIT = [
    ("f1 out-back 2 km", "plane", [("wp", 2000, 0, 60)], 3.0, 90, 0, 31),
    ("f2 square 600 m", "plane", [("wp", 600, 0, 80), ("wp", 600, 600, 80), ("wp", 0, 600, 80)], 5.0, 0, 200, 32),
    ("f3 loiter 90 s", "plane", [("wp", 900, -900, 100), ("loiter", 900, -900, 100, 90)], 2.0, 200, 0, 33),
    ("f4 quadplane hop", "quadplane", [("wp", 1500, 500, 50)], 3.0, 300, 0, 34),
    ("f5 quadplane square, loiter", "quadplane", [("wp", 900, 0, 70), ("loiter", 900, 900, 70, 60), ("wp", 0, 900, 70)], 5.0, 60, 300, 35),
    ("f6 climb 120 m, tailwind", "plane", [("wp", 2500, 300, 120)], 6.0, 180, 0, 36),
]
ROTOR_MODELS = ["dandrea", "dorling", "stolaroff", "kirschstein", "tseng_solo"]


def truth_wh(path):
    """Simulated energy, Wh: in all, on the wing, on the rotors."""
    e = {"all": 0.0, "wing": 0.0, "rotor": 0.0}
    prev = None
    with open(path) as f:
        for r in csv.DictReader(f):
            t = float(r["t_s"])
            if prev is not None:
                de = float(prev["power_w"]) * (t - float(prev["t_s"])) / 3600.0
                e["all"] += de
                e["wing" if prev["vtol"] in ("fw", "undefined") else "rotor"] += de
            prev = r
    return e


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--set", choices=["test", "fit"], default="test")
    ap.add_argument("--bin", default="target/debug/dronewatt")
    ap.add_argument("--json", help="write the rows as JSON here")
    a = ap.parse_args()
    plans = TEST if a.set == "test" else FIT
    rows = []
    with tempfile.TemporaryDirectory(prefix="plane-mission-eval-") as d:
        for name, vehicle, items, wind, wdir, payload, seed in plans:
            wp = os.path.join(d, "p.waypoints")
            with open(wp, "w") as f:
                f.write(waypoints(items, vehicle == "quadplane"))
            truth = os.path.join(d, "t.csv")
            subprocess.run(
                [a.bin, "simulate", "--vehicle", vehicle, "--plan", wp, "--out", os.path.join(d, "f.tlog"),
                 "--truth", truth, "--wind-mps", str(wind), "--wind-dir-deg", str(wdir),
                 "--payload-g", str(payload), "--seed", str(seed)],
                check=True, capture_output=True)
            out = subprocess.run(
                [a.bin, "plan", wp, "--vehicle", vehicle, "--wind", f"{wind}@{wdir}",
                 "--payload-g", str(payload), "--json", "-"],
                check=True, capture_output=True, text=True).stdout
            fc = json.loads(out)["forecast"]
            split = truth_wh(truth)
            t = split["all"]
            rows.append({
                "split": split, "raw": dict(fc["models_raw_wh"]),
                "plan": name, "vehicle": vehicle, "wind": f"{wind}@{wdir}", "payload_g": payload,
                "truth_wh": t, "p50_wh": fc["energy_p50_wh"], "p90_wh": fc["energy_p90_wh"],
                "error_pct": 100.0 * (fc["energy_p50_wh"] - t) / t,
                "p90_covers": t <= fc["energy_p90_wh"],
            })
    print(f"| plan | vehicle | wind m/s@from | payload g | simulated Wh | P50 Wh | P50 error | P90 Wh | P90 covers |")
    print("|---|---|---|---:|---:|---:|---:|---:|---|")
    for r in rows:
        print(f"| {r['plan']} | {r['vehicle']} | {r['wind']} | {r['payload_g']} | {r['truth_wh']:.2f} | "
              f"{r['p50_wh']:.2f} | {r['error_pct']:+.1f} % | {r['p90_wh']:.2f} | {'yes' if r['p90_covers'] else 'no'} |")
    errs = [abs(r["error_pct"]) for r in rows]
    print(f"\n{a.set} set, {len(rows)} plans: median |P50 error| {statistics.median(errs):.2f} %, "
          f"max {max(errs):.2f} %, P90 covers {sum(r['p90_covers'] for r in rows)}/{len(rows)}")
    if a.set == "fit":
        fit(rows)
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=1)


def fit(rows):
    """The `[forecast]` of each vehicle from the fit plans (see the module docs)."""
    for vehicle in sorted({r["vehicle"] for r in rows}):
        rs = [r for r in rows if r["vehicle"] == vehicle]
        scale = {"fixed_wing": sum(r["split"]["wing"] for r in rs) / sum(r["raw"]["fixed_wing"] for r in rs)}
        model = "fixed_wing"
        if any(r["split"]["rotor"] > 0.01 for r in rs):
            def spread(m):
                ratios = [r["split"]["rotor"] / r["raw"][m] for r in rs if r["raw"][m] > 0]
                return statistics.pstdev(ratios) / statistics.mean(ratios) if ratios else math.inf
            model = min(ROTOR_MODELS, key=spread)
            scale[model] = sum(r["split"]["rotor"] for r in rs) / sum(r["raw"][model] for r in rs)
        p50 = [sum(k * r["raw"][m] for m, k in scale.items()) for r in rs]
        # a handful of fit plans is no spread: the P90 is floored at 1.10 (an ASSUMPTION)
        p90 = max(1.10, max(r["truth_wh"] / p for r, p in zip(rs, p50)))
        print(f"\n{vehicle}: [forecast] from {len(rs)} fit plans")
        print('model = "fixed_wing"  # on the wing; ' + (f"{model} on the rotors (scale)" if model != "fixed_wing" else "a plane"))
        print("scale = { " + ", ".join(f"{m} = {k:.3f}" for m, k in sorted(scale.items())) + " }")
        print(f"p90_ratio = {p90:.3f}")


if __name__ == "__main__":
    sys.exit(main())
