#!/usr/bin/env python3
"""The M100 held out as an airframe: its data set's test flights flown through `dronewatt
replay` with a spec sheet of its five facts as the vehicle, the hover-efficiency prior
fitted without the M100 (scripts/spec-priors.py's `held_out_prior`, passed as `[priors]`).

For each test flight (src/offline/data.rs TEST_FLIGHTS), or with `--flights train` each route
flight of the training set with a payload of 0, 250 or 500 g (what a choice may look at): the
spec sheet's take-off mass is the vehicle's, 2.431 kg, and the flight's payload is the
mission's (the data set's `payload` column, which `replay` sends as the mission's payload and
the members add to the take-off mass, as a user's mission config would). Before session 26 the
take-off mass was written as 2.431 kg plus the payload, and the payload was counted twice.

- `spec`: the energy the momentum-theory member gives along the flight's own path (its
  estimates' `models.stolaroff` power × the time to the next estimate, airborne: from the
  first to the last estimate whose measured power is above 150 W), against the measured V·I
  over the same estimates; the P90 is that energy × the spec sheet's P90 ratio;
- `hover`: the same with the first hover's efficiency: the route flights climb and go (no
  hover of 15 s: the live calibration says so and calibrates nothing), so the hover is the
  vehicle's earlier one, the data set's hover flights (route H, no payload:
  scripts/spec-priors.py's `m100_hover_w`), as the vehicle store would keep it: η_h =
  ideal / (P_hover − 8 W) at 2.431 kg (the hover's mass), and the member's power (at the
  flight's mass, payload included) × η_prior/η_h on its non-avionics part.

The flight's own path, not a plan: the M100's error here is the power model's alone, where
the peer's is the plan's (path, speeds, wind) as well. The M100's learned stage is the
book's own (the shipped M100 profile, `plan-eval`).

    .venv-py/bin/python scripts/spec-m100.py [--bin target/debug/dronewatt] [--json PATH] [--plot PNG] [--flights train]
"""
import argparse
import importlib
import json
import math
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
DATA = os.path.join(HERE, "..", "..", "shared", "data", "m100", "flights.csv.gz")
TEST_FLIGHTS = [268, 269, 270, 271, 272, 273, 276, 277, 278, 279]
TAKEOFF_KG = 2.431  # the M100 with its TB48D (DJI), as config/vehicles/m100.toml
AIRBORNE_W = 150.0
AVIONICS_W = 8.0
SPEC = """name = "DJI M100 (spec sheet)"
[vehicle]
takeoff_kg = {kg:.3f}
rotors = 4
prop_diameter_m = 0.3302
[battery]
cells = 6
capacity_mah = 5700
chemistry = "lipo"
[priors]
eta_h = {eta:.4f}
eta_h_log_sd = {sd:.4f}
drag_per_kg23 = {drag:.5f}
eta_h_per_ln_dl = {slope:.4f}
profile_share = {share:.3f}
"""


def payloads(which="test"):
    """{flight: payload kg}: the test flights, or the training set's route flights with a
    payload of 0, 250 or 500 g."""
    import csv
    import gzip
    out = {}
    with gzip.open(DATA, "rt") as f:
        for r in csv.DictReader(f):
            k = int(r["flight"])
            if k in out:
                continue
            pay = float(r["payload"])
            if which == "test" and k in TEST_FLIGHTS:
                out[k] = pay / 1000.0
            elif (which == "train" and k not in TEST_FLIGHTS and r["route"].startswith("R")
                  and pay in (0.0, 250.0, 500.0)):
                out[k] = pay / 1000.0
    return out


def score(binary, flight, spec, p90_ratio, eta_prior, eta_hover):
    r = subprocess.run([binary, "replay", DATA, "--flight", str(flight), "--speed", "max", "-q", "--json", "-",
                        "--vehicle", spec, "--data-dir", "off"], capture_output=True, text=True, check=True)
    est = [json.loads(line) for line in r.stdout.splitlines() if line.startswith("{")]
    est = [e for e in est if e.get("type") == "estimate" and e.get("models", {}).get("stolaroff") is not None]
    air = [i for i, e in enumerate(est) if (e.get("measured_w") or 0) > AIRBORNE_W]
    if not air:
        return None
    est = est[air[0]:air[-1] + 1]
    cal = next((e["hover_calibration"] for e in est if e.get("hover_calibration")), None)
    if cal:
        print(f"flight {flight}: a live hover calibration ({cal}): not expected on a route flight", file=sys.stderr)
    model = measured = model_cal = 0.0
    for a, b in zip(est, est[1:]):
        dt = b["t"] - a["t"]
        if not 0 < dt < 5 or a.get("measured_w") is None:
            continue
        p = a["models"]["stolaroff"]
        measured += a["measured_w"] * dt
        if cal and cal.get("applied") and a["t"] >= cal["t_s"]:
            # after the calibration the estimate's member is already the calibrated one:
            # undo it for the spec column
            p = cal["avionics_w"] + (p - cal["avionics_w"]) * cal["eta_h"] / cal["prior_eta_h"]
        model += p * dt
        model_cal += (AVIONICS_W + (p - AVIONICS_W) * eta_prior / eta_hover) * dt
    truth = measured / 3600
    spec_wh = model / 3600
    row = dict(flight=flight, truth_wh=round(truth, 2), spec_wh=round(spec_wh, 2),
               spec_err_pct=round(100 * (spec_wh / truth - 1), 1), p90_covers=bool(spec_wh * p90_ratio >= truth),
               live_calibration=bool(cal))
    row["hover"] = dict(eta_h=round(eta_hover, 4), wh=round(model_cal / 3600, 2),
                        err_pct=round(100 * (model_cal / 3600 / truth - 1), 1))
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bin", default=os.path.join(HERE, "..", "target", "debug", "dronewatt"))
    ap.add_argument("--json")
    ap.add_argument("--flights", choices=("test", "train"), default="test",
                    help="the test flights (the book's table), or the training set's route flights (for choices)")
    ap.add_argument("--drag-area", type=float,
                    help="a check: the spec sheet's [stolaroff] drag_area_m2 instead of the drag prior")
    ap.add_argument("--profile-share", type=float,
                    help="the spec sheet's [priors] profile_share instead of the one fitted without the M100 "
                         "(scripts/profile-share-fit.py's grid)")
    ap.add_argument("--every", type=int, default=1, help="a check: every Nth flight only")
    ap.add_argument("--plot", help="draw each flight's measured energy, the spec sheet's P50 and P90 and the after-hover P50 here")
    a = ap.parse_args()
    priors = importlib.import_module("spec-priors")
    rows = priors.airframes()
    etas, sd, form, inner = priors.held_out_prior(rows, "m100")
    eta = etas["DJI M100 (published)"]
    drag, _ = priors.drag_prior("m100")
    slope = priors.dl_slope(rows, "m100")
    share = a.profile_share if a.profile_share is not None else priors.profile_share_prior("m100")
    p90_ratio = math.exp(1.2816 * math.sqrt(sd ** 2 + (0.25 * 0.5) ** 2))
    hover_w, _ = priors.m100_hover_w()
    eta_hover = priors.ideal_hover_w(TAKEOFF_KG, 4, 0.3302) / (hover_w - AVIONICS_W)
    out = tempfile.mkdtemp(prefix="spec-m100-")
    flights = []
    spec = os.path.join(out, "m100.toml")
    with open(spec, "w") as f:
        f.write(SPEC.format(kg=TAKEOFF_KG, eta=eta, sd=sd, drag=drag, slope=slope, share=share))
        if a.drag_area is not None:
            f.write(f"[stolaroff]\ndrag_area_m2 = {a.drag_area}\n")
    for k, payload in sorted(payloads(a.flights).items())[::max(a.every, 1)]:
        r = score(a.bin, k, spec, p90_ratio, eta, eta_hover)
        if r:
            r["payload_kg"] = payload
            flights.append(r)
            print(r, file=sys.stderr)
    errs = sorted(abs(r["spec_err_pct"]) for r in flights)
    hov = sorted(abs(r["hover"]["err_pct"]) for r in flights if r["hover"])
    med = lambda v: v[len(v) // 2] if len(v) % 2 else (v[len(v) // 2 - 1] + v[len(v) // 2]) / 2
    res = dict(hover=dict(hover_w=round(hover_w, 1), eta_h=round(eta_hover, 4)), prior_held_out=dict(
        eta_h=round(eta, 4), log_sd=round(sd, 4), form=form, inner_err=inner, drag_per_kg23=round(drag, 4),
        eta_h_per_ln_dl=round(slope, 4), profile_share=round(share, 3)),
               p90_ratio=round(p90_ratio, 3), flights=flights,
               summary=dict(spec=dict(median_abs_err_pct=round(med(errs), 1), flights=len(errs),
                                      p90_cover_pct=round(100 * sum(r["p90_covers"] for r in flights) / len(flights), 1)),
                            hover=dict(median_abs_err_pct=round(med(hov), 1), flights=len(hov)) if hov else None),
               by_payload={f"{int(1000 * p)} g": dict(
                   flights=len(rs), spec_median_err_pct=round(med(sorted(r["spec_err_pct"] for r in rs)), 1),
                   hover_median_err_pct=round(med(sorted(r["hover"]["err_pct"] for r in rs)), 1))
                   for p in sorted({r["payload_kg"] for r in flights})
                   for rs in [[r for r in flights if r["payload_kg"] == p]]},
               flights_set=a.flights)
    text = json.dumps(res, indent=1)
    if a.plot:
        plot(res, a.plot)
    if a.json:
        with open(a.json, "w") as f:
            f.write(text)
    print(text)


def plot(res, path):
    """Each flight: the measured energy, the spec sheet's P50 (its P90 a tick) and the P50
    after the hover, the M100 held out."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fl = res["flights"]
    fig, ax = plt.subplots(figsize=(10, 3.6))
    for k, r in enumerate(fl):
        ax.bar(k - 0.2, r["spec_wh"], 0.4, color="tab:orange", label="spec P50" if k == 0 else None)
        ax.bar(k + 0.2, r["hover"]["wh"], 0.4, color="tab:blue", label="after the hover P50" if k == 0 else None)
        ax.plot([k - 0.38, k - 0.02], [r["spec_wh"] * res["p90_ratio"]] * 2, color="k",
                label="spec P90" if k == 0 else None)
        ax.plot(k, r["truth_wh"], "r*", markersize=12, label="measured" if k == 0 else None)
    ax.set_xticks(range(len(fl)), [f"flight {r['flight']}\n{int(1000 * r['payload_kg'])} g" for r in fl], fontsize=8)
    ax.set_ylabel("energy along its path, Wh")
    ax.set_title("DJI M100 (data set) held out: spec sheet and after the hover, each test flight")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
