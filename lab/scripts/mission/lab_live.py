#!/usr/bin/env python3
"""The live-correction analysis of docs/src/mission.md ("Learning from the flight so far:
what was tried, and why the live correction is unchanged"), reproducible:

    dronewatt-lab plan-eval --dump-live /tmp/live-dump
    python3 lab/scripts/mission/lab_live.py /tmp/live-dump [--oof /tmp/blend-oof.csv]

Reads the per-flight JSON that `plan-eval --dump-live` writes (training flights only; see
src/offline/live_dump.rs) and prints the section's table (median error of the rest at half
time, training flights, rolling validation) and the correlations it quotes. Refuses any test
flight. Needs numpy.

`--oof` adds the learned model's row: the first half's measured energy against the power
model's *out-of-fold* estimate on the kinematics actually flown (`lab/scripts/blend_cv.py
--write-blend`; a model that has not seen the flight, as live), which the monitor has
live because it runs that model on the telemetry.

Every candidate scales the forecast of the rest L by 1 + w·(s − 1), s a ratio from the
first half clamped to 0.8…1.25. The weight w is fitted for each flight on the training
flights numbered before it (the first 20 flights: on all the others), either on a grid
(median error) or by least squares (relative error of the rest).
"""

import json
import math
import os
import random
import sys

try:
    import numpy as np
except ImportError:
    sys.exit("lab_live.py needs numpy (python3 -m venv /tmp/venv-lab && /tmp/venv-lab/bin/pip install numpy)")

TEST_FLIGHTS = {268, 269, 270, 271, 272, 273, 276, 277, 278, 279}
GRID = [0, 0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 1.0]
MIN_BEFORE = 20  # rolling validation: fewer flights before it -> fit on all the others
RESAMPLES = 2000
# sample categories by where the vehicle is found on the plan
CLIMB, DESCENT, CRUISE, HOVER, GROUND = 0, 1, 2, 3, 4


def clamp(s):
    return min(max(s, 0.8), 1.25)


def corr(a, b):
    return float(np.corrcoef(np.asarray(a, float), np.asarray(b, float))[0, 1])


def med(v):
    return float(np.median(np.asarray(v, float)))


def load(d):
    """Calibration and the training flights' dumps; exits on a test flight."""
    with open(os.path.join(d, "calibration.json")) as fh:
        head = json.load(fh)
    test = TEST_FLIGHTS | set(head.get("test_flights", []))
    flights = {}
    for name in sorted(os.listdir(d)):
        if not name.endswith(".json") or name == "calibration.json":
            continue
        with open(os.path.join(d, name)) as fh:
            x = json.load(fh)
        if x["flight"] in test:
            sys.exit(f"{name}: flight {x['flight']} is a test flight; this analysis reads training flights only")
        flights[x["flight"]] = x
    if not flights:
        sys.exit(f"{d}: no flight dumps (run `dronewatt-lab plan-eval --dump-live {d}`)")
    return head["calibration"], flights


def prepare(cal, F):
    """Per flight: the forecast's P50 energy per plan sample with the members' rolling
    scales (as plan-eval), the live point's figures, and the first half's rows labelled by
    where the vehicle is found on the plan."""
    M = cal["members"]
    fl = sorted(F)
    for f in fl:
        x = F[f]
        S = np.asarray(x["samples"], float)
        x["cat"] = np.where(S[:, 0] == 0, CLIMB, np.where(S[:, 0] == 1, DESCENT, np.where(S[:, 1] >= 1.0, CRUISE, HOVER)))
        x["leg"] = S[:, 3].astype(int)
        x["enu"] = S[:, 4:7]
        x["wup"] = S[:, 7]
        x["E"] = {m["name"]: np.asarray(m["e"], float) for m in x["models"]}
        x["R"] = np.asarray(x["rows"], float)
        x["tot"] = [m["phase_scale"][0] * x["E"][m["model"]].sum() + m["climb_work"][0] * x["wup"].sum() for m in M]
    meas = {f: F[f]["measured_wh"] for f in fl}

    def rscale(i, f):
        k = M[i]["recent_flights"]
        before = [g for g in fl if g < f]
        if len(before) < 5:
            before = [g for g in fl if g != f]
        before = sorted(before, reverse=True)
        take = before if k == 0 else before[:k]
        return med([meas[g] / F[g]["tot"][i] for g in take])

    lw = cal["live_weight"]
    mismatch = 0
    for f in fl:
        x = F[f]
        R, cat, k, dt = x["R"], x["cat"], x["k"], x["dt"]
        i0, ih, i1 = x["i0"], x["ih"], x["i1"]
        e50 = np.zeros(len(cat))
        for i, m in enumerate(M):
            e50 += rscale(i, f) * (m["phase_scale"][0] * x["E"][m["model"]] + m["climb_work"][0] * x["wup"]) / len(M)
        x["e50"] = e50
        x["done"], x["left"] = e50[: k + 1].sum(), e50[k + 1 :].sum()
        x["so_far"], x["rest_meas"] = R[ih, 2], R[-1, 2] - R[ih, 2]
        today = x["left"] * (1 + lw * (clamp(x["so_far"] / x["done"]) - 1))
        if abs(today - x["live_forecast_rest_wh"]) > 1e-3:
            mismatch += 1
        # the rest's forecast by phase: climb, descent, the rest
        L = [0.0, 0.0, 0.0]
        for c in (CLIMB, DESCENT, CRUISE, HOVER):
            L[min(c, 2)] += e50[k + 1 :][cat[k + 1 :] == c].sum()
        x["L"] = L
        # every row of the recording: measured energy, time, the plan sample found there
        rk = np.asarray(x["row_k"])
        r = np.arange(i0, len(R) - 1)
        de, ddt = R[r + 1, 2] - R[r, 2], R[r + 1, 0] - R[r, 0]
        kr = np.where(r <= i1, rk[np.minimum(r - i0, len(rk) - 1)], -1)
        half = (r >= ih).astype(int)
        c_loc = np.where(r <= i1, cat[np.maximum(kr, 0)], GROUND)
        mc, tc, fc = np.zeros((2, 5)), np.zeros((2, 5)), np.zeros((2, 5))
        np.add.at(mc, (half, c_loc), de)
        np.add.at(tc, (half, c_loc), ddt)
        mc[0, GROUND] += R[i0, 2]
        np.add.at(fc, ((np.arange(len(cat)) > k).astype(int), cat), e50)
        x["mc"], x["tc"], x["fc"] = mc, tc, fc
        # first half's airborne rows: measured energy against the forecast's power at the
        # plan sample found, over the row's time
        first = r < ih
        x["h_de"], x["h_dt"], x["h_k"] = de[first], ddt[first], kr[first]
        x["h_fe"] = e50[kr[first]] / dt * ddt[first]
        x["h_cat"] = cat[kr[first]]
    return fl, mismatch


def features(F, fl):
    """The candidate ratios s of the first half (each clamped; 1 when too little flown)."""
    for f in fl:
        x = F[f]
        de, fe, kr, c, R = x["h_de"], x["h_fe"], x["h_k"], x["h_cat"], x["R"]
        tot = x["e50"].sum()

        def ratio(sel, floor):
            n, d = de[sel].sum(), fe[sel].sum()
            return clamp(n / d) if d > floor and n > 0 else 1.0

        horiz = (c == CRUISE) | (c == HOVER)
        after = kr != 0  # not at the plan's first sample (the spin-up on the ground)
        x["sE"] = clamp(x["so_far"] / x["done"])
        x["sP"] = clamp(de.sum() / fe.sum())
        x["sC"] = clamp(de[c == CLIMB].sum() / fe[c == CLIMB].sum()) if fe[c == CLIMB].sum() > 0.3 else 1.0
        x["sH"] = clamp(de[horiz].sum() / max(fe[horiz].sum(), 1e-9)) if fe[horiz].sum() > 0.3 else 1.0
        x["sH2"] = ratio(horiz & after, 0.05 * tot)
        x["sCr"] = ratio((c == CRUISE) & after, 0.05 * tot)
        x["sHv"] = ratio((c == HOVER) & after, 0.05 * tot)
        # the rows found at the plan's first sample: how long (none when the first GPS fix
        # comes after the spin-up)
        x["t0"] = x["h_dt"][kr == 0].sum()
        i0, ih = x["i0"], x["ih"]
        # the spin-up's own ratio: measured power from the motors' start until the vehicle
        # climbs (v_up > 0.5 m/s) against the forecast's before the plan's first climb sample
        r, e, t = i0, 0.0, 0.0
        while r < ih and R[r, 7] <= 0.5:
            e, t, r = e + R[r + 1, 2] - R[r, 2], t + R[r + 1, 0] - R[r, 0], r + 1
        kt = int(np.argmax(x["cat"] == CLIMB))
        spin_w = x["e50"][:kt].sum() / (kt * x["dt"]) if kt > 0 else 0.0
        x["sG"] = clamp((e / t) / spin_w) if t > 1 and spin_w > 0 else 1.0
        x["sT"] = clamp((R[ih, 0] - R[i0, 0]) / ((x["k"] + 1) * x["dt"]))
        x["rr"] = x["rest_meas"] / sum(x["L"])
        wind_features(x)


def heading(x, leg):
    _, a, b = x["legs"][leg]
    e0, e1 = x["enu"][a], x["enu"][b - 1]
    return math.atan2(e1[0] - e0[0], e1[1] - e0[1])


def wind_features(x):
    """The wind aloft from the first half's cruise rows (anemometer's apparent wind less the
    ground velocity along the leg), and `hwd`: 1 + 1 %/(m/s) × (the rest's headwind − the
    first half's), each weighted by the forecast's energy."""
    R, rk, i0, ih = x["R"], x["row_k"], x["i0"], x["ih"]
    W = []
    for r in range(i0 + 1, ih):
        kr = rk[r - i0]
        if x["cat"][kr] != CRUISE:
            continue
        hd = heading(x, x["leg"][kr])
        sp = math.hypot(R[r, 5], R[r, 6]) / 0.925
        ws, wa = R[r, 3], math.radians(R[r, 4])
        W.append((ws * math.sin(wa) - sp * math.sin(hd), ws * math.cos(wa) - sp * math.cos(hd)))
    we, wn = (float(np.mean([w[0] for w in W])), float(np.mean([w[1] for w in W]))) if W else (0.0, 0.0)
    x["wind_first"] = (we, wn, len(W))

    def hw(js):
        s = e = 0.0
        for j in js:
            if x["cat"][j] != CRUISE:
                continue
            hd = heading(x, x["leg"][j])
            s += x["e50"][j] * (we * math.sin(hd) + wn * math.cos(hd))
            e += x["e50"][j]
        return s / e if e > 0 else 0.0

    n, k = len(x["cat"]), x["k"]
    x["hwd"] = 1 + 0.01 * (hw(range(k + 1, n)) - hw(range(0, k + 1)))


def err(pred, y):
    return 100 * abs(pred - y) / y


def rolling_sets(fl):
    for f in fl:
        before = [g for g in fl if g < f]
        yield f, (before if len(before) >= MIN_BEFORE else [g for g in fl if g != f])


def predict(x, w, feats):
    return sum(x["L"]) * (1 + sum(wi * (x[ft] - 1) for wi, ft in zip(w, feats)))


def predict_sep(x, w, feats):
    nf = len(feats)
    return sum(x["L"][c] * (1 + sum(w[c * nf + i] * (x[ft] - 1) for i, ft in enumerate(feats))) for c in range(3))


def fit_ls(F, train, feats, sep=False, ridge=1e-6):
    """Weights minimising the squared relative error of the rest; one per feature, or one
    per feature and phase of the rest (climb, descent, the rest) with `sep`."""
    nf = len(feats)
    A, b = [], []
    for f in train:
        x = F[f]
        y = x["rest_meas"]
        if sep:
            A.append([x["L"][c] * (x[ft] - 1) / y for c in range(3) for ft in feats])
        else:
            A.append([sum(x["L"]) * (x[ft] - 1) / y for ft in feats])
        b.append((y - sum(x["L"])) / y)
    A, b = np.asarray(A), np.asarray(b)
    try:
        return np.linalg.solve(A.T @ A + ridge * len(train) * np.eye(A.shape[1]), A.T @ b)
    except np.linalg.LinAlgError:
        return np.zeros(3 * nf if sep else nf)


def rolling_ls(F, fl, feats, sep=False):
    pr = predict_sep if sep else predict
    e = [err(pr(F[f], fit_ls(F, tr, feats, sep), feats), F[f]["rest_meas"]) for f, tr in rolling_sets(fl)]
    return e, fit_ls(F, fl, feats, sep)


def grid_err(x, feat, w):
    return err(predict(x, [w], [feat]), x["rest_meas"])


def grid_w(F, train, feat):
    return min(GRID, key=lambda w: (med([grid_err(F[g], feat, w) for g in train]), w))


def rolling_grid(F, fl, feat):
    e = [grid_err(F[f], feat, grid_w(F, tr, feat)) for f, tr in rolling_sets(fl)]
    return e, grid_w(F, fl, feat)


def better_share(a, b):
    """Share of paired resamples of the flights in which errors `a` have the smaller median."""
    rng = random.Random(1)
    n, wins = len(a), 0
    for _ in range(RESAMPLES):
        idx = [rng.randrange(n) for _ in range(n)]
        if med([a[i] for i in idx]) < med([b[i] for i in idx]):
            wins += 1
    return wins / RESAMPLES


def model_ratio(F, fl, path):
    """`sM`: the first half's measured energy over the power model's out-of-fold estimate of
    the same rows (joined on flight and instant, the measured power agreeing within 1 W);
    1 where fewer than half the first half's rows have an estimate. Returns how many have one."""
    est = {}
    with open(path) as fh:
        head = fh.readline().strip().split(",")
        fi, ti, mi, bi = (head.index(c) for c in ("flight", "t_s", "measured_w", "blend_w"))
        for line in fh:
            v = line.split(",")
            est.setdefault(int(v[fi]), {})[round(10 * float(v[ti]))] = (float(v[mi]), float(v[bi]))
    if set(est) & TEST_FLIGHTS:
        sys.exit(f"{path}: test flights {sorted(set(est) & TEST_FLIGHTS)}; this analysis reads training flights only")
    have = 0
    for f in fl:
        x, e = F[f], est.get(f, {})
        R, i0, ih = x["R"], x["i0"], x["ih"]
        num = den = 0.0
        n = 0
        for r in range(i0, ih):
            m = e.get(round(10 * R[r, 0]))
            if m is not None and abs(m[0] - R[r, 1]) < 1.0:
                num, den, n = num + m[0], den + m[1], n + 1
        enough = n >= 0.5 * (ih - i0) and den > 0
        x["sM"] = clamp(num / den) if enough else 1.0
        have += enough
    return have


def main():
    args = sys.argv[1:]
    oof = None
    if len(args) == 3 and args[1] == "--oof":
        oof = args[2]
    elif len(args) != 1:
        sys.exit(__doc__)
    cal, F = load(args[0])
    fl, mismatch = prepare(cal, F)
    features(F, fl)
    rest = [F[f]["rest_meas"] for f in fl]
    rr = [F[f]["rr"] for f in fl]
    r_of = lambda ft: corr([F[f][ft] for f in fl], rr)  # noqa: E731
    print(f"{len(fl)} training flights (rolling validation); live weight {cal['live_weight']}; "
          f"plan-eval's live forecast reproduced on {len(fl) - mismatch} of them")
    G = {ft: rolling_grid(F, fl, ft) for ft in ["sE", "sH", "sH2", "sCr", "sHv", "sC", "sP"]}
    LS = {tuple(fs): rolling_ls(F, fl, fs) for fs in [["sE"], ["sH2"], ["sT"], ["hwd"], ["sH2", "hwd"]]}
    ls_sep_sT = rolling_ls(F, fl, ["sT"], sep=True)
    shipped = [err(F[f]["left"] * (1 + cal["live_weight"] * (F[f]["sE"] - 1)), F[f]["rest_meas"]) for f in fl]
    gm = lambda ft: med(G[ft][0])  # noqa: E731
    lm = lambda *fs: med(LS[fs][0])  # noqa: E731

    def row(name, value, note=""):
        print(f"| {name} | {value} | {note} |".replace("|  |", "| |").replace("r = -", "r = −"))

    print("\nMedian error of the rest at half time, training flights:\n")
    print("| live correction | training, rolling | note |\n|---|---|---|")
    row("none", f"{med([err(sum(F[f]['L']), y) for f, y in zip(fl, rest)]):.2f} %")
    row("overall ratio, weight on a grid 0…1 (shipped)",
        f"{gm('sE'):.2f} % ({med(shipped):.2f} % with the weight fitted on all of them, as shipped)",
        f"r = {r_of('sE'):.2f} with the rest's measured/forecast")
    row("overall ratio, weight by least squares", f"{lm('sE'):.2f} %")
    tie = 1 - better_share(LS[("sH2",)][0], LS[("sE",)][0])
    row("horizontal flight only (cruise and stops after lift-off), grid / least squares",
        f"{gm('sH2'):.2f} % / {lm('sH2'):.2f} %",
        f"r = {r_of('sH2'):.2f}; no better than the overall ratio in {100 * tie:.0f} % of paired resamples: a tie")
    g = [f for f in fl if F[f]["fc"][0, CRUISE] > 0.5 and F[f]["fc"][1, CRUISE] > 0.5]
    cr = corr([F[f]["mc"][0, CRUISE] / F[f]["fc"][0, CRUISE] for f in g], [F[f]["mc"][1, CRUISE] / F[f]["fc"][1, CRUISE] for f in g])
    row("cruise only", f"{gm('sCr'):.2f} %", f"cruise first half vs the rest's cruise, r = {cr:.2f}")
    row("stops (hover) only", f"{gm('sHv'):.2f} % (weight {G['sHv'][1]:g})", f"r = {r_of('sHv'):.2f}")
    cl = [f for f in fl if F[f]["fc"][0, CLIMB] > 0.3]
    rc = corr([F[f]["mc"][0, CLIMB] / F[f]["fc"][0, CLIMB] for f in cl], [F[f]["rest_meas"] / F[f]["left"] for f in cl])
    row("climb only", f"{gm('sC'):.2f} % (weight {G['sC'][1]:g})", f"r = {rc:.2f} with the rest")
    row("the whole first half's power at matched places", f"{gm('sP'):.2f} %")
    pace = sorted([lm("sT"), med(ls_sep_sT[0])])
    t_first = [(F[f]["R"][F[f]["ih"], 0] - F[f]["R"][F[f]["i0"], 0]) / ((F[f]["k"] + 1) * F[f]["dt"]) for f in fl]
    t_rest = [(F[f]["R"][F[f]["i1"], 0] - F[f]["R"][F[f]["ih"], 0]) / ((len(F[f]["cat"]) - F[f]["k"] - 1) * F[f]["dt"]) for f in fl]
    # least squares, one weight / one per phase of the rest
    row("pace: the first half's airborne time over the plan's",
        f"{pace[0]:.2f}–{pace[1]:.2f} %", f"r = {corr(t_first, t_rest):.2f} with the rest's time")
    row("wind from the first half: the rest's headwind against the first half's, least squares",
        f"{lm('hwd'):.2f} % alone; {lm('sH2', 'hwd'):.2f} % beside the horizontal ratio ({lm('sH2'):.2f} % without it)",
        "see below")

    if oof:
        have = model_ratio(F, fl, oof)
        g1, _ = rolling_grid(F, fl, "sM")
        l1, _ = rolling_ls(F, fl, ["sM"])
        l2, _ = rolling_ls(F, fl, ["sE", "sM"])
        row("the power model's own ratio: measured / its out-of-fold estimate on the flown kinematics, grid / least squares",
            f"{med(g1):.2f} % / {med(l1):.2f} %; {med(l2):.2f} % beside the overall ratio (least squares)",
            f"r = {r_of('sM'):.2f}; {have} of {len(fl)} flights have the estimate")

    print("\nCorrelations and the rest:")
    p_rest = [F[f]["rest_meas"] / max(F[f]["R"][F[f]["i1"], 0] - F[f]["R"][F[f]["ih"], 0], 1)
              / (F[f]["left"] / ((len(F[f]["cat"]) - F[f]["k"] - 1) * F[f]["dt"])) for f in fl]
    rl = [F[f]["rest_meas"] / F[f]["left"] for f in fl]
    print(f"- the rest's measured/forecast energy vs its measured/planned time: r = {corr(rl, t_rest):.2f}; "
          f"vs its mean power measured/forecast: r = {corr(rl, p_rest):.2f}")
    print(f"- the first half's ratio vs the rest's (unclamped): r = "
          f"{corr([F[f]['so_far'] / F[f]['done'] for f in fl], rl):.2f}; horizontal flight: r = {r_of('sH2'):.2f}")
    share = lambda h, c: np.mean([F[f]["fc"][h, c] / F[f]["fc"][h].sum() for f in fl])  # noqa: E731
    print(f"- share of the forecast: first half climb {share(0, CLIMB):.2f}, cruise {share(0, CRUISE):.2f}; "
          f"rest descent {share(1, DESCENT):.2f}, cruise {share(1, CRUISE):.2f}")
    art = better_share(G["sH"][0], G["sE"][0])
    none0 = np.mean([F[f]["t0"] == 0 for f in fl])
    print(f"- artefact (horizontal flight with the rows found at the plan's first sample, the spin-up): "
          f"{gm('sH'):.2f} % rolling, better than the overall ratio in {100 * art:.0f} % of resamples; "
          f"the spin-up's own ratio vs the rest: r = {r_of('sG'):.2f}; no row found there on {100 * none0:.0f} % of the flights")
    wind_report(F, fl)


def wind_report(F, fl):
    """The wind bullet: the legs' wind estimates, their agreement with the ground wind, and
    the legs' measured/forecast power against the headwind along them."""
    spread, vs_ground, scatter = [], [], {}
    for f in fl:
        x = F[f]
        R, rk, i0, i1 = x["R"], x["row_k"], x["i0"], x["i1"]
        est = {}
        for r in range(i0 + 1, i1):
            kr = rk[r - i0]
            if x["cat"][kr] != CRUISE:
                continue
            leg = x["leg"][kr]
            hd = heading(x, leg)
            sp = math.hypot(R[r, 5], R[r, 6]) / 0.925
            ws, wa = R[r, 3], math.radians(R[r, 4])
            est.setdefault(leg, []).append((ws * math.sin(wa) - sp * math.sin(hd), ws * math.cos(wa) - sp * math.cos(hd)))
        m = {leg: np.mean(v, axis=0) for leg, v in est.items() if len(v) > 10}
        if len(m) >= 2:
            legs = sorted(m)
            spread.append(np.mean([np.hypot(*(m[leg] - m[legs[0]])) for leg in legs[1:]]))
        gs, gf = x["wind"][0], math.radians(x["wind"][1])
        if m:
            g = np.array([gs * math.sin(gf), gs * math.cos(gf)])
            vs_ground.append(np.mean([np.hypot(*(v - g)) for v in m.values()]))
    print(f"- wind aloft: the legs' estimates differ by {med(spread):.1f} m/s (median, {len(spread)} flights); "
          f"from the pre-take-off ground wind by {med(vs_ground):.1f} m/s")
    for label, src in [("the first half's wind", "first"), ("the ground wind", "ground")]:
        X, Y = [], []
        for f in fl:
            x = F[f]
            R, rk, i0, i1, dt = x["R"], x["row_k"], x["i0"], x["i1"], x["dt"]
            num, den = {}, {}
            for r in range(i0, i1):
                kr = rk[r - i0]
                if x["cat"][kr] != CRUISE:
                    continue
                leg = x["leg"][kr]
                num[leg] = num.get(leg, 0) + R[r + 1, 2] - R[r, 2]
                den[leg] = den.get(leg, 0) + x["e50"][kr] / dt * (R[r + 1, 0] - R[r, 0])
            if src == "first":
                we, wn, _ = x["wind_first"]
            else:
                gs, gf = x["wind"][0], math.radians(x["wind"][1])
                we, wn = gs * math.sin(gf), gs * math.cos(gf)
            per = []
            for leg in num:
                if den[leg] < 0.5:
                    continue
                hd = heading(x, leg)
                per.append((num[leg] / den[leg], we * math.sin(hd) + wn * math.cos(hd), leg))
            if len(per) >= 2:
                mean = np.mean([p[0] for p in per])
                for ratio, hw, leg in per:
                    X.append(hw)
                    Y.append(ratio / mean - 1)
                    if src == "ground":
                        scatter.setdefault(leg, []).append(ratio / mean - 1)
        slope = np.polyfit(X, Y, 1)[0]
        print(f"- legs' measured/forecast power vs the headwind along them ({label}): r = {corr(X, Y):.2f}, "
              f"{100 * slope:.2f} % per m/s ({len(X)} legs)")
    sd = [100 * np.std(v) for v in scatter.values() if len(v) > 20]
    print(f"- the legs' own scatter (their ratio over the flight's mean, standard deviation): "
          f"{min(sd):.1f}–{max(sd):.1f} %")


if __name__ == "__main__":
    main()
