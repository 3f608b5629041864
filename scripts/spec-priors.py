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


def peer_rows():
    """The `multirotor` package's airframes (scripts/peer_airframes.py) in hover."""
    sys.path.insert(0, HERE)
    import peer_airframes
    out = []
    for key, make in peer_airframes.AIRFRAMES.items():
        a = make()
        src = ("multirotor 0.5.0 models/tarott18.py: k_thrust, k_drag, motor R, k_emf (its Motor)" if key == "t18" else
               "built with multirotor's classes from the source its empty djimavicpro.py cites (scripts/peer_airframes.py)")
        out.append((a.name, a.mass, a.n, a.prop_m, a.hover_w() + AVIONICS_W, "peer", src, key,
                    dict(figure_of_merit=round(a.figure_of_merit(), 3), motor_eff=round(a.motor_efficiency(), 3),
                         **({"layout": peer_airframes.t18_layout()} if key == "t18" else {}))))
    return out


REMEMBERED = "as remembered, not re-checked"


def airframes():
    m100_w, m100_how = m100_hover_w()
    rows = [
        # name, kg, rotors, prop m, hover W, kind, source, airframe group (left out together)
        ("DJI M100 (data set)", 2.431, 4, 0.3302, m100_w, "measured",
         f"Rodrigues et al. 2021 data set, hover flights ({m100_how}); mass as config/vehicles/m100.toml", "m100"),
        ("DJI M100 (published)", 2.431, 4, 0.3302, 129.96 / (28 / 60), "published",
         f"DJI M100 specs: TB48D 129.96 Wh, 28 min hovering, no payload ({REMEMBERED})", "m100"),
        ("DJI Mavic Pro (published)", 0.734, 4, 0.2108, 43.6 / (24 / 60), "published",
         f"DJI Mavic Pro specs: 43.6 Wh, 24 min hovering, 8330 props ({REMEMBERED})", "mavic"),
        ("3DR Solo (regression)", 1.5, 4, 0.254, 251.7, "published",
         "Tseng et al. 2017 Solo form's intercept (tseng_solo in m100.toml); 1.5 kg, 10-inch props", "solo"),
        ("DJI S900 (published)", 6.8, 6, 0.381, 22.2 * 12.0 / (18 / 60), "published",
         f"DJI S900 specs: 6S 12000 mAh, 18 min hovering at 6.8 kg, 1552 props ({REMEMBERED})", "s900"),
        ("DJI S1000 (published)", 9.5, 8, 0.381, 22.2 * 15.0 / (15 / 60), "published",
         f"DJI S1000 specs: 6S 15000 mAh, 15 min hovering at 9.5 kg, 1552 props ({REMEMBERED})", "s1000"),
        ("DJI Matrice 600 (published)", 9.1, 6, 0.5334, 6 * 99.9 / (35 / 60), "published",
         f"DJI M600 specs: 6 TB47S (99.9 Wh each), 35 min hovering, no payload, 2170 props ({REMEMBERED})", "m600"),
        ("Holybro X500 (simulator here)", 2.0, 4, 0.254, 284.0, "simulator",
         "config/vehicles/x500.toml flown by `dronewatt simulate` (ASSUMPTION-built)", "x500"),
        ("3S quad (simulator here)", 1.0, 4, 0.1778, 145.0, "simulator",
         "config/vehicles/quad-3s.toml flown by `dronewatt simulate` (ASSUMPTION-built)", "quad3s"),
    ]
    try:
        rows += [r[:8] for r in peer_rows()]
    except ImportError as e:
        print(f"multirotor not importable ({e}); the peer rows are left out", file=sys.stderr)
    out = []
    for name, m, n, d, w, kind, src, group in rows:
        ideal = ideal_hover_w(m, n, d)
        out.append(dict(airframe=name, group=group, kg=m, rotors=n, prop_m=d, hover_w=round(float(w), 1),
                        ideal_w=round(ideal, 1), eta_h=round(ideal / (w - AVIONICS_W), 4),
                        kind=kind, source=src))
    return out


# Body drag areas C_D·A, m², of the airframes that have one: (group, airframe, take-off kg,
# C_D·A, source). The prior is their geometric mean per kg^(2/3) (frontal area grows as
# mass^(2/3)); src/model/spec.rs DRAG_PER_KG23.
DRAGS = [
    ("x500", "Holybro X500 (simulator here)", 2.0, 0.025, "config/vehicles/x500.toml (ASSUMPTION-built)"),
    ("quad3s", "3S quad (simulator here)", 1.0, 0.020, "config/vehicles/quad-3s.toml (ASSUMPTION-built)"),
    ("m100", "DJI M100", 2.431, 0.055, "config/vehicles/m100.toml's published-model value"),
    ("mavic", "DJI Mavic Pro", 0.743, 0.0197, "souhaiel1's model, the source multirotor cites (C_D 1.0 on 0.0197 m²)"),
    ("t18", "Tarot T18 (multirotor peer)", 10.66, 0.20, "the peer harness's ASSUMPTION (the package models no body drag)"),
]


def drag_prior(without=None):
    """(C_D·A per kg^(2/3), its leave-one-out predictive log-sd) from the airframes of DRAGS
    but `without`'s group: the geometric mean, and the RMS of each one's leave-one-out
    residual × t₀.₉(n − 1 df) / 1.2816 (as `predictive_sd`)."""
    pts = [(g, math.log(cda / kg ** (2 / 3))) for g, _, kg, cda, _ in DRAGS if g != without]
    mu = statistics.mean(v for _, v in pts)
    res = [v - statistics.mean(w for h, w in pts if h != g) for g, v in pts]
    rms = math.sqrt(sum(e * e for e in res) / len(res))
    return math.exp(mu), rms * T90.get(len(pts) - 1, Z90) / Z90


PROFILE_SHARE_JSON = os.path.join(HERE, "..", "docs", "src", "generated", "profile-share.json")


def profile_share_prior(without=None):
    """The profile share s (1 − the figure of merit, `[priors] profile_share`) fitted without
    `without`'s airframe: scripts/profile-share-fit.py's grid, its rule (the s minimizing the
    other airframes' mean after-hover median |error|); all three when `without` is None (the
    shipped src/model/spec.rs PROFILE_SHARE). 0 (the form before the split) when the grid
    was never run."""
    if not os.path.exists(PROFILE_SHARE_JSON):
        return 0.0
    with open(PROFILE_SHARE_JSON) as f:
        j = json.load(f)
    if without is None:
        return j["shipped"]["profile_share"]
    return j["held_out"][without]["profile_share"]


def dl_slope(rows, without=None):
    """d ln η_h / d ln(disk loading) across the airframes but `without`'s group (the disk
    loading's line): how η_h grows with the mass a vehicle flies (src/model/spec.rs
    ETA_H_PER_LN_DL, `[priors] eta_h_per_ln_dl`)."""
    import numpy as np
    rest = [r for r in rows if r["group"] != without]
    return float(np.polyfit([feature(r, "disk_loading") for r in rest], [math.log(r["eta_h"]) for r in rest], 1)[0])


def prior(etas):
    logs = [math.log(e) for e in etas]
    return math.exp(statistics.mean(logs)), statistics.stdev(logs)


# The forms tried for ln η_h, each a physical reading of how the hover efficiency scales:
# - `constant`: it does not (one η_h for every airframe);
# - `prop_m`: the propeller's size (a larger blade works at a higher Reynolds number);
# - `disk_loading`: the thrust per disk area (a loaded blade works nearer its best lift
#   coefficient: the figure of merit grows with it);
# - `rotor_thrust`: the thrust per rotor, m·g/N (2026-11-29). At a given thrust coefficient
#   the tip speed is √(T/(C_T ρ))/D·π and the chord ∝ D, so the blade's Reynolds number goes
#   as √T whatever the diameter; and the motor's size (its copper and iron, hence its
#   efficiency) grows with the torque it must give, ∝ T at a fixed C_P/C_T·D. Both of the
#   size effects the spec sheet could carry (the figure of merit's Reynolds scaling and the
#   motors' efficiency with size) are this one number.
FORMS = ("constant", "prop_m", "disk_loading", "rotor_thrust")


def feature(r, name):
    t = r["kg"] * G / r["rotors"]
    return math.log({"prop_m": r["prop_m"], "disk_loading": t / (math.pi * r["prop_m"] ** 2 / 4),
                     "rotor_thrust": t}[name])


def fit_form(rows, form):
    """ln η_h on the rows: a constant, or a line in ln(feature). Returns (predict, log-sd)."""
    import numpy as np
    y = [math.log(r["eta_h"]) for r in rows]
    if form == "constant":
        mu, sd = statistics.mean(y), statistics.stdev(y)
        return (lambda r: math.exp(mu)), sd
    x = [feature(r, form) for r in rows]
    slope, icpt = np.polyfit(x, y, 1)
    res = [yi - (icpt + slope * xi) for xi, yi in zip(x, y)]
    sd = math.sqrt(sum(e * e for e in res) / max(len(res) - 2, 1))
    return (lambda r: math.exp(icpt + slope * feature(r, form))), sd


# The t distribution's 90th percentile by degrees of freedom (a new airframe's spread about a
# line fitted on few airframes is wider than the normal's 1.2816 sd).
T90 = {1: 3.078, 2: 1.886, 3: 1.638, 4: 1.533, 5: 1.476, 6: 1.440, 7: 1.415, 8: 1.397, 9: 1.383,
       10: 1.372, 11: 1.363, 12: 1.356, 13: 1.350, 14: 1.345, 15: 1.341}
Z90 = 1.2816


def predictive_sd(rows, form):
    """The log-spread a new airframe meets about `form` fitted on `rows`: the RMS of each
    group's leave-one-group-out residual of ln η_h (the error an airframe the fit never saw
    actually had, not the fit's own residual), × the t distribution's 90th percentile over
    the normal's for as few groups (df = groups − the form's parameters): the P90, which
    `exp(1.2816 · sd)` makes of it, is then the t's. Returns (sd, the residuals)."""
    groups = sorted({r["group"] for r in rows})
    res = []
    for g in groups:
        pred, _ = fit_form([r for r in rows if r["group"] != g], form)
        res += [math.log(r["eta_h"] / pred(r)) for r in rows if r["group"] == g]
    rms = math.sqrt(sum(e * e for e in res) / len(res))
    df = len(groups) - (1 if form == "constant" else 2)
    return rms * T90.get(df, Z90 if df > 15 else T90[1]) / Z90, res


def loao_err(rows, form):
    """Median |ln error| of η_h, each airframe group left out in turn, the form fitted on the rest."""
    errs = []
    for g in sorted({r["group"] for r in rows}):
        rest = [r for r in rows if r["group"] != g]
        pred, _ = fit_form(rest, form)
        errs += [abs(math.log(pred(r) / r["eta_h"])) for r in rows if r["group"] == g]
    return statistics.median(errs)


def held_out_prior(rows, group):
    """The prior for an airframe group the fit never sees: the form chosen on the other
    groups alone (their own leave-one-group-out error), fitted on them. Returns
    (η_h for each of the group's rows, its predictive log-sd on the other groups
    (`predictive_sd`), the form, each form's inner error)."""
    rest = [r for r in rows if r["group"] != group]
    inner = {form: round(loao_err(rest, form), 3) for form in FORMS}
    form = min(FORMS, key=lambda k: inner[k])
    pred, _ = fit_form(rest, form)
    sd, _ = predictive_sd(rest, form)
    return {r["airframe"]: pred(r) for r in rows if r["group"] == group}, sd, form, inner


def form_table(rows):
    """Each form's leave-one-airframe-group-out median |ln error| of η_h over all groups (what
    the book shows; each held-out row's own prior chooses its form without its group)."""
    return {form: round(loao_err(rows, form), 3) for form in FORMS}


def shipped(rows, form):
    """What src/model/spec.rs ships: `form` fitted on every airframe (ln η_h = ln0 + per ·
    ln(disk loading) for the disk loading's line) and its predictive log-spread."""
    import numpy as np
    sd, res = predictive_sd(rows, form)
    out = dict(form=form, eta_h_log_sd=round(sd, 4),
               loao_residual_rms=round(math.sqrt(sum(e * e for e in res) / len(res)), 4))
    if form != "constant":
        slope, icpt = np.polyfit([feature(r, form) for r in rows], [math.log(r["eta_h"]) for r in rows], 1)
        out.update(ln0=round(float(icpt), 4), per_ln=round(float(slope), 4))
    return out


def safe_peer_rows():
    try:
        return peer_rows()
    except ImportError:
        return []


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--json", help="write the table and the priors as JSON here")
    ap.add_argument("--markdown", action="store_true", help="print the book's table")
    ap.add_argument("--plot", help="draw each airframe's hover power and the forecast of the prior without it here")
    a = ap.parse_args()
    rows = airframes()
    for g in sorted({r["group"] for r in rows}):
        etas, sd, form, inner = held_out_prior(rows, g)
        for r in rows:
            if r["group"] != g:
                continue
            eta = etas[r["airframe"]]
            fc = r["ideal_w"] / eta + AVIONICS_W
            r["loao_eta"] = round(eta, 4)
            r["loao_sd"] = round(sd, 4)
            r["loao_form"] = form
            r["loao_inner_err"] = inner
            r["loao_hover_w"] = round(fc, 1)
            r["loao_err_pct"] = round(100 * (fc / r["hover_w"] - 1), 1)
            r["loao_p90_covers"] = bool(fc * math.exp(1.2816 * sd) >= r["hover_w"])
            # each form fitted without the group, whichever the inner choice: what it says of η_h
            rest = [q for q in rows if q["group"] != g]
            r["loao_eta_by_form"] = {form: round(fit_form(rest, form)[0](r), 4) for form in FORMS}
    med, sd = prior([r["eta_h"] for r in rows])
    forms = form_table(rows)
    form_all = min(FORMS, key=lambda k: forms[k])
    drag, drag_sd = drag_prior()
    result = dict(eta_h_median=round(med, 4), eta_h_log_sd=round(sd, 4), avionics_w=AVIONICS_W,
                  airframes=rows, forms=forms, form_all=form_all, shipped=shipped(rows, form_all),
                  drag=dict(per_kg23=round(drag, 4), log_sd=round(drag_sd, 3),
                            airframes=[dict(group=g, airframe=n, kg=kg, cda_m2=c, per_kg23=round(c / kg ** (2 / 3), 4),
                                            held_out_prior=round(drag_prior(g)[0], 4), source=src)
                                       for g, n, kg, c, src in DRAGS]),
                  peers=[dict(airframe=r[0], **r[8]) for r in safe_peer_rows()],
                  loao_median_abs_err_pct=round(statistics.median(abs(r["loao_err_pct"]) for r in rows), 1),
                  loao_p90_cover_pct=round(100 * sum(r["loao_p90_covers"] for r in rows) / len(rows), 1))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(result, f, indent=1)
    if a.markdown:
        print("| airframe | kg | rotors | prop m | hover W | η_h | prior without it | form | forecast W | error | P90 covers | source |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|")
        for r in rows:
            print(f"| {r['airframe']} | {r['kg']} | {r['rotors']} | {r['prop_m']} | {r['hover_w']} | "
                  f"{r['eta_h']:.3f} | {r['loao_eta']:.3f} ± {r['loao_sd']:.2f} | {r['loao_form']} | {r['loao_hover_w']} | "
                  f"{r['loao_err_pct']:+.1f} % | {'yes' if r['loao_p90_covers'] else 'no'} | {r['source']} |")
        for r in rows:
            print(f"{r['airframe']}: form {r['loao_form']} (inner {r['loao_inner_err']})")
        print(f"forms over all groups: {forms}")
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
