#!/usr/bin/env python3
# Usage: lab/scripts/measure-plane.py RUN.jsonl TRUTH.csv [SKIP_S=60] [FLY_W=20] [--json]
#   RUN.jsonl: `dronewatt replay LOG --speed max --json RUN.jsonl` of a simulated flight;
#   TRUTH.csv: `dronewatt simulate … --truth TRUTH.csv` of the same flight.
"""Score a replay of a simulated plane or quadplane against the simulator's truth:
- forecast-power MAPE: the forecast model's adapted power (as `measure-adapt.py` takes it)
  against the truth's mean power over the same 1 s window, over the windows in flight from
  SKIP_S s after the take-off began to the landing, the motors running (truth over FLY_W W:
  a glide with the motor stopped draws only the avionics, and a percentage of that says
  nothing), as `measure-adapt.py` keeps the windows over its in-flight threshold; against
  the measured (noisy) power too;
- the same split by VTOL state (mc, transition_to_fw, fw, transition_to_mc) over the whole
  flight, and by model (the adapted `fixed_wing` alone);
- energy used over the whole log: dronewatt's last `energy_used_wh` against the truth's
  energy (10 Hz rectangles)."""
import csv, json, sys

args = [a for a in sys.argv[1:] if not a.startswith("--")]
run, truth_path = args[0], args[1]
skip = float(args[2]) if len(args) > 2 else 60.0
fly_w = float(args[3]) if len(args) > 3 else 20.0
est = [json.loads(l) for l in open(run)]
est = [e for e in est if e.get("type") == "estimate"]
truth = list(csv.DictReader(open(truth_path)))
tt = [float(r["t_s"]) for r in truth]
tp = [float(r["power_w"]) for r in truth]
airborne = ("Climb", "Leg", "Hold", "Descent")
t_fly = next(float(r["t_s"]) for r in truth if r["phase"].startswith(airborne))
t_end = max(float(r["t_s"]) for r in truth if r["phase"].startswith(airborne))


def truth_mean(t0, t1):
    v = [p for t, p in zip(tt, tp) if t0 < t <= t1]
    return sum(v) / len(v) if v else None


def forecast(e):
    m = e.get("forecast_model")
    if not m:
        return None
    src = e.get("adapted", {}) if e.get("forecast_adapted") else e.get("models", {})
    return src.get(m)


rows = []
for e in est:
    t = e["t"]
    if not (t_fly < t <= t_end):
        continue
    tr = truth_mean(t - 1.0, t)
    f = forecast(e)
    if tr is None or f is None or tr <= fly_w:
        continue
    rows.append((t, e.get("vtol_state") or "plane", f, tr, e.get("measured_w"), e.get("adapted", {}).get("fixed_wing"), e.get("models", {}).get("fixed_wing")))


def mape(pairs):
    pairs = [(a, b) for a, b in pairs if a is not None and b is not None and b > 0]
    return (100 * sum(abs(a - b) / b for a, b in pairs) / len(pairs), len(pairs)) if pairs else (float("nan"), 0)


after = [r for r in rows if r[0] >= t_fly + skip]
out = {}
out["forecast_mape_vs_truth_pct"], out["windows"] = mape([(r[2], r[3]) for r in after])
out["forecast_mape_vs_measured_pct"], _ = mape([(r[2], r[4]) for r in after])
out["measured_mape_vs_truth_pct"], _ = mape([(r[4], r[3]) for r in after])
out["fixed_wing_adapted_mape_vs_truth_pct"], out["fixed_wing_windows"] = mape([(r[5], r[3]) for r in after])
out["fixed_wing_raw_mape_vs_truth_pct"], _ = mape([(r[6], r[3]) for r in after])
by = {}
for state in sorted({r[1] for r in rows}):
    m, n = mape([(r[2], r[3]) for r in rows if r[1] == state])
    by[state] = {"mape_pct": m, "windows": n}
out["by_state_whole_flight"] = by
truth_wh = sum(tp) * 0.1 / 3600
used = [e["energy_used_wh"] for e in est if e.get("energy_used_wh") is not None]
out["truth_wh"] = truth_wh
out["dronewatt_wh"] = used[-1] if used else None
out["energy_error_pct"] = 100 * (used[-1] - truth_wh) / truth_wh if used else None
out["followed"] = sorted({e.get("forecast_model") or "measured" for e in est if t_fly < e["t"] <= t_end})
if "--json" in sys.argv:
    print(json.dumps(out))
else:
    print(f"{run}: {out['windows']} windows from {skip:.0f} s after take-off to landing")
    print(f"  forecast power MAPE vs truth {out['forecast_mape_vs_truth_pct']:.1f} % (vs measured {out['forecast_mape_vs_measured_pct']:.1f} %; measured vs truth {out['measured_mape_vs_truth_pct']:.1f} %); models followed: {', '.join(out['followed'])}")
    for s, v in by.items():
        print(f"  {s:<18} {v['mape_pct']:6.1f} % over {v['windows']} windows (whole flight)")
    print(f"  energy used {out['dronewatt_wh']:.3f} Wh vs truth {truth_wh:.3f} Wh: {out['energy_error_pct']:+.2f} %")
