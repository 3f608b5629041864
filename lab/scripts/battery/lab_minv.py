"""Lab (round 3): corrections of the lowest-loaded-voltage forecasts, chosen by 5-fold
by-flight cross-validation on the TRAINING flights only (fold = flight number mod 5).

Input: `dronewatt-lab battery-eval --json PATH` (per-flight raw figures). Reads only rows with
`"test": false` unless `--test` is given (the one-time scoring, after the choice).

    python3 lab/scripts/battery/lab_minv.py /tmp/be.json
"""
import json
import statistics as st
import sys


def rows(path, test=False):
    r = json.load(open(path))
    out = []
    for f in r["flights"]:
        if f["test"] != test or f.get("measured_min_v") is None:
            continue
        out.append(f)
    return out


def num(x):
    return x if isinstance(x, (int, float)) and x == x else None


def med_abs(e):
    e = [abs(x) for x in e if x is not None]
    return st.median(e) if e else float("nan")


# A correction: fit(train rows) -> params; apply(row, params) -> corrected error (forecast − measured)
def const_fit(tr, err, sag):
    return {"c": st.median([err(f) for f in tr])}


def const_apply(f, p, err, sag):
    return err(f) - p["c"]


GRID = [x / 100 for x in range(0, 151, 2)]


def beta_fit(tr, err, sag):
    best = None
    for b in GRID:
        m = med_abs([err(f) - b * sag(f) for f in tr])
        if best is None or m < best[0]:
            best = (m, b)
    return {"b": best[1]}


def beta_apply(f, p, err, sag):
    return err(f) - p["b"] * sag(f)


def both_fit(tr, err, sag):
    best = None
    for b in GRID:
        c = st.median([err(f) - b * sag(f) for f in tr])
        m = med_abs([err(f) - b * sag(f) - c for f in tr])
        if best is None or m < best[0]:
            best = (m, b, c)
    return {"b": best[1], "c": best[2]}


def both_apply(f, p, err, sag):
    return err(f) - p["b"] * sag(f) - p["c"]


def none_fit(tr, err, sag):
    return {}


def none_apply(f, p, err, sag):
    return err(f)


VARIANTS = {
    "none": (none_fit, none_apply),
    "constant margin": (const_fit, const_apply),
    "sag × (1 + β)": (beta_fit, beta_apply),
    "sag × (1 + β) + c": (both_fit, both_apply),
}


def cv(fl, err, sag, fit, apply):
    fl = [f for f in fl if err(f) is not None and sag(f) is not None]
    out, firsts, chained = [], [], []
    for k in range(5):
        tr = [f for f in fl if f["flight"] % 5 != k]
        te = [f for f in fl if f["flight"] % 5 == k]
        p = fit(tr, err, sag)
        for f in te:
            e = apply(f, p, err, sag)
            out.append(e)
            (chained if f.get("k_prev") is not None else firsts).append(e)
    return med_abs(out), med_abs(firsts), med_abs(chained), st.median(out), len(out)


TARGETS = {
    "pre-flight, plan power": (
        lambda f: num(f["preflight_plan_min_v_err"]),
        lambda f: num(f["preflight_plan_sag_v"]),
    ),
    "pre-flight, plan power, raw (no sag term)": (
        lambda f: num(f["preflight_plan_v_min_smooth"]) is not None and num(f["measured_min_v"]) is not None
        and f["preflight_plan_v_min_smooth"] - f["measured_min_v"] or None,
        lambda f: num(f["preflight_plan_sag_v"]),
    ),
    "half time, plan's rest, raw": (
        lambda f: num(f.get("halftime_plan_v_min_smooth")) is not None and num(f.get("halftime_measured_min_v")) is not None
        and f["halftime_plan_v_min_smooth"] - f["halftime_measured_min_v"] or None,
        lambda f: num(f.get("halftime_plan_sag_v")),
    ),
    "pre-flight, measured power": (
        lambda f: num(f["preflight_min_v_err"]),
        lambda f: num(f["preflight_sag_v"]),
    ),
    "half time, measured power": (
        lambda f: num(f["halftime_min_v_err"]),
        lambda f: num(f["halftime_sag_v"]),
    ),
}

if __name__ == "__main__":
    path = sys.argv[1]
    fl = rows(path)
    print(f"training flights with a lowest loaded voltage: {len(fl)}")
    print(f"{'forecast':<28} {'correction':<20} {'CV |err|':>9} {'first':>7} {'chained':>8} {'signed':>7} {'n':>4}  all-training fit")
    for name, (err, sag) in TARGETS.items():
        for vn, (fit, apply) in VARIANTS.items():
            m, a, b, s, n = cv(fl, err, sag, fit, apply)
            p = fit([f for f in fl if err(f) is not None and sag(f) is not None], err, sag)
            print(f"{name:<28} {vn:<20} {m:9.3f} {a:7.3f} {b:8.3f} {s:+7.3f} {n:4d}  {p}")

    # the plan's power from half time (smooth, like the live path's), the forecast as shipped
    print()
    err = lambda f: num(f.get("halftime_plan_min_v_err"))
    sag = lambda f: num(f.get("halftime_plan_sag_v"))
    for vn, (fit, apply) in VARIANTS.items():
        m, a, b, s, n = cv(fl, err, sag, fit, apply)
        p = fit([f for f in fl if err(f) is not None and sag(f) is not None], err, sag)
        print(f"{'half time, plan power':<28} {vn:<20} {m:9.3f} {a:7.3f} {b:8.3f} {s:+7.3f} {n:4d}  {p}")

    # one sag fraction for both smooth (plan) forecasts, pre-flight and half time: CV by flight
    pre = (TARGETS["pre-flight, plan power"][0], TARGETS["pre-flight, plan power"][1])
    mid = (err, sag)
    def joint(fl):
        res = {"pre": [], "mid": []}
        bs = []
        for k in range(5):
            tr = [f for f in fl if f["flight"] % 5 != k]
            te = [f for f in fl if f["flight"] % 5 == k]
            best = None
            for b in GRID:
                e = [pre[0](f) - b * pre[1](f) for f in tr if pre[0](f) is not None] + \
                    [mid[0](f) - b * mid[1](f) for f in tr if mid[0](f) is not None]
                m = med_abs(e)
                if best is None or m < best[0]:
                    best = (m, b)
            bs.append(best[1])
            for f in te:
                if pre[0](f) is not None:
                    res["pre"].append(pre[0](f) - best[1] * pre[1](f))
                if mid[0](f) is not None:
                    res["mid"].append(mid[0](f) - best[1] * mid[1](f))
        return med_abs(res["pre"]), med_abs(res["mid"]), bs
    a, b, bs = joint(fl)
    print(f"one sag fraction for both plan forecasts (CV): pre-flight {a:.3f}, half time {b:.3f}; folds' β {bs}")
