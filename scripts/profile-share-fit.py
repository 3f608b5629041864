#!/usr/bin/env python3
"""Fit the profile share s (1 - the figure of merit, `[priors] profile_share`) leave-one-airframe-out.

For each s on a grid, each airframe's after-hover plan error: the `multirotor` peers' ten plans
(scripts/peer-multirotor.py's flights, `plan --hover-w` on the spec sheet with the priors fitted
without the airframe) and the M100 data set's training route flights, every third
(scripts/spec-m100.py --flights train --every 3: never its test flights). The hover is exact at
any s (a hover is T·v_h/η whatever the split), so this stage sees only the cruise: how much of
the hover power the translational lift relieves and what the parasite power pays.

The rule (written before the grid was run): for an airframe held out, s is the grid value that
minimizes the mean, over the other airframes, of their after-hover median |error| (ties: the
smaller s); the shipped prior (src/model/spec.rs PROFILE_SHARE) the same over all three.
scripts/spec-priors.py's `profile_share_prior` reads the grid this writes.

    .venv-py/bin/python scripts/profile-share-fit.py --json docs/src/generated/profile-share.json [--out DIR]
"""
import argparse
import importlib
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
GRID = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6]
AIRFRAMES = ("t18", "mavic", "m100")


def peer_flights(peer, out, pm):
    """Fly the ten plans once (cached in `out`): [(plan, spec facts, speed, wind, truth Wh, hover W)]."""
    res = []
    for i, (name, legs, speed, wind) in enumerate(pm.FLIGHTS):
        tlog = os.path.join(out, f"flight{i}.tlog")
        if not os.path.exists(tlog):
            pm.fly(peer, pm.profile(legs, speed), wind[0], wind[1], i, tlog, pm.mission_items(legs, speed))
        rows = pm.read_tlog(tlog)
        truth = sum(v * c for _, v, c, _ in rows) * pm.DT / 3600.0
        plan = os.path.join(out, f"flight{i}.waypoints")
        pm.waypoints(plan, legs, speed)
        res.append((plan, speed, wind, truth, pm.first_hover_w(rows)))
    return res


def peer_errors(binary, peer, flights, held, share, out, pm):
    """{spec, hover}: (median |error| %, P90 cover %) at this share."""
    eta0, sd0, drag0, slope0 = held
    spec = os.path.join(out, f"spec-{share:.2f}.toml")
    with open(spec, "w") as f:
        f.write(pm.SPEC.format(name=peer.name, kg=peer.mass, n=peer.n, d=peer.prop_m, cells=peer.cells,
                               mah=peer.mah, chem=peer.chemistry)
                + f"[priors]\neta_h = {eta0:.4f}\neta_h_log_sd = {sd0:.4f}\ndrag_per_kg23 = {drag0:.5f}\n"
                  f"eta_h_per_ln_dl = {slope0:.4f}\nprofile_share = {share:.3f}\n")
    st = {"spec": [], "hover": []}
    for plan, speed, wind, truth, hw in flights:
        p50, p90 = pm.forecast(binary, plan, spec, speed, wind)
        st["spec"].append((100 * (p50 / truth - 1), p90 >= truth))
        h50, h90 = pm.forecast(binary, plan, spec, speed, wind, ["--hover-w", f"{hw:.1f}"])
        st["hover"].append((100 * (h50 / truth - 1), h90 >= truth))
    return {k: dict(median_abs_err_pct=round(float(np.median([abs(e) for e, _ in v])), 2),
                    p90_cover_pct=round(100 * sum(c for _, c in v) / len(v), 1),
                    errs=[round(e, 1) for e, _ in v]) for k, v in st.items()}


def m100_errors(binary, share):
    r = subprocess.run([sys.executable, os.path.join(HERE, "spec-m100.py"), "--bin", binary, "--flights", "train",
                        "--every", "3", "--profile-share", str(share)], capture_output=True, text=True, check=True)
    j = json.loads(r.stdout)
    return dict(spec=dict(median_abs_err_pct=j["summary"]["spec"]["median_abs_err_pct"],
                          p90_cover_pct=j["summary"]["spec"]["p90_cover_pct"]),
                hover=dict(median_abs_err_pct=j["summary"]["hover"]["median_abs_err_pct"]))


def choose(grid, fitting):
    """The grid's s minimizing the mean after-hover median |error| over `fitting` (ties: the smaller)."""
    best = None
    for s in sorted(grid, key=float):
        cost = float(np.mean([grid[s][a]["hover"]["median_abs_err_pct"] for a in fitting]))
        if best is None or cost < best[1] - 1e-9:
            best = (float(s), cost)
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bin", default=os.path.join(HERE, "..", "target", "debug", "dronewatt"))
    ap.add_argument("--json")
    ap.add_argument("--out", help="keep the peers' .tlog here (reused when there)")
    ap.add_argument("--grid", default=",".join(str(s) for s in GRID))
    a = ap.parse_args()
    pm = importlib.import_module("peer-multirotor")
    import peer_airframes
    priors = importlib.import_module("spec-priors")
    rows = priors.airframes()
    out = a.out or tempfile.mkdtemp(prefix="profile-share-")
    shares = [float(s) for s in a.grid.split(",")]
    grid = {f"{s:.2f}": {} for s in shares}
    for key in ("t18", "mavic"):
        peer = peer_airframes.AIRFRAMES[key]()
        etas, sd0, _, _ = priors.held_out_prior(rows, key)
        held = (etas[peer.name], sd0, priors.drag_prior(key)[0], priors.dl_slope(rows, key))
        sub = os.path.join(out, key)
        os.makedirs(sub, exist_ok=True)
        flights = peer_flights(peer, sub, pm)
        for s in shares:
            grid[f"{s:.2f}"][key] = peer_errors(a.bin, peer, flights, held, s, sub, pm)
            print(key, s, {k: v["median_abs_err_pct"] for k, v in grid[f"{s:.2f}"][key].items()}, file=sys.stderr)
    for s in shares:
        grid[f"{s:.2f}"]["m100"] = m100_errors(a.bin, s)
        print("m100", s, grid[f"{s:.2f}"]["m100"], file=sys.stderr)
    chosen = {}
    for held in AIRFRAMES:
        s, cost = choose(grid, [x for x in AIRFRAMES if x != held])
        chosen[held] = dict(profile_share=s, mean_fitting_hover_err_pct=round(cost, 2))
    s, cost = choose(grid, AIRFRAMES)
    res = dict(rule=__doc__.split("\n\n")[2].replace("\n", " "), grid=grid, held_out=chosen,
               shipped=dict(profile_share=s, mean_hover_err_pct=round(cost, 2)))
    text = json.dumps(res, indent=1)
    if a.json:
        with open(a.json, "w") as f:
            f.write(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
