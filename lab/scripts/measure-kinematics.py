#!/usr/bin/env python3
# Usage: lab/scripts/measure-kinematics.py [FLIGHTS_CSV(.gz)]   (default: $DRONEWATT_DATA or ../shared/data/m100/flights.csv.gz)
"""How the M100 flies a waypoint mission, measured phase by phase on the data set's R1
training flights (test flights excluded): the defaults of `[forecast.kinematics]`.

Each flight is cut at its events, from the motors' start (first row above 150 W) to their
stop (last row above 150 W): lift-off (height 0.4 m above the ground), the climb, the
first horizontal move (speed over 1 m/s), the stops between legs (speed under 1 m/s for
more than 0.5 s), the last move and the end. A flight counts when it shows the route's
three legs (two stops). A leg's distance is the straight line between the stops' positions.

The cut at 1 m/s moves the slow ends of every acceleration into the stops: with a
trapezoid at `a`, a measured leg lasts distance/speed + (v − 2)/a (not + v/a) and a measured
stop lasts the pause + 2/a, the stop after the climb the pause + 1/a. So `accel_m_s2` is
fitted by least squares to the legs' extra time over (v − 2) at every speed, and the pause is
the measured stop less 2/a. Standard library only; prints medians and the fitted defaults."""
import csv, gzip, math, os, statistics as st, sys
from collections import defaultdict

TEST = {268, 269, 270, 271, 272, 273, 276, 277, 278, 279}
path = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("DRONEWATT_DATA", "../shared/data/m100/flights.csv.gz")
opener = gzip.open if path.endswith(".gz") else open
flights = defaultdict(list)
with opener(path, "rt", newline="") as fh:
    for r in csv.DictReader(fh):
        if r["route"] == "R1" and int(r["flight"]) not in TEST:
            flights[int(r["flight"])].append(r)

M_PER_DEG = 111_320.0
spin, climb_s_per_m, settle, stops, over, tail = [], [], [], [], defaultdict(list), defaultdict(list)
used = 0
for f, rows in sorted(flights.items()):
    num = lambda k: [float(r[k]) for r in rows]
    t, v, i = num("time"), num("battery_voltage"), num("battery_current")
    p = [a * b for a, b in zip(v, i)]
    on = [k for k, x in enumerate(p) if x > 150.0]
    if not on:
        continue
    a, b = on[0], on[-1]
    z0 = float(rows[a]["position_z"])
    lat0, lon0 = float(rows[a]["position_y"]), float(rows[a]["position_x"])
    coslat = math.cos(math.radians(lat0))
    seg = []
    for k in range(a, b + 1):
        r = rows[k]
        seg.append((t[k] - t[a], float(r["position_z"]) - z0, math.hypot(float(r["velocity_x"]), float(r["velocity_y"])),
                    (float(r["position_x"]) - lon0) * M_PER_DEG * coslat, (float(r["position_y"]) - lat0) * M_PER_DEG))
    ts = [s[0] for s in seg]
    lift = next((s[0] for s in seg if s[1] > 0.4), None)
    moving = [s[2] > 1.0 for s in seg]
    if lift is None or not any(moving):
        continue
    first = moving.index(True)
    last = len(moving) - 1 - moving[::-1].index(True)
    # stops between the first and the last move
    runs, k = [], first
    while k < last:
        if not moving[k]:
            j = k
            while j < len(moving) and not moving[j]:
                j += 1
            if ts[j] - ts[k] > 0.5:
                runs.append((k, j))
            k = j
        else:
            k += 1
    if len(runs) != 2:
        continue  # not the route's three legs as planned (an extra stop, or one missed)
    used += 1
    alt = float(rows[0]["altitude"])
    speed = float(rows[0]["speed"])
    spin.append(lift)
    zc = st.median(s[1] for s in seg[len(seg) // 3: 2 * len(seg) // 3])
    top = next(s[0] for s in seg if s[1] > 0.9 * zc)
    climb_s_per_m.append((top - lift) / (0.9 * zc))
    settle.append(ts[first] - lift - alt * (top - lift) / (0.9 * zc))
    stops += [ts[j] - ts[k] for k, j in runs]
    bounds = [(first, runs[0][0]), (runs[0][1], runs[1][0]), (runs[1][1], last)]
    for s0, s1 in bounds:
        d = math.hypot(seg[s1][3] - seg[s0][3], seg[s1][4] - seg[s0][4])
        over[speed].append(ts[s1] - ts[s0] - d / speed)
    tail[alt].append(ts[-1] - ts[last])

print(f"{path}: {used} R1 training flights with the route's three legs (of {len(flights)})")
print(f"spin-up (motors on to lift-off)       spinup_s     {st.median(spin):5.2f} s")
print(f"climb                                 climb_m_s    {1 / st.median(climb_s_per_m):5.2f} m/s")
print(f"stop after the climb (at 3 m/s)                    {st.median(settle):5.2f} s")
print(f"stop between legs (under 1 m/s)                    {st.median(stops):5.2f} s")
for v in sorted(over):
    o = st.median(over[v])
    print(f"leg at {v:4.1f} m/s: distance/speed + {o:5.2f} s  (through the cut, a = (v - 2)/extra = {(v - 2) / o if o > 0 else float('inf'):5.2f})")
# the trapezoid seen through the 1 m/s cut: extra = (v - 2 u)/a, u = 1 m/s
U = 1.0
xs = [(v - 2 * U, st.median(o)) for v, o in over.items()]
a = sum(x * x for x, _ in xs) / sum(x * y for x, y in xs)
pause = st.median(stops) - 2 * U / a
print(f"fitted through the 1 m/s cut:         accel_m_s2   {a:5.2f} m/s² (legs: " + ", ".join(f"{v:.0f} m/s {(v - 2 * U) / a:.2f} s" for v in sorted(over)) + ")")
print(f"                                      waypoint_pause_s {pause:5.2f} s (stop {st.median(stops):.2f} s less 2/a; after the climb {st.median(settle) - U / a:.2f} s)")
for h in sorted(tail):
    print(f"last stop and descent from {h:5.0f} m: {st.median(tail[h]):5.1f} s")
# the tail is the last slow end (1/a), the pause, the descent to 20 m and 20 m at 1 m/s (land_m_s)
ys = [(h - 20.0, st.median(tl) - U / a - pause - 20.0) for h, tl in tail.items() if h > 20.0]
print(f"descent above 20 m, least squares:    descent_m_s  {sum(x * x for x, _ in ys) / sum(x * y for x, y in ys):5.2f} m/s")
