"""Lab (round 5): can what the vehicle knows before take-off tell the pre-flight forecast of
the lowest loaded voltage how deep a pack will sag? Chosen by 5-fold by-flight
cross-validation on the TRAINING flights only (fold = flight number mod 5), each candidate
against the shipped single sag fraction by a paired bootstrap over the training flights.

Input: `dronewatt-lab battery-eval --json PATH` (per-flight raw figures; only rows with
`"test": false` are read: round 5 chose no change, so there was no test scoring)
and the data set's `parameters.csv` / `flights.csv.gz` (dates, start times and recording
lengths: what the vehicle store would know of the vehicle's last flight).

    dronewatt-lab battery-eval --json /tmp/be.json > /dev/null   # the table would show test figures
    python3 lab/scripts/battery/lab_cold.py /tmp/be.json

The two candidates that fly the first flight of a pack on another circuit (R0, R1 × γ; the
cold excess warm_a × γ) need the pre-flight plan forecast rerun on those circuits: apply
`lab/scripts/battery/round5-lab.patch` (a lab field `lab_cold`, not in the shipped code; made
against commit e87b521) before building, and `git checkout src/offline/battery_eval/score.rs`
after. Without it those two rows are left out. About 20 s.

Pre-flight knowledge per flight:
- `chained`: the pack flew minutes ago (battery-eval's chain rule, what the vehicle store's
  gap rule sees: k_prev carried over);
- `rest_min`: minutes since the vehicle's last flight ended (same date; none = the first
  flight of the day, the store's last flight hours old, or one of parameters.csv's five
  clock slips);
- `v_cell`: the start resting voltage per cell (the state of charge);
- `hour`: the local time of day; `month`: the date.

The forecast's error is `raw − β·sag` (raw = smooth path's lowest point − measured lowest,
sag = its sag below the OCV there): each candidate is a rule for β (or β and an offset).
"""
import json
import math
import os
import random
import statistics as st
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

GRID = [x / 100 for x in range(0, 201, 2)]
BOOT = 4000


def num(x):
    return x if isinstance(x, (int, float)) and x == x else None


def med_abs(e):
    e = [abs(x) for x in e if x is not None]
    return st.median(e) if e else float("nan")


def context():
    """Per flight: date, start minute, recording length (s): the vehicle's own log book."""
    import pandas as pd
    from load import PARAMS, load

    par = pd.read_csv(PARAMS)
    df = load()
    dur = df.groupby("flight")["time"].max().to_dict()
    out = {}
    rows = sorted(par.itertuples(), key=lambda r: r.flight)
    prev = None
    for r in rows:
        h, m = str(r.local_time).strip().split(":")
        t0 = int(h) * 60 + int(m)
        rest = None
        if prev is not None and prev[0] == r.date:
            rest = t0 - prev[1] - prev[2] / 60.0
            # five clock slips in parameters.csv (12 h or 1 h): an unknown rest, as a
            # vehicle whose store holds no usable last flight
            if rest < 0:
                rest = None
        out[int(r.flight)] = {
            "date": r.date,
            "month": int(str(r.date)[5:7]),
            "hour": t0 / 60.0,
            "rest_min": rest,
        }
        prev = (r.date, t0, dur.get(r.flight, 0.0))
    return out


def rows(path, ctx, test=False):
    r = json.load(open(path))
    out = []
    for f in r["flights"]:
        if f["test"] != test:
            continue
        v, m, s = num(f.get("preflight_plan_v_min_smooth")), num(f.get("measured_min_v")), num(f.get("preflight_plan_sag_v"))
        if v is None or m is None or s is None:
            continue
        c = ctx.get(f["flight"], {})
        out.append({
            "flight": f["flight"],
            "raw": v - m,
            "sag": s,
            "chained": f.get("k_prev") is not None,
            "k_prev": f.get("k_prev"),
            # (kind, factor) -> (smooth lowest V − measured, sag): the circuit refitted with
            # R0, R1 × factor (kind 0) or warm_a × factor (kind 1); only with the scratch
            # patch of round 5 (NOTES-min-voltage.md), else empty
            "lab": {(int(k), g): (v - m, sg) for k, g, v, sg in f.get("lab_cold", [])
                    if num(v) is not None and num(sg) is not None},
            "v_cell": f["v_start"] / 6.0,
            "rest_min": c.get("rest_min"),
            "hour": c.get("hour"),
            "month": c.get("month"),
        })
    return out


def fit_beta(tr, grp=lambda f: 0):
    """One β per group (grid, median |error|)."""
    out = {}
    for g in sorted({grp(f) for f in tr}):
        sub = [f for f in tr if grp(f) == g]
        best = min(GRID, key=lambda b: (med_abs([f["raw"] - b * f["sag"] for f in sub]), b))
        out[g] = best
    return out


# ---- candidates: fit(train) -> predict(f) gives the corrected error -------------------------

def pooled(tr):
    b = fit_beta(tr)[0]
    return lambda f: f["raw"] - b * f["sag"]


def split_chained(tr):
    b = fit_beta(tr, lambda f: f["chained"])
    return lambda f: f["raw"] - b[f["chained"]] * f["sag"]


def cold_after(minutes):
    """Cold = not chained and the vehicle rested ≥ `minutes` (or first flight of the day)."""
    def cold(f):
        return (not f["chained"]) and (f["rest_min"] is None or f["rest_min"] >= minutes)

    def fit(tr):
        b = fit_beta(tr, cold)
        return lambda f: f["raw"] - b.get(cold(f), b.get(not cold(f))) * f["sag"]
    return fit


def decay(tau_min):
    """β = β_w + (β_c − β_w)·(1 − exp(−rest/τ)) for flights not chained; chained β_w.
    rest: minutes since the vehicle's last flight (first of the day: ∞)."""
    def w(f):
        if f["chained"]:
            return 0.0
        r = f["rest_min"]
        return 1.0 if r is None else 1.0 - math.exp(-max(r, 0.0) / tau_min)

    def fit(tr):
        best = None
        for bw in GRID[::2]:
            for bc in GRID[::2]:
                m = med_abs([f["raw"] - (bw + (bc - bw) * w(f)) * f["sag"] for f in tr])
                if best is None or m < best[0]:
                    best = (m, bw, bc)
        _, bw, bc = best
        return lambda f: f["raw"] - (bw + (bc - bw) * w(f)) * f["sag"]
    return fit


def soc_linear(by_group):
    """β = β0 + β1·(v_cell − 3.9), per chained/first group if `by_group`."""
    def fit(tr):
        groups = {True, False} if by_group else {None}
        par = {}
        for g in groups:
            sub = [f for f in tr if g is None or f["chained"] == g]
            best = None
            for b0 in GRID[::2]:
                for b1 in [x / 10 for x in range(-30, 31, 2)]:
                    m = med_abs([f["raw"] - (b0 + b1 * (f["v_cell"] - 3.9)) * f["sag"] for f in sub])
                    if best is None or m < best[0]:
                        best = (m, b0, b1)
            par[g] = best[1:]
        return lambda f: f["raw"] - (lambda p: p[0] + p[1] * (f["v_cell"] - 3.9))(par[f["chained"] if by_group else None]) * f["sag"]
    return fit


def split_morning(tr):
    """First flights before noon get their own β (a clock, not a general rule)."""
    g = lambda f: (f["chained"], (not f["chained"]) and f["hour"] < 12.0)
    b = fit_beta(tr, g)
    return lambda f: f["raw"] - b.get(g(f), 0.24) * f["sag"]


def joint_split(tr):
    """β first / β chained fitted together on the overall median |error| (the target's
    figure), not each group's own."""
    best = None
    for bf in GRID[::2]:
        for bc in GRID[::2]:
            m = med_abs([f["raw"] - (bc if f["chained"] else bf) * f["sag"] for f in tr])
            if best is None or m < best[0]:
                best = (m, bf, bc)
    _, bf, bc = best
    return lambda f: f["raw"] - (bc if f["chained"] else bf) * f["sag"]


def split_plus_c(tr):
    """β and a constant per group."""
    par = {}
    for g in (True, False):
        sub = [f for f in tr if f["chained"] == g]
        best = None
        for b in GRID:
            c = st.median([f["raw"] - b * f["sag"] for f in sub])
            m = med_abs([f["raw"] - b * f["sag"] - c for f in sub])
            if best is None or m < best[0]:
                best = (m, b, c)
        par[g] = best[1:]
    return lambda f: f["raw"] - par[f["chained"]][0] * f["sag"] - par[f["chained"]][1]


FACTOR_GRID = {
    0: [0.5, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2, 1.3, 1.5, 1.75, 2.0, 2.5, 3.0],
    1: [0.0, 0.25, 0.5, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2, 1.3, 1.5, 1.75, 2.0, 2.5, 3.0],
}


def factor_err(f, kind, g, b):
    if f["chained"] or g == 1.0:
        return f["raw"] - b * f["sag"]
    r, s = f["lab"][(kind, g)]
    return r - b * s


def fit_factor(tr, kind, grid):
    best = None
    for g in grid:
        for b in GRID[::2]:
            m = med_abs([factor_err(f, kind, g, b) for f in tr])
            if best is None or m < best[0]:
                best = (m, g, b)
    return best[1], best[2], best[0]


def factor(kind, grid):
    """First-of-pack flights flown on a circuit with R0, R1 × γ (kind 0: a cold-resistance
    factor) or the cold excess warm_a × γ (kind 1: a colder pack whose excess still warms
    off), γ and one pooled β fitted together on the overall median |error|."""
    def fit(tr):
        g, b, _ = fit_factor(tr, kind, grid)
        return lambda f: factor_err(f, kind, g, b)
    return fit


CANDIDATES = {
    "pooled β (shipped)": pooled,
    "β first / β chained": split_chained,
    "β cold: not chained, rest ≥ 30 min": cold_after(30),
    "β cold: not chained, rest ≥ 60 min": cold_after(60),
    "β cold: not chained, rest ≥ 120 min": cold_after(120),
    "β decays with rest, τ 15 min": decay(15),
    "β decays with rest, τ 60 min": decay(60),
    "β decays with rest, τ 240 min": decay(240),
    "β linear in SoC (pooled)": soc_linear(False),
    "β linear in SoC per group": soc_linear(True),
    "β first (morning / afternoon) / chained": split_morning,
    "β + c per group": split_plus_c,
    "β first / β chained, joint on overall median": joint_split,
}
LAB_CANDIDATES = {
    "first: R0, R1 × γ, pooled β": factor(0, FACTOR_GRID[0]),
    "first: cold excess warm_a × γ, pooled β": factor(1, FACTOR_GRID[1]),
}


def cv(fl, fit):
    e = {}
    for k in range(5):
        tr = [f for f in fl if f["flight"] % 5 != k]
        pred = fit(tr)
        for f in fl:
            if f["flight"] % 5 == k:
                e[f["flight"]] = pred(f)
    return e


def summary(fl, e):
    a = [e[f["flight"]] for f in fl]
    fi = [e[f["flight"]] for f in fl if not f["chained"]]
    ch = [e[f["flight"]] for f in fl if f["chained"]]
    return med_abs(a), med_abs(fi), med_abs(ch), st.median(a), st.median(fi), st.median(ch)


def boot_win(fl, e, base, seed=1, only=None):
    """Share of paired bootstrap resamples (flights) in which `e`'s median |error| is lower
    than `base`'s, and the median difference's 90 % interval."""
    rng = random.Random(seed)
    ids = [f["flight"] for f in fl if only is None or f["chained"] == only]
    wins, d = 0, []
    for _ in range(BOOT):
        s = [rng.choice(ids) for _ in ids]
        x = st.median([abs(e[i]) for i in s]) - st.median([abs(base[i]) for i in s])
        d.append(x)
        wins += x < 0
    d.sort()
    return wins / BOOT, d[int(0.05 * BOOT)], d[int(0.95 * BOOT)]


def nested_selection(fl, cands):
    """The whole selection as a procedure, cross-validated: in each outer fold, every
    candidate is scored by CV over the other four folds, the best is fitted on them and
    predicts the held-out fold. Guards against picking the luckiest of many candidates."""
    e, picks = {}, []
    for k in range(5):
        tr = [f for f in fl if f["flight"] % 5 != k]
        best = None
        for name, fit in cands.items():
            inner = {}
            folds = sorted({f["flight"] % 5 for f in tr})
            for j in folds:
                itr = [f for f in tr if f["flight"] % 5 != j]
                pred = fit(itr)
                for f in tr:
                    if f["flight"] % 5 == j:
                        inner[f["flight"]] = pred(f)
            m = med_abs(list(inner.values()))
            if best is None or m < best[0]:
                best = (m, name)
        picks.append(best[1])
        pred = cands[best[1]](tr)
        for f in fl:
            if f["flight"] % 5 == k:
                e[f["flight"]] = pred(f)
    return e, picks


if __name__ == "__main__":
    test = "--test" in sys.argv
    path = [a for a in sys.argv[1:] if not a.startswith("--")][0]
    ctx = context()
    fl = rows(path, ctx)
    n_first = sum(not f["chained"] for f in fl)
    print(f"training route flights with a plan: {len(fl)} (first of pack {n_first}, chained {len(fl) - n_first})")
    fi = [f for f in fl if not f["chained"]]
    day1 = sum(f["rest_min"] is None for f in fi)
    print(f"first-of-pack flights: first of the day {day1}; after a rest of (min): "
          f"{sorted(round(f['rest_min']) for f in fi if f['rest_min'] is not None)}")
    base = cv(fl, pooled)
    print("P(win): share of 4,000 paired bootstrap resamples of the training flights in which the"
          " candidate's CV median |error| is lower than the shipped pooled β's (wins beyond noise: ≥ 0.95);"
          " Δ: the difference of the medians, 5–95 %; then the same within first-of-pack and chained flights")
    print(f"{'candidate':<48} {'CV':>6} {'first':>6} {'chain':>6} {'signed':>7} {'s.first':>7} {'s.chain':>7}"
          f" {'P(win)':>7} {'Δ 90 % interval':>16}  P(win) within the groups")
    cands = dict(CANDIDATES)
    if test:
        raise SystemExit("round 5 shipped no change: there is no choice to score on the test flights")
    if all(f["lab"] for f in fl if not f["chained"]):
        cands.update(LAB_CANDIDATES)
    for name, fit in cands.items():
        e = cv(fl, fit)
        m, a, b, s, sa, sb = summary(fl, e)
        w, lo, hi = boot_win(fl, e, base)
        wf = boot_win(fl, e, base, only=False)[0]
        wc = boot_win(fl, e, base, only=True)[0]
        print(f"{name:<48} {m:6.3f} {a:6.3f} {b:6.3f} {s:+7.3f} {sa:+7.3f} {sb:+7.3f} {w:7.3f}  [{lo:+.3f}, {hi:+.3f}]"
              f"  first {wf:5.3f} chained {wc:5.3f}")
    # diagnostics on the training flights: the β each first flight would need
    print()
    need = sorted((f["raw"] / f["sag"], f) for f in fi if f["sag"] > 0)
    import numpy as np
    x = np.array([[f["v_cell"], f["hour"], f["month"], -1 if f["rest_min"] is None else f["rest_min"], f["raw"] / f["sag"]] for _, f in need])
    print("first-of-pack flights, the β each would need (raw/sag): quartiles",
          np.percentile(x[:, 4], [10, 25, 50, 75, 90]).round(2))
    for j, nm in enumerate(["v_cell", "hour", "month", "rest_min (-1 first of day)"]):
        print(f"  corr(β needed, {nm}) = {np.corrcoef(x[:, j], x[:, 4])[0, 1]:+.2f}")
    ch = [f for f in fl if f["chained"] and f["sag"] > 0]
    y = np.array([[f["v_cell"], f["hour"], f["month"], f["raw"] / f["sag"]] for f in ch])
    print("chained flights, β needed quartiles", np.percentile(y[:, 3], [10, 25, 50, 75, 90]).round(2))
    for j, nm in enumerate(["v_cell", "hour", "month"]):
        print(f"  corr(β needed, {nm}) = {np.corrcoef(y[:, j], y[:, 3])[0, 1]:+.2f}")
    kp = np.array([[f["k_prev"], -1 if f["rest_min"] is None else f["rest_min"], f["raw"] / f["sag"]] for f in ch])
    print(f"  corr(β needed, carried k) = {np.corrcoef(kp[:, 0], kp[:, 2])[0, 1]:+.2f},"
          f" corr(β needed, rest since the last flight) = {np.corrcoef(kp[:, 1], kp[:, 2])[0, 1]:+.2f}")
    raw = {g: [f["raw"] for f in fl if f["chained"] == g] for g in (False, True)}
    sag = {g: [f["sag"] for f in fl if f["chained"] == g] for g in (False, True)}
    print("median raw error (smooth path − measured, no sag term): first "
          f"{st.median(raw[False]):+.3f} V, chained {st.median(raw[True]):+.3f} V; the smooth path's sag there: "
          f"first {st.median(sag[False]):.2f} V, chained {st.median(sag[True]):.2f} V")
    print("all-training fits: pooled β", fit_beta(fl)[0], "; β first / chained",
          fit_beta(fl, lambda f: f["chained"]))
    if "first: cold excess warm_a × γ, pooled β" in cands:
        g, b, m = fit_factor(fl, 1, FACTOR_GRID[1])
        print(f"all-training fit of the cold excess × γ: γ {g}, β {b} (median |error| {m:.3f})")
    fs = [f for f in fl if not f["chained"]]
    a = [f["raw"] / f["sag"] for f in fs if f["rest_min"] is None and f["sag"] > 0]
    b = [f["raw"] / f["sag"] for f in fs if f["rest_min"] is not None and f["sag"] > 0]
    print(f"first-of-pack flights, β needed: first of the day (or unknown rest) median {st.median(a):.2f} ({len(a)}),"
          f" after a pack swap {st.median(b):.2f} ({len(b)})")
    # a day-level (ambient) signal: the needed β of the vehicle's previous flight that day
    xs, ys = [], []
    for f in fs:
        d = ctx[f["flight"]]["date"]
        p = [g for g in fl if g["flight"] < f["flight"] and ctx[g["flight"]]["date"] == d and g["sag"] > 0]
        if p and f["sag"] > 0:
            q = max(p, key=lambda g: g["flight"])
            xs.append(q["raw"] / q["sag"])
            ys.append(f["raw"] / f["sag"])
    print(f"first-of-pack flights: corr(β needed, the previous same-day flight's) = {np.corrcoef(xs, ys)[0, 1]:+.2f} ({len(xs)})")

    # the selection among all the candidates, cross-validated as a procedure
    print()
    e, picks = nested_selection(fl, cands)
    m, a, b, s, sa, sb = summary(fl, e)
    w, lo, hi = boot_win(fl, e, base)
    print(f"nested selection over the {len(cands)} candidates: CV {m:.3f} (first {a:.3f}, chained {b:.3f},"
          f" signed {s:+.3f}); P(win) {w:.3f} [{lo:+.3f}, {hi:+.3f}]; picked per fold: {picks}")
    # what the gains are made of: the tails, first-of-pack and chained flights
    print()
    for name in ["pooled β (shipped)", "β first / β chained, joint on overall median",
                 "first: cold excess warm_a × γ, pooled β"]:
        if name not in cands:
            continue
        e = cv(fl, cands[name])
        for g, lab in [(False, "first"), (True, "chained")]:
            x = [e[f["flight"]] for f in fl if f["chained"] == g]
            print(f"{name:<48} {lab:<8} forecast > 0.5 V above the measured: {sum(v > 0.5 for v in x) / len(x):.2f},"
                  f" > 0.5 V below: {sum(v < -0.5 for v in x) / len(x):.2f}; mean |error| {st.mean(abs(v) for v in x):.3f}")
