"""Lab (round 4): the forecast from half time on the flight's own warm/cold resistance fit
(`src/battery/split.rs`) against the RLS's resistance held (as shipped before), chosen by
5-fold by-flight cross-validation on the TRAINING flights only (fold = flight number mod 5).
Prints training figures only; the test flights are scored by `dronewatt-lab battery-eval`.

    python3 lab/scripts/battery/lab_split.py            # ~1 min; numpy, scipy, pandas (README.md)
    MEMORY_S=300 python3 lab/scripts/battery/lab_split.py

Mirrors the Rust estimator (circuit.rs) and forecast (forecast.rs): the same constants, the
heat and the resistance scale carried from the previous flight on the same pack, the
forecast given the flight's measured power after half time. The figure is the median
|lowest loaded voltage after half time, forecast − measured| (V, I > 3 A).
"""
import os
import numpy as np
from extract import flights, NC
from ecm import Curve, resample, DT, TAUH

# src/battery/ocv.rs (TB48D) and circuit.rs defaults
V_ = [3.30, 3.50, 3.60, 3.65, 3.70, 3.75, 3.80, 3.85, 3.90, 3.95, 4.00, 4.05, 4.10, 4.15, 4.20, 4.25, 4.30, 4.35]
E_ = [0.0, 2.6967, 5.9327, 8.6295, 12.4048, 23.2373, 33.4275, 42.5313, 50.2597, 56.8941, 62.9216,
      68.8063, 74.5859, 80.2470, 85.9296, 91.7883, 97.5807, 103.3736]
C = Curve(V_, E_)
R0, R1, T1, WA, HS, B = 0.03815986718039996, 0.020102362824778616, 27.887386318929398, 1.1655876571448482, 58469.27, -0.0226429840582387
LAM, CARRY = 0.995, 0.555131958024547
MEMORY_S = float(os.environ.get("MEMORY_S", "600"))
PRIOR_GRID = [5, 10, 20, 40, 80, 160]


def vcell(e):
    return float(np.interp(e, C.e, C.v))


class Est:
    """circuit.rs's Estimator (RLS on [R0, R1, b]) plus split.rs's sums."""

    def __init__(s, v_rest, h0=0.0, m=1.0):
        s.m, s.E, s.x1, s.H = m, float(C.E(v_rest / NC)), 0.0, h0
        s.th, s.P = np.array([R0 * m, R1 * m, B]), np.diag([1e-4, 1e-4, 1e-2])
        s.zz, s.zy, s.T, s.xw, s.xc, s.ss = np.zeros((3, 3)), np.zeros(3), 0.0, 0.0, 0.0, np.zeros(2)

    def update(s, dt, i, v):
        if not (np.isfinite(dt) and np.isfinite(i) and np.isfinite(v)) or dt <= 0 or dt > 5 or v <= 0 or i < -2:
            return
        i = max(i, 0.0)
        s.H = s.H * np.exp(-dt / TAUH) + i * i * TAUH * (1 - np.exp(-dt / TAUH))
        c = WA * np.exp(-s.H / HS); f = 1 + c; e1 = np.exp(-dt / T1)
        s.x1 = s.x1 * e1 + f * i * (1 - e1)
        s.xw = s.xw * e1 + i * (1 - e1); s.xc = s.xc * e1 + c * i * (1 - e1)
        phi = np.array([f * i, s.x1, 1.0])
        s.E = max(s.E - v * i * dt / 3600, 0.0); ocv = NC * vcell(s.E)
        err = v - (ocv - s.th @ phi)
        if i > 1.0:
            pp = s.P @ phi; g = pp / (LAM + phi @ pp)
            s.th = np.clip(s.th + g * (-err), [0, 0, -1], [0.5, 0.5, 1]); s.P = (s.P - np.outer(g, pp)) / LAM
            tr = np.trace(s.P)
            if tr > 1.0:
                s.P /= tr
        if i > 3.0:
            gn = s.m * (R0 * f * i + R1 * s.x1); s.ss += [gn * (ocv - B - gn - v), gn * gn]
            z = np.array([s.m * (R0 * i + R1 * s.xw), s.m * (R0 * c * i + R1 * s.xc), 1.0])
            keep = np.exp(-dt / MEMORY_S)
            s.zz = s.zz * keep + np.outer(z, z) * dt; s.zy = s.zy * keep + z * (ocv - v) * dt; s.T = s.T * keep + dt

    def fit(s, prior_s):
        prior = np.array([1.0, 1.0, B])
        if s.T <= 0:
            return prior
        w = (prior_s / s.T) * np.diag(np.diag(s.zz))
        try:
            k = np.linalg.solve(s.zz + w, s.zy + w @ prior)
        except np.linalg.LinAlgError:
            return prior
        return np.clip(k, [0, 0, -1], [5, 5, 1])

    def copy(s):
        n = Est.__new__(Est); n.__dict__ = dict(s.__dict__)
        for k in ("th", "P", "zz", "zy", "ss"):
            setattr(n, k, getattr(s, k).copy())
        return n


def lowest(s, prof, k=None):
    """Lowest loaded voltage flying prof [(dt, W)]: on the RLS's θ (k None) or the split fit k."""
    s = s.copy(); vmin = np.inf
    for dt, p in prof:
        p = max(p, 0.0); s.H *= np.exp(-dt / TAUH); c = WA * np.exp(-s.H / HS); e1 = np.exp(-dt / T1)
        ocv = NC * vcell(s.E)
        if k is None:
            r0, r1, b = s.th; f = 1 + c
            cc = ocv - b - r1 * s.x1 * e1; re = f * r0 + r1 * f * (1 - e1)
        else:
            kw, kc, b = k
            cc = ocv - b - s.m * R1 * (kw * s.xw + kc * s.xc) * e1
            re = max(s.m * (R0 + R1 * (1 - e1)) * (kw + kc * c), 1e-6)
        disc = cc * cc - 4 * re * p
        i = (cc - np.sqrt(disc)) / (2 * re) if disc >= 0 else cc / (2 * re)
        v = cc - re * i
        s.H += i * i * TAUH * (1 - np.exp(-dt / TAUH))
        s.x1 = s.x1 * e1 + (1 + c) * i * (1 - e1); s.xw = s.xw * e1 + i * (1 - e1); s.xc = s.xc * e1 + c * i * (1 - e1)
        s.E = max(s.E - v * i * dt / 3600, 0.0); vmin = min(vmin, v)
    return vmin


def main():
    F = flights()
    prev = {r["next"]: f for f, r in F.items() if r.get("next")}
    end, rows = {}, []
    for f, r in sorted(F.items()):
        if not r.get("has_on") or not np.isfinite(r.get("v_start", np.nan)):
            continue
        h0, m = 0.0, 1.0
        if prev.get(f) in end:
            he, kp = end[prev[f]]; q = F[prev[f]]
            h0 = he * np.exp(-max((r["tmin"] - q["tmin"]) * 60 - q["t"][-1], 0) / TAUH)
            if kp is not None and 0.2 <= kp <= 5:
                m = min(max(1 + CARRY * (kp - 1), 0.5), 2.0)
        t, cur, volt = r["t"], r["I"], r["V"]
        s = Est(r["v_start"], h0, m); mid = None
        tmid = 0.5 * (t[r["i_on"]] + t[r["i_off"]])
        for k in range(1, len(t)):
            if t[k] >= tmid and mid is None:
                mid = (s.copy(), k)
            s.update(t[k] - t[k - 1], cur[k], volt[k])
        end[f] = (s.H, 1 + s.ss[0] / s.ss[1] if s.ss[1] > 1e-9 else None)
        if r["test"] or r["route"] in ("A1", "A2", "A3", "H") or mid is None:
            continue  # training route flights only (the test flights are battery-eval's)
        tg, ig, vg = resample(r); loaded = ig > 3
        sm, k = mid; j = np.searchsorted(tg, t[k - 1])
        if not loaded[j:].any():
            continue
        prof = list(zip(np.full(len(tg) - j, DT), (vg * ig)[j:])); meas = vg[j:][loaded[j:]].min()
        row = dict(flight=f, first=f not in prev, rls=lowest(sm, prof) - meas)
        for p in PRIOR_GRID:
            row[p] = lowest(sm, prof, sm.fit(p)) - meas
        rows.append(row)
    med = lambda xs: float(np.median(np.abs(xs)))
    print(f"training route flights scored from half time: {len(rows)} (memory {MEMORY_S:g} s)")
    for key in ["rls"] + PRIOR_GRID:
        xs = [x[key] for x in rows]
        print(f"{'RLS held' if key == 'rls' else f'split, prior {key} s':<22} |err| {med(xs):.3f} V  signed {np.median(xs):+.3f}"
              f"  first {med([x[key] for x in rows if x['first']]):.3f}  chained {med([x[key] for x in rows if not x['first']]):.3f}")
    errs, picks = [], []
    for fo in range(5):
        trn = [x for x in rows if x["flight"] % 5 != fo]
        best = min(PRIOR_GRID, key=lambda p: med([x[p] for x in trn])); picks.append(best)
        errs += [x[best] for x in rows if x["flight"] % 5 == fo]
    print(f"nested CV (prior picked on the other 4 folds): |err| {med(errs):.3f} V, picks {picks}")


if __name__ == "__main__":
    main()
