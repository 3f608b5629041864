#!/usr/bin/env python3
"""The spec sheet's hover-efficiency prior, fitted across airframes, leave-one-airframe-out.

Momentum theory gives the ideal hover power of a multirotor from four facts (take-off mass m,
rotors N, propeller diameter D, air density rho): P_ideal = T^1.5 / sqrt(2 rho A), T = m g,
A = N pi D^2 / 4. What a battery pays is P_hover = P_ideal / eta_h + P_avio: eta_h is the
figure of merit times the motors' and ESCs' efficiency, the one number a spec sheet does not
give. This script lists each airframe's measured, simulated or published hover power, the
eta_h it implies, and for each airframe the prior fitted on the others (the geometric mean
and log-spread of their eta_h) with the hover power that prior forecasts.

    .venv-py/bin/python scripts/spec-priors.py [--json PATH] [--markdown]

Sources (the `source` column): the M100 data set's hover flights (../shared/data/m100, routes
H, flights 221-224, read when present; else the figure this script printed when it was
run, 481.4 W), the `multirotor` package's Tarot T18 (its motor and propeller constants, the
hover solved with its own Motor model), DJI's published hovering times (as remembered, not
re-checked: the table says so), the 3DR Solo regression the project ships (tseng_solo's
intercept, Tseng et al. 2017) and the simulators written here (config/vehicles/*.toml,
hover as tests/it/sim_airframes.rs checks it).
"""
import argparse
import gzip
import json
import math
import os
import statistics
import sys

RHO, G = 1.225, 9.81
AVIONICS_W = 8.0  # the spec sheet's avionics prior (src/model/spec.rs), subtracted first
HERE = os.path.dirname(os.path.abspath(__file__))
M100_CSV = os.path.join(HERE, "..", "..", "shared", "data", "m100", "flights.csv.gz")


def ideal_hover_w(m, n, d):
    t = m * G
    a = n * math.pi * d * d / 4
    return t ** 1.5 / math.sqrt(2 * RHO * a)


def m100_hover_w():
    """Median electrical power of the data set's hover flights (route H, still, payload 0)."""
    if not os.path.exists(M100_CSV):
        return 481.4, "M100 data set absent: the figure of the last run"
    import csv
    per = {}
    with gzip.open(M100_CSV, "rt") as f:
        for row in csv.DictReader(f):
            if row["route"] != "H" or float(row["payload"]) != 0.0:
                continue
            v = math.hypot(float(row["velocity_x"]), float(row["velocity_y"]))
            p = float(row["battery_voltage"]) * float(row["battery_current"])
            if v < 0.5 and abs(float(row["velocity_z"])) < 0.3 and p > 150:
                per.setdefault(row["flight"], []).append(p)
    meds = [statistics.median(v) for v in per.values()]
    return statistics.median(meds), f"median of flights {', '.join(sorted(per))}"


def t18_hover_w():
    """The multirotor package's Tarot T18 in hover: each motor's current from its own Motor."""
    from multirotor.models.tarott18 import MP, PP, VP, BP, SP
    from multirotor.simulation import Motor
    import copy
    t = VP.mass * G / len(VP.propellers)
    omega = math.sqrt(t / PP.k_thrust)
    mp = copy.deepcopy(MP)
    mp.k_drag = PP.k_drag
    motor = Motor(mp, SP)
    # the voltage that holds omega: back-EMF plus the current the propeller's torque needs
    volts = omega * mp.k_emf + PP.k_drag * omega ** 2 / mp.k_torque * mp.resistance
    motor.speed = omega
    motor.step(volts / mp.speed_voltage_scaling, max_voltage=BP.max_voltage)
    watts = motor.current_average(BP.max_voltage) * BP.max_voltage * len(VP.propellers)
    return watts, VP.mass, len(VP.propellers)


def airframes():
    m100_w, m100_how = m100_hover_w()
    rows = [
        # name, kg, rotors, prop m, hover W, kind, source
        ("DJI M100 (data set)", 2.431, 4, 0.3302, m100_w, "measured",
         f"Rodrigues et al. 2021 data set, hover flights ({m100_how}); mass as config/vehicles/m100.toml"),
        ("DJI M100 (published)", 2.431, 4, 0.3302, 129.96 / (28 / 60), "published",
         "DJI M100 specs: TB48D 129.96 Wh, 28 min hovering, no payload (as remembered, not re-checked)"),
        ("DJI Mavic Pro (published)", 0.734, 4, 0.2108, 43.6 / (24 / 60), "published",
         "DJI Mavic Pro specs: 43.6 Wh, 24 min hovering, 8330 props (as remembered, not re-checked)"),
        ("3DR Solo (regression)", 1.5, 4, 0.254, 251.7, "published",
         "Tseng et al. 2017 Solo form's intercept (tseng_solo in m100.toml); 1.5 kg, 10-inch props"),
        ("Holybro X500 (simulator here)", 2.0, 4, 0.254, 284.0, "simulator",
         "config/vehicles/x500.toml flown by `dronewatt simulate` (ASSUMPTION-built)"),
        ("3S quad (simulator here)", 1.0, 4, 0.1778, 145.0, "simulator",
         "config/vehicles/quad-3s.toml flown by `dronewatt simulate` (ASSUMPTION-built)"),
    ]
    try:
        w, m, n = t18_hover_w()
        rows.append(("Tarot T18 (multirotor peer)", m, n, 0.4572, w, "peer",
                     "multirotor 0.5.0 models/tarott18.py: k_thrust, k_drag, motor R, k_emf (its Motor)"))
    except ImportError as e:
        print(f"multirotor not importable ({e}); the T18 row is left out", file=sys.stderr)
    out = []
    for name, m, n, d, w, kind, src in rows:
        ideal = ideal_hover_w(m, n, d)
        out.append(dict(airframe=name, kg=m, rotors=n, prop_m=d, hover_w=round(float(w), 1),
                        ideal_w=round(ideal, 1), eta_h=round(ideal / (w - AVIONICS_W), 4),
                        kind=kind, source=src))
    return out


def prior(etas):
    logs = [math.log(e) for e in etas]
    return math.exp(statistics.mean(logs)), statistics.stdev(logs)


def size_fits(rows):
    """Does a size feature carry η_h across airframes? For each airframe left out, ln η_h
    fitted as a line in ln(feature) on the others (least squares), and what it forecasts for
    the one left out: propeller diameter, disk loading (thrust per disk area) and thrust per
    rotor, the spec sheet's facts that set a rotor's Reynolds number and a motor's size."""
    import numpy as np

    def feat(r, name):
        t = r["kg"] * G / r["rotors"]
        return math.log({"prop_m": r["prop_m"], "disk_loading": t / (math.pi * r["prop_m"] ** 2 / 4),
                         "thrust_per_rotor": t}[name])
    out = {}
    for name in ("prop_m", "disk_loading", "thrust_per_rotor"):
        per = []
        for r in rows:
            o = [q for q in rows if q is not r]
            slope, icpt = np.polyfit([feat(q, name) for q in o], [math.log(q["eta_h"]) for q in o], 1)
            eta = math.exp(icpt + slope * feat(r, name))
            per.append(dict(airframe=r["airframe"], eta_h=r["eta_h"], forecast_eta_h=round(eta, 3),
                            slope=round(float(slope), 2)))
        out[name] = dict(loao=per, median_abs_log_err=round(float(np.median(
            [abs(math.log(p["forecast_eta_h"] / p["eta_h"])) for p in per])), 3))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--json", help="write the table and the priors as JSON here")
    ap.add_argument("--markdown", action="store_true", help="print the book's table")
    ap.add_argument("--plot", help="draw each airframe's hover power and the forecast of the prior without it here")
    a = ap.parse_args()
    rows = airframes()
    for r in rows:
        others = [o["eta_h"] for o in rows if o is not r]
        med, sd = prior(others)
        fc = r["ideal_w"] / med + AVIONICS_W
        r["loao_eta"] = round(med, 4)
        r["loao_sd"] = round(sd, 4)
        r["loao_hover_w"] = round(fc, 1)
        r["loao_err_pct"] = round(100 * (fc / r["hover_w"] - 1), 1)
        r["loao_p90_covers"] = bool(fc * math.exp(1.2816 * sd) >= r["hover_w"])
    med, sd = prior([r["eta_h"] for r in rows])
    result = dict(eta_h_median=round(med, 4), eta_h_log_sd=round(sd, 4), avionics_w=AVIONICS_W,
                  airframes=rows, size_fits=size_fits(rows),
                  loao_median_abs_err_pct=round(statistics.median(abs(r["loao_err_pct"]) for r in rows), 1))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(result, f, indent=1)
    if a.markdown:
        print("| airframe | kg | rotors | prop m | hover W | η_h | prior without it | forecast W | error | P90 covers | source |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        for r in rows:
            print(f"| {r['airframe']} | {r['kg']} | {r['rotors']} | {r['prop_m']} | {r['hover_w']} | "
                  f"{r['eta_h']:.3f} | {r['loao_eta']:.3f} ± {r['loao_sd']:.2f} | {r['loao_hover_w']} | "
                  f"{r['loao_err_pct']:+.1f} % | {'yes' if r['loao_p90_covers'] else 'no'} | {r['source']} |")
        for name, v in result["size_fits"].items():
            t18 = next((p for p in v["loao"] if "T18" in p["airframe"]), None)
            print(f"size fit on {name}: median |ln error| {v['median_abs_log_err']}"
                  + (f"; the T18 left out: η_h {t18['forecast_eta_h']} (slope {t18['slope']}), its own {t18['eta_h']}"
                     if t18 else ""))
        print(f"\nAll airframes: η_h = {med:.3f}, log-spread {sd:.3f}; leave-one-airframe-out median |error| "
              f"{result['loao_median_abs_err_pct']} %")
    else:
        print(json.dumps(result, indent=1))
    if a.plot:
        plot(rows, a.plot)


def plot(rows, path):
    """Each airframe's hover power, and what the prior fitted without it forecasts (P50, P90)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(10, 4.2))
    for k, r in enumerate(rows):
        p90 = r["loao_hover_w"] * math.exp(1.2816 * r["loao_sd"])
        ax.bar(k - 0.2, r["hover_w"], 0.4, color="tab:red", label="its hover power" if k == 0 else None)
        ax.bar(k + 0.2, r["loao_hover_w"], 0.4, color="tab:orange",
               label="spec sheet, prior without it (P50)" if k == 0 else None)
        ax.plot([k + 0.02, k + 0.38], [p90, p90], color="k", label="P90" if k == 0 else None)
        ax.text(k + 0.2, r["loao_hover_w"], f"{r['loao_err_pct']:+.0f} %", ha="center", va="bottom", fontsize=7)
    ax.set_yscale("log")
    ax.set_xticks(range(len(rows)), [r["airframe"].replace(" (", "\n(") for r in rows], fontsize=7)
    ax.set_ylabel("hover power, W (log)")
    ax.set_title("Hover power, each airframe held out: the spec sheet's forecast with the prior fitted on the others")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
