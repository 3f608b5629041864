#!/usr/bin/env python3
"""Score dronewatt on ProgPy packs (flights from progpy_flights.py): replay each .tlog with
`dronewatt replay --json`, and compare with ProgPy's truth beside it.

  progpy_score.py --dir DIR --bin target/release/dronewatt [--set score] [--json OUT] [--plot OUT.png]
                  [--before OTHER_BIN] [--md]
  progpy_score.py --from-json OUT --prognoser PROGNOSER.json --plot OUT.png   # the plot again, with
                  ProgPy's prognoser (progpy_prognoser.py --json) beside

Figures, per flight then the median over the set:
- time to BATT_LOW_VOLT forecast at 25/50/75 % of the way from take-off to the crossing:
  (forecast − truth) / truth, signed (+ = too long, late: the dangerous side);
- state of charge at take-off (points), dronewatt's `soc_pct` against ProgPy's energy fraction;
- energy left at landing, dronewatt's `soc_pct` × `capacity_wh` against ProgPy's (C/5 to 3.0 V
  a cell), as % of the pack's full energy.
Beside dronewatt: PX4's estimator as it runs today (its time remaining, SoC × capacity over the
50 s average current, the port of src/offline/battery_eval/autopilots.rs in Python), and
`--before`, another dronewatt binary (the model before a change).
"""
import argparse
import glob
import json
import math
import os
import statistics
import subprocess
import tempfile

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402

FRACS = (0.25, 0.5, 0.75)
CONFIG = '[energy]\nchemistry = "liion"\n'


def replay(binary, tlog, cfg):
    out = subprocess.run([binary, "replay", "--speed", "max", "--json", "-", "-q", "--data-dir", "off",
                          "--config", cfg, tlog], capture_output=True, text=True, timeout=600)
    if out.returncode != 0:
        raise RuntimeError(f"{binary} replay {tlog}: {out.stderr[-2000:]}")
    est = [json.loads(x) for x in out.stdout.splitlines() if x.startswith('{"type":"estimate"')]
    alerts = [json.loads(x) for x in out.stdout.splitlines() if x.startswith('{"type":"alert"')]
    return est, alerts


def readings(tlog):
    """(t on the flight's clock, pack V, pack A) of the log's battery messages."""
    m = mavutil.mavlink_connection(tlog, dialect="ardupilotmega")
    rows, t0 = [], 1_700_000_000.0  # progpy_flights.py's T0_US: the flight's own clock
    while True:
        msg = m.recv_match(type=["SYS_STATUS", "BATTERY_STATUS"], blocking=False)
        if msg is None:
            break
        t = msg._timestamp
        if msg.get_type() == "SYS_STATUS":
            v, i = msg.voltage_battery / 1000.0, msg.current_battery / 100.0
        else:
            cells = [c for c in msg.voltages if c != 65535]
            v, i = cells[0] / 1000.0 * len(cells), msg.current_battery / 100.0
        rows.append((t - t0, v, i))
    return rows


def px4_time_remaining(rows, n, cap_mah, t_takeoff):
    """PX4's Battery (defaults: BAT1_R_INTERNAL −1, V_EMPTY 3.6, V_CHARGED 4.05) and its
    computeRemainingTime: [(t, seconds remaining, soc)]."""
    lam, p_ocv, p_r = 0.95, 1.5 * n, 0.1 * n
    st = {"conn": 0.0, "rls": [4.2 * n, 0.005 * n], "P": [[p_ocv, 0.0], [0.0, p_r]], "r": 0.005,
          "cell": None, "mah": 0.0, "soc": 0.0, "iavg": None}

    def pnorm(P):
        return math.sqrt(P[0][0] ** 2 + 2 * P[1][0] ** 2 + P[1][1] ** 2)
    st["pn"] = pnorm(st["P"])
    out, last = [], None
    for t, v, i in rows:
        dt = 0.0 if last is None else t - last
        last = t
        st["conn"] += dt
        settled = st["conn"] > 2.0
        if not settled:
            st["rls"], st["P"], st["r"] = [v, 0.005 * n], [[p_ocv, 0.0], [0.0, p_r]], 0.005
            st["pn"] = pnorm(st["P"])
            st["cell"] = v / n + st["r"] * i
        used = i * 1e3 * dt / 3600.0
        st["mah"] += used
        cell = v / n
        if i > 1e-9:
            x = [1.0, -i]
            P = st["P"]
            px = [P[0][0] * x[0] + P[0][1] * x[1], P[1][0] * x[0] + P[1][1] * x[1]]
            xpx = x[0] * px[0] + x[1] * px[1]
            err = v - (x[0] * st["rls"][0] + x[1] * st["rls"][1])
            g = [px[0] / (lam + xpx), px[1] / (lam + xpx)]
            Pn = [[(P[r][c] - g[r] * px[c]) / lam for c in range(2)] for r in range(2)]
            if pnorm(Pn) < st["pn"]:
                st["rls"] = [st["rls"][0] + g[0] * err, st["rls"][1] + g[1] * err]
                st["P"], st["pn"] = Pn, pnorm(Pn)
                st["r"] = max(st["rls"][1] / n, 0.0)
            else:
                st["rls"][0] = v + st["rls"][1] * i
            cell += st["r"] * i
        a = dt / (1.0 + dt)
        st["cell"] = cell if st["cell"] is None else st["cell"] + a * (cell - st["cell"])
        soc_v = min(max((st["cell"] - 3.6) / (4.05 - 3.6), 0.0), 1.0)
        if settled:
            w = 0.03 * (1.0 - soc_v)
            st["soc"] = max((1 - w) * st["soc"] + w * soc_v - used / cap_mah, 0.0)
            st["soc"] = min(st["soc"], max(1.0 - st["mah"] / cap_mah, 0.0))
        else:
            st["soc"] = soc_v
        if t >= t_takeoff:
            ia = 1.0 - math.exp(-dt / 50.0) if dt > 0 else 0.0
            st["iavg"] = 15.0 if st["iavg"] is None else st["iavg"] + ia * (i - st["iavg"])
            out.append((t, st["soc"] * cap_mah / 1000.0 / max(st["iavg"], 0.1) * 3600.0, st["soc"]))
        else:
            out.append((t, None, st["soc"]))
    return out


def at(series, t, key):
    """The latest value of `key` at or before t (estimates carry t)."""
    best = None
    for e in series:
        if e["t"] <= t + 1e-6 and e.get(key) is not None:
            best = e
        if e["t"] > t:
            break
    return None if best is None else best[key]


def score_flight(tr, est, rows):
    """One flight's figures (None where the estimate was absent)."""
    t0, tc = tr["t_takeoff"], tr["t_cross"]
    # The JSON's t is seconds of source time since the log's first frame (a battery message's).
    for e in est:
        e["t"] += rows[0][0] if rows else 0.0
    f = {"name": tr["name"], "ttl": {}, "px4": {}}
    if tc is not None and tc > t0:
        px4 = px4_time_remaining(rows, tr["s"], tr["cap_mah"], t0)
        for q in FRACS:
            tq = t0 + q * (tc - t0)
            truth = tc - tq
            pred = at(est, tq, "time_to_low_v_s")
            f["ttl"][q] = None if pred is None else (pred - truth) / truth
            pp = [x for x in px4 if x[0] <= tq and x[1] is not None]
            f["px4"][q] = (pp[-1][1] - truth) / truth if pp else None
    soc = at(est, t0 - 0.5, "soc_pct")
    f["soc_err"] = None if soc is None else soc - 100.0 * tr["soc_takeoff"]
    soc_l, cap = at(est, tr["t_land"], "soc_pct"), at(est, tr["t_land"], "capacity_wh")
    f["energy_err_pct"] = (None if soc_l is None or cap is None
                           else 100.0 * (soc_l / 100.0 * cap - tr["energy_landing_wh"]) / tr["full_wh"])
    return f


def summarise(fl, key="ttl"):
    errs = [x[key][q] for x in fl for q in FRACS if q in x[key]]
    have = [e for e in errs if e is not None]
    return {
        "forecasts": len(errs), "missing": len(errs) - len(have),
        "median_abs_pct": 100.0 * statistics.median([abs(e) for e in have]) if have else None,
        "late_over_25pct": sum(1 for e in have if e > 0.25),
        "worst_late_pct": 100.0 * max(have) if have else None,
        "by_frac": {q: (100.0 * statistics.median([abs(x[key][q]) for x in fl if x[key].get(q) is not None])
                        if any(x[key].get(q) is not None for x in fl) else None) for q in FRACS},
    }


def run_bin(binary, truths, d, cfg):
    fl = []
    for tr in truths:
        tlog = os.path.join(d, tr["name"] + ".tlog")
        est, _ = replay(binary, tlog, cfg)
        fl.append(score_flight(tr, est, readings(tlog)))
    return fl


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--dir", required=True)
    ap.add_argument("--bin", required=True)
    ap.add_argument("--before", default=None)
    ap.add_argument("--set", default="score")
    ap.add_argument("--json", default=None)
    ap.add_argument("--plot", default=None)
    ap.add_argument("--prognoser", default=None, help="progpy_prognoser.py's --json, for the plot")
    ap.add_argument("--from-json", default=None, help="an earlier --json: plot it, replay nothing")
    a = ap.parse_args()
    if a.from_json:
        res = json.load(open(a.from_json))
        if a.prognoser:
            pr = json.load(open(a.prognoser))
            res["per_flight_prognoser"] = pr["per_flight"]
        for k in [k for k in res if k.startswith("per_flight")]:
            for f in res[k]:  # JSON's keys are strings: the fractions again
                for key in ("ttl", "px4"):
                    if key in f:
                        f[key] = {float(q): v for q, v in f[key].items()}
        if a.plot:
            plot(res, a.plot)
        return
    truths = sorted((json.load(open(p)) for p in glob.glob(os.path.join(a.dir, "*.truth.json"))),
                    key=lambda t: t["name"])
    truths = [t for t in truths if a.set == "all" or t["set"] == a.set]
    with tempfile.NamedTemporaryFile("w", suffix=".toml", delete=False) as f:
        f.write(CONFIG)
        cfg = f.name
    res = {"flights": len(truths), "set": a.set}
    now = run_bin(a.bin, truths, a.dir, cfg)
    res["dronewatt"] = summarise(now)
    res["px4"] = summarise(now, "px4")
    socs = [x["soc_err"] for x in now if x["soc_err"] is not None]
    ens = [x["energy_err_pct"] for x in now if x["energy_err_pct"] is not None]
    res["soc_takeoff_median_abs_pts"] = statistics.median([abs(s) for s in socs]) if socs else None
    res["energy_landing_median_abs_pct"] = statistics.median([abs(e) for e in ens]) if ens else None
    res["per_flight"] = now
    if a.before:
        before = run_bin(a.before, truths, a.dir, cfg)
        res["before"] = summarise(before)
        bs = [abs(x["soc_err"]) for x in before if x["soc_err"] is not None]
        be = [abs(x["energy_err_pct"]) for x in before if x["energy_err_pct"] is not None]
        res["before"]["soc_takeoff_median_abs_pts"] = statistics.median(bs) if bs else None
        res["before"]["energy_landing_median_abs_pct"] = statistics.median(be) if be else None
        res["per_flight_before"] = before
    os.unlink(cfg)
    if a.json:
        with open(a.json, "w") as f:
            json.dump(res, f, indent=1, default=str)
    if a.plot:
        plot(res, a.plot)
    print(json.dumps({k: v for k, v in res.items() if not k.startswith("per_flight")}, indent=1, default=str))


def plot(res, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4))
    series = [("dronewatt", res["per_flight"], "ttl", "C0")]
    if "per_flight_before" in res:
        series.append(("dronewatt before", res["per_flight_before"], "ttl", "C7"))
    series.append(("PX4 time remaining", res["per_flight"], "px4", "C3"))
    if "per_flight_prognoser" in res:
        series.append(("ProgPy's prognoser", res["per_flight_prognoser"], "ttl", "C2"))
    for k, (label, fl, key, col) in enumerate(series):
        for j, q in enumerate(FRACS):
            ys = [100.0 * x[key][q] for x in fl if x[key].get(q) is not None]
            xs = [j + (k - (len(series) - 1) / 2) * 0.2 + 0.03 * ((n % 5) - 2) for n in range(len(ys))]
            ax.scatter(xs, ys, s=12, color=col, label=label if j == 0 else None, alpha=0.7)
    ax.axhline(25, color="k", lw=0.8, ls="--")
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xticks(range(3), ["25 %", "50 %", "75 %"])
    ax.set_xlabel("forecast made at this fraction of the way to BATT_LOW_VOLT")
    ax.set_ylabel("time-to-low error, % (+ = late)")
    ax.set_yscale("symlog", linthresh=50)
    ax.legend(fontsize=8)
    ax.set_title(f"ProgPy packs, {res['set']} set ({res['flights']} flights)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
