#!/usr/bin/env python3
# Usage: lab/scripts/measure-adapt.py RUN.jsonl [IN_FLIGHT_W=100] [SKIP_S=60]  (a `dronewatt replay --json` file)
"""Score a dronewatt JSON-lines replay: per model (raw and adapted), power MAPE over the
in-flight windows after the first {skip:.0f} s in flight in flight, energy error over the same span, and
time to empty vs remaining energy / mean measured power over the next 60 s."""
import json, sys
est = [json.loads(l) for l in open(sys.argv[1])]
est = [e for e in est if e.get("type") == "estimate" and e.get("measured_w") is not None]
fly = float(sys.argv[2]) if len(sys.argv) > 2 else 100.0  # in-flight threshold, W
t_air = [e["t"] for e in est if e["measured_w"] > fly]
skip = float(sys.argv[3]) if len(sys.argv) > 3 else 60.0
t0 = t_air[0] + skip
rest = [e for e in est if e["t"] >= t0 and e["measured_w"] > fly]
def energy(vals, ts):
    return sum(0.5 * (vals[i] + vals[i-1]) * min(ts[i] - ts[i-1], 1.0) for i in range(1, len(ts))) / 3600
ts = [e["t"] for e in rest]; meas = [e["measured_w"] for e in rest]
print(f"{sys.argv[1]}: {len(rest)} in-flight windows after the first {skip:.0f} s in flight; measured {energy(meas, ts):.2f} Wh")
print(f"{'model':<20}{'MAPE % raw':>12}{'MAPE % adapted':>16}{'energy % raw':>14}{'energy % adapted':>18}")
for name in rest[0]["models"]:
    row = [name]
    for key in ("models", "adapted"):
        p = [e.get(key, {}).get(name) for e in rest]
        if any(v is None for v in p):
            row += [float("nan"), float("nan")]; continue
        mape = 100 * sum(abs(a - m) / m for a, m in zip(p, meas)) / len(p)
        err = 100 * (energy(p, ts) - energy(meas, ts)) / energy(meas, ts)
        row += [mape, err]
    print(f"{row[0]:<20}{row[1]:>12.1f}{row[3]:>16.1f}{row[2]:>14.1f}{row[4]:>18.1f}")
# The forecast: the model the forecast followed at each line (its adapted value where adapted).
if all("forecast_model" in e for e in rest):
    p = [(e.get("adapted", {}) if e["forecast_adapted"] else e["models"]).get(e["forecast_model"]) if e["forecast_model"] else m for e, m in zip(rest, meas)]
    if all(v is not None for v in p):
        mape = 100 * sum(abs(a - m) / m for a, m in zip(p, meas)) / len(p)
        err = 100 * (energy(p, ts) - energy(meas, ts)) / energy(meas, ts)
        used = sorted({e["forecast_model"] or "measured" for e in rest})
        print(f"{'forecast (followed)':<20}{'':>12}{mape:>16.1f}{'':>14}{err:>18.1f}   models followed: {', '.join(used)}")
# time to empty vs remaining / mean measured power over the next 60 s
errs = []
for i, e in enumerate(est):
    if e["t"] < t0 or e["measured_w"] <= fly or e.get("time_to_empty_s") is None:
        continue
    nxt = [x["measured_w"] for x in est[i:] if x["t"] < e["t"] + 60.0]
    if est[-1]["t"] < e["t"] + 60.0:
        break
    ref = 3600 * e["remaining_wh"] / (sum(nxt) / len(nxt))
    errs.append(abs(e["time_to_empty_s"] - ref) / ref)
errs.sort()
if errs:
    print(f"time to empty vs remaining/next-60-s power: median {100*errs[len(errs)//2]:.1f} %, 90th pct {100*errs[int(len(errs)*0.9)]:.1f} %, within 15 %: {100*sum(e <= 0.15 for e in errs)/len(errs):.0f} % of {len(errs)} windows")
last = est[-1]
print(f"capacity {last['capacity_wh']:.1f} Wh ({last['capacity_source']}), cells {last['cell_count']} ({last['cell_count_source']}), forecast adapted: {last['forecast_adapted']}")
