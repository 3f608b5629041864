#!/usr/bin/env python3
"""Score the spec-sheet forecast against an independent electrical peer: the `multirotor`
package's Tarot T18 (PyPI multirotor 0.5.0, models/tarott18.py) and a DJI Mavic Pro built
with its classes (its models/djimavicpro.py is empty: scripts/peer_airframes.py says from what).

What is the package's and what is this harness's (be exact about it):
- The package's: the T18's mass, rotor count, propeller thrust and torque constants
  (k_thrust, k_drag) and its motor (winding resistance, back-EMF and torque constants, as
  tarott18.py defines MP; its propellers ship with motor=None, so the harness attaches MP,
  which that file leaves commented out). Each motor's current comes from the package's own
  `Motor.step` (I = (V - k_e·ω)/R) and the pack current from its duty-cycle average.
- The harness's: the flight path. The package ships no tuned controller gains (its cascaded
  PID's `make_for` gives P-only unit gains meant for its optuna tuner), so the harness flies
  the plan as a point mass with the kinematics of a waypoint mission (climb, a 30 s hover,
  trapezoidal legs, stops, descent), in wind with gusts, and asks the package's motors for
  the thrust that path needs (weight, acceleration and a body drag of C_D·A = 0.20 m², the
  harness's ASSUMPTION: the package models no body drag). The package's propellers give
  thrust k·ω² whatever the airspeed (no translational lift), so forward flight costs the
  peer what hover costs at the same thrust.
- The pack: the T18's 6S LiPo 22 000 mAh (25 mΩ), the Mavic's 3S 3830 mAh (30 mΩ), a LiPo
  resting-voltage curve; the telemetry's
  current is the package's power over this pack's loaded voltage, as ArduPilot's
  SYS_STATUS / BATTERY_STATUS report it, written to a pymavlink .tlog at 10 Hz after the
  parameters a ground station fetches (BATT_CAPACITY, FRAME_CLASS, MOT_BAT_VOLT_MAX/MIN).

Stages scored, each airframe held out:
- `spec`: the five facts; the hover-efficiency prior fitted on the other airframes
  (scripts/spec-priors.py's `held_out_prior`: the form and the fit chosen without the
  airframe's group, passed as `[priors]`).
- `hover`: `plan --hover-w W` on the same spec, W the first 30 s hover the .tlog shows (mean
  V·I there): the efficiency becomes ideal power / (W − 8 W avionics).
- `learned`: `dronewatt learn` on the first four flights' .tlog (it trains on three, holds
  one out and picks the forecast model), the later flights planned with its profile.

    .venv-py/bin/python scripts/peer-multirotor.py --bin target/debug/dronewatt [--quick] \
        [--airframe t18,mavic] [--json out.json] [--markdown] [--plot energy.png] [--out DIR]
"""
import argparse
import copy
import json
import math
import os
import struct
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
RHO, G = 1.225, 9.81
R_PACK = {"t18": 0.025, "mavic": 0.030}
LIPO = [(0.0, 3.27), (0.05, 3.61), (0.1, 3.69), (0.2, 3.73), (0.3, 3.77), (0.4, 3.80),
        (0.5, 3.84), (0.6, 3.87), (0.7, 3.95), (0.8, 4.02), (0.9, 4.11), (1.0, 4.20)]
HOME = (47.397742, 8.545594)
DT = 0.1
HOVER_S = 30.0
ALT = 30.0
SPEC = """name = "{name}"
[vehicle]
takeoff_kg = {kg}
rotors = {n}
prop_diameter_m = {d}
[battery]
cells = {cells}
capacity_mah = {mah:.0f}
chemistry = "{chem}"
"""


def profile(legs_m, speed, alt=ALT):
    """The path as (pos ENU, vel, acc, mission item flown to) at DT: climb, hover, legs stop
    to stop, descent (the items as `mission_items` numbers them)."""
    out = []
    pos = np.zeros(3)
    seq = [1]

    def emit(p, v, a, secs):
        for _ in range(int(round(secs / DT))):
            out.append((p.copy(), v.copy(), a.copy(), seq[0]))

    z = 0.0
    while z < alt:
        z = min(alt, z + 3.0 * DT)
        emit(np.array([0, 0, z]), np.array([0, 0, 3.0]), np.zeros(3), DT)
    pos[2] = alt
    seq[0] = 2
    emit(pos, np.zeros(3), np.zeros(3), HOVER_S)
    acc = 2.5
    for li, (dx, dy) in enumerate(legs_m):
        seq[0] = 4 + li
        d = math.hypot(dx, dy)
        u = np.array([dx / d, dy / d, 0.0])
        vtop = min(speed, math.sqrt(acc * d))
        ta = vtop / acc
        tc = (d - vtop * ta) / vtop
        start = pos.copy()
        t = 0.0
        total = 2 * ta + tc
        while t < total:
            if t < ta:
                s, v, a = 0.5 * acc * t * t, acc * t, acc
            elif t < ta + tc:
                s, v, a = 0.5 * acc * ta * ta + vtop * (t - ta), vtop, 0.0
            else:
                r = total - t
                s, v, a = d - 0.5 * acc * r * r, acc * r, -acc
            emit(start + s * u, v * u, a * u, DT)
            t += DT
        pos = start + d * u
        emit(pos, np.zeros(3), np.zeros(3), 2.0)
    seq[0] = 4 + len(legs_m)
    while pos[2] > 0:
        vz = 2.7 if pos[2] > 20 else 1.0
        pos = pos.copy()
        pos[2] = max(0.0, pos[2] - vz * DT)
        emit(pos, np.array([0, 0, -vz]), np.zeros(3), DT)
    return out


def ocv(soc):
    soc = min(max(soc, 0.0), 1.0)
    for (s0, v0), (s1, v1) in zip(LIPO, LIPO[1:]):
        if soc <= s1:
            return v0 + (v1 - v0) * (soc - s0) / (s1 - s0)
    return LIPO[-1][1]


def fly(peer, path, wind_speed, wind_from_deg, seed, tlog_path, items=()):
    CELLS, MAH, R = peer.cells, peer.mah, R_PACK[peer.key]
    """Fly the path in wind; write the .tlog as ArduPilot would; return the truth, Wh."""
    from pymavlink.dialects.v20 import ardupilotmega as mavlink
    rng = np.random.default_rng(seed)
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    to = math.radians(wind_from_deg + 180.0)
    mean_w = wind_speed * np.array([math.sin(to), math.cos(to), 0.0])
    gust = np.zeros(3)
    soc, energy_j, t_us = 1.0, 0.0, 1_700_000_000_000_000
    lat0, lon0 = HOME
    with open(tlog_path, "wb") as f:
        def put(msg):
            f.write(struct.pack(">Q", t_us) + msg.pack(mav))
        # the parameters a ground station fetches on connecting (ArduPilot's names and types)
        params = [("BATT_CAPACITY", MAH, 6), ("FRAME_CLASS", 3 if peer.n == 8 else 1, 2), ("MOT_BAT_VOLT_MAX", 4.2 * CELLS, 9),
                  ("MOT_BAT_VOLT_MIN", 3.3 * CELLS, 9)]
        for k, (p, v, a, seq) in enumerate(path):
            gust += -gust * DT / 3.0 + rng.normal(0, 1.0, 3) * math.sqrt(2 * DT / 3.0) * (0.2 * wind_speed)
            gust[2] = 0.0
            air = v - (mean_w + gust)
            drag = -0.5 * RHO * peer.cda * np.linalg.norm(air) * air
            thrust = peer.mass * (a + np.array([0, 0, G])) - drag
            airborne = p[2] > 0.05 or k == 0
            pw = peer.power_w(np.linalg.norm(thrust)) + 8.0 if airborne else 8.0
            v_oc = CELLS * ocv(soc)
            amps = (v_oc - math.sqrt(max(v_oc * v_oc - 4 * R * pw, 0.0))) / (2 * R)
            volts = v_oc - amps * R
            soc -= amps * DT / 3600.0 / (MAH / 1000.0)
            energy_j += volts * amps * DT
            n = thrust / np.linalg.norm(thrust)
            lat = lat0 + p[1] / 111_320.0
            lon = lon0 + p[0] / (111_320.0 * math.cos(math.radians(lat0)))
            if k % 10 == 0:
                # MAV_TYPE by the rotor count (QUADROTOR 2, HEXAROTOR 13, OCTOROTOR 14): until
                # 2026-11-29 every airframe said OCTOROTOR, the Mavic too
                put(mavlink.MAVLink_heartbeat_message({4: 2, 6: 13, 8: 14}.get(peer.n, 14), 3,
                                                      81 if airborne else 1, 3, 4, 3))
            if k == 10:  # after the vehicle is heard
                for i, (pid, val, typ) in enumerate(params):
                    put(mavlink.MAVLink_param_value_message(pid.encode(), float(val), typ, len(params), i))
                # the mission, as a ground station logs its download (ArduPilot's home item 0)
                if items:
                    put(mavlink.MAVLink_mission_count_message(255, 190, len(items), 0))
                    for (sq, frame, cmd, p1, p2, p3, p4, la, lo, al) in items:
                        put(mavlink.MAVLink_mission_item_int_message(255, 190, sq, frame, cmd, 0, 1, p1, p2, p3, p4,
                                                                     int(round(la * 1e7)), int(round(lo * 1e7)), al, 0))
            if items and k % 10 == 0 and k > 10:
                put(mavlink.MAVLink_mission_current_message(seq, len(items) - 1))
            put(mavlink.MAVLink_sys_status_message(0, 0, 0, 500, int(volts * 1000), int(amps * 100),
                                                   int(soc * 100), 0, 0, 0, 0, 0, 0))
            put(mavlink.MAVLink_battery_status_message(0, 1, 1, 3200, [int(volts * 1000 / CELLS)] * CELLS + [65535] * (10 - CELLS),
                                                       int(amps * 100), int((1 - soc) * MAH), -1, int(soc * 100)))
            put(mavlink.MAVLink_global_position_int_message(k * 100, int(lat * 1e7), int(lon * 1e7),
                                                            int((488 + p[2]) * 1000), int(p[2] * 1000),
                                                            int(v[1] * 100), int(v[0] * 100), int(-v[2] * 100), 0))
            # yaw 0 (body x north): thrust tilted north is nose down, east is right wing down
            put(mavlink.MAVLink_attitude_message(k * 100, math.atan2(n[0], n[2]), -math.atan2(n[1], n[2]),
                                                 0.0, 0.0, 0.0, 0.0))
            t_us += int(DT * 1e6)
    return energy_j / 3600.0


def read_tlog(path):
    """(t s, V, A, relative alt m) from the .tlog's SYS_STATUS and GLOBAL_POSITION_INT."""
    from pymavlink import mavutil
    m = mavutil.mavlink_connection(path)
    rows, alt = [], 0.0
    while True:
        msg = m.recv_match(type=["SYS_STATUS", "GLOBAL_POSITION_INT"])
        if msg is None:
            break
        if msg.get_type() == "GLOBAL_POSITION_INT":
            alt = msg.relative_alt / 1000.0
        else:
            rows.append((msg._timestamp, msg.voltage_battery / 1000.0, msg.current_battery / 100.0, alt))
    return rows


def first_hover_w(rows):
    """Mean V·I over the first 30 s at hover height (still, above 90 % of the climb)."""
    t0 = next((t for t, _, _, a in rows if a >= 0.9 * ALT), None)
    if t0 is None:
        return None
    p = [v * i for t, v, i, a in rows if t0 + 2 <= t <= t0 + HOVER_S - 2]
    return sum(p) / len(p) if p else None


def mission_items(legs_m, speed):
    """(seq, frame, command, p1..p4, lat, lon, alt): home, take-off, the 30 s hover, the
    speed, the waypoints, land."""
    lat0, lon0 = HOME
    items = [(0, 0, 16, 0, 0, 0, 0, lat0, lon0, 488.0), (1, 3, 22, 0, 0, 0, 0, lat0, lon0, ALT),
             (2, 3, 19, HOVER_S, 0, 0, 0, lat0, lon0, ALT), (3, 3, 178, 1, speed, -1, 0, 0.0, 0.0, 0.0)]
    x = y = 0.0
    lat, lon = lat0, lon0
    for dx, dy in legs_m:
        x, y = x + dx, y + dy
        lat = lat0 + y / 111_320.0
        lon = lon0 + x / (111_320.0 * math.cos(math.radians(lat0)))
        items.append((len(items), 3, 16, 0, 0, 0, 0, lat, lon, ALT))
    items.append((len(items), 3, 21, 0, 0, 0, 0, lat, lon, 0.0))
    return items


def waypoints(path_file, legs_m, speed):
    lines = ["QGC WPL 110"]
    for (sq, frame, cmd, p1, p2, p3, p4, la, lo, al) in mission_items(legs_m, speed):
        lines.append(f"{sq}\t{int(sq == 0)}\t{frame}\t{cmd}\t{p1}\t{p2}\t{p3}\t{p4}\t{la:.7f}\t{lo:.7f}\t{al}\t1")
    with open(path_file, "w") as f:
        f.write("\n".join(lines) + "\n")


def forecast(binary, plan, spec, speed, wind, extra=()):
    cmd = [binary, "plan", plan, "--vehicle", spec, "--speed", str(speed), "--json", "-", *extra]
    if wind[0] > 0:
        cmd += ["--wind", f"{wind[0]}@{wind[1]}"]
    out = subprocess.run(cmd, capture_output=True, text=True, check=True)
    j = json.loads(out.stdout)
    return j["forecast"]["energy_p50_wh"], j["forecast"]["energy_p90_wh"]


FLIGHTS = [  # name, legs (m, ENU), speed m/s, wind (m/s, from deg)
    ("square 400 m", [(400, 0), (0, 400), (-400, 0), (0, -400)], 8, (0, 0)),
    ("square 400 m", [(400, 0), (0, 400), (-400, 0), (0, -400)], 12, (5, 270)),
    ("out-back 1 km", [(1000, 0), (-1000, 0)], 10, (8, 90)),
    ("out-back 1 km", [(0, 1000), (0, -1000)], 5, (3, 0)),
    ("zigzag 1.2 km", [(300, 200), (300, -200), (300, 200), (-900, -200)], 10, (6, 200)),
    ("triangle 900 m", [(300, 0), (-150, 260), (-150, -260)], 9, (4, 45)),
    ("out-back 600 m", [(0, 600), (0, -600)], 11, (7, 180)),
    ("square 250 m", [(250, 0), (0, 250), (-250, 0), (0, -250)], 6, (2, 315)),
    ("long leg 1.6 km", [(1600, 0), (-1600, 0)], 12, (5, 120)),
    ("short hop", [(150, 0), (-150, 0)], 6, (0, 0)),
]
FLIGHTS_BY_INDEX = []  # the flights flown, by their index here
LEARN_ON = 4  # `learn` on the first four flights' .tlog (it holds out one of them itself)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bin", default=os.path.join(HERE, "..", "target", "debug", "dronewatt"))
    ap.add_argument("--quick", action="store_true", help="one short flight per airframe (the make-test check)")
    ap.add_argument("--airframe", default="t18,mavic", help="the airframes to fly, comma separated (t18, mavic)")
    ap.add_argument("--json")
    ap.add_argument("--markdown", action="store_true")
    ap.add_argument("--plot")
    ap.add_argument("--out", help="keep the .tlog, plans and specs here")
    a = ap.parse_args()
    import importlib
    import peer_airframes
    priors = importlib.import_module("spec-priors")
    rows = priors.airframes()
    out = a.out or tempfile.mkdtemp(prefix="peer-multirotor-")
    res = dict(peer="multirotor 0.5.0", airframes={})
    for key in a.airframe.split(","):
        peer = peer_airframes.AIRFRAMES[key]()
        etas, sd0, form, inner = priors.held_out_prior(rows, key)
        eta0 = etas[peer.name]
        drag0, _ = priors.drag_prior(key)
        slope0 = priors.dl_slope(rows, key)
        share0 = priors.profile_share_prior(key)
        sub = os.path.join(out, key)
        os.makedirs(sub, exist_ok=True)
        r = fly_airframe(a, peer, (eta0, sd0, drag0, slope0, share0), priors, sub)
        r.update(airframe=peer.name, prior_held_out=dict(eta_h=round(eta0, 4), log_sd=round(sd0, 4), form=form,
                                                         inner_err=inner, drag_per_kg23=round(drag0, 4),
                                                         eta_h_per_ln_dl=round(slope0, 4),
                                                         profile_share=round(share0, 3)),
                 figure_of_merit=round(peer.figure_of_merit(), 3), motor_eff=round(peer.motor_efficiency(), 3),
                 body_cda_m2=peer.cda, body_cda_source=peer.cda_source)
        res["airframes"][key] = r
    if a.json:
        with open(a.json, "w") as f:
            json.dump(res, f, indent=1)
    if a.markdown:
        for key, r in res["airframes"].items():
            print(f"## {r['airframe']}")
            for st, v in r["summary"].items():
                print(f"- {st}: {v}")
    else:
        print(json.dumps(res, indent=1))
    if a.plot:
        plot(res, a.plot)


def fly_airframe(a, peer, held_out, priors, out):
    """Fly the plans with one airframe; score each stage; the flights and their summary.
    `held_out`: the η_h prior, its log-sd, the drag per kg^(2/3) and η_h's slope in the disk
    loading, each fitted without it."""
    eta0, sd0, drag0, slope0, share0 = held_out
    results = []
    flights = FLIGHTS[-1:] if a.quick else FLIGHTS
    FLIGHTS_BY_INDEX.clear()
    FLIGHTS_BY_INDEX.extend(flights)
    for i, (name, legs, speed, wind) in enumerate(flights):
        tlog = os.path.join(out, f"flight{i}.tlog")
        fly(peer, profile(legs, speed), wind[0], wind[1], i, tlog, mission_items(legs, speed))
        rows_t = read_tlog(tlog)
        measured = sum(v * c for _, v, c, _ in rows_t) * DT / 3600.0
        plan = os.path.join(out, f"flight{i}.waypoints")
        waypoints(plan, legs, speed)
        spec = os.path.join(out, f"flight{i}-spec.toml")
        facts = SPEC.format(name=peer.name, kg=peer.mass, n=peer.n, d=peer.prop_m, cells=peer.cells, mah=peer.mah,
                            chem=peer.chemistry)
        with open(spec, "w") as f:
            f.write(facts + f"[priors]\neta_h = {eta0:.4f}\neta_h_log_sd = {sd0:.4f}\ndrag_per_kg23 = {drag0:.5f}\n"
                    f"eta_h_per_ln_dl = {slope0:.4f}\nprofile_share = {share0:.3f}\n")
        p50, p90 = forecast(a.bin, plan, spec, speed, wind)
        stage = [dict(stage="spec", p50=p50, p90=p90)]
        hw = first_hover_w(rows_t)
        if hw is not None:
            h50, h90 = forecast(a.bin, plan, spec, speed, wind, ["--hover-w", f"{hw:.1f}"])
            eta = priors.ideal_hover_w(peer.mass, peer.n, peer.prop_m) / (hw - 8.0)
            stage.append(dict(stage="hover", p50=h50, p90=h90, hover_w=round(float(hw), 1), eta=round(float(eta), 4)))
        lv = live(a.bin, out, i, spec, rows_t)
        if lv is not None:
            stage.append(lv)
        for s in stage:
            if "p50" not in s:
                continue
            s["err_pct"] = round(100 * (s["p50"] / measured - 1), 1)
            s["p90_covers"] = bool(s["p90"] >= measured)
        results.append(dict(flight=name, speed=speed, wind=list(wind), truth_wh=round(float(measured), 2),
                            stages=stage))
    if not a.quick:
        learned(a.bin, out, flights, results)
    summary = {}
    for st in ("spec", "hover", "live", "learned"):
        errs = [s for r in results for s in r["stages"] if s["stage"] == st and "err_pct" in s]
        if errs:
            summary[st] = dict(median_abs_err_pct=round(float(np.median([abs(s["err_pct"]) for s in errs])), 1),
                               p90_cover_pct=round(100 * sum(s["p90_covers"] for s in errs) / len(errs), 1),
                               flights=len(errs))
    lv = [s for r in results for s in r["stages"] if s["stage"] == "live" and s.get("mission")]
    if lv:
        summary["live_mission"] = dict(
            before_median_abs_err_pct=round(float(np.median([abs(s["before_err_pct"]) for s in lv])), 1),
            after_median_abs_err_pct=round(float(np.median([abs(s["after_err_pct"]) for s in lv])), 1),
            flights=len(lv))
    mape = [s["adapted_mape_pct"] for r in results for s in r["stages"]
            if s["stage"] == "learned" and s.get("adapted_mape_pct") is not None]
    if mape:
        summary["learned_adapted_power"] = dict(median_mape_pct=round(float(np.median(mape)), 1), flights=len(mape))
    return dict(flights=results, summary=summary)


def live(binary, out, i, spec, rows):
    """`replay` of the flight's .tlog with the spec sheet, a store of its own: the live
    mission forecast (`mission_energy_wh`) just before the first hover calibrates and just
    after, each against what the peer's flight still drew from then on; then `plan --vehicle
    <the stored vehicle>` (the store keeps the calibrated profile)."""
    store = os.path.join(out, f"store{i}")
    tlog = os.path.join(out, f"flight{i}.tlog")
    r = subprocess.run([binary, "replay", tlog, "--speed", "max", "-q", "--json", "-", "--vehicle", spec,
                        "--data-dir", store], capture_output=True, text=True, check=True)
    est = [json.loads(line) for line in r.stdout.splitlines() if line.startswith("{")]
    est = [e for e in est if e.get("type") == "estimate"]
    cal = next((e for e in est if e.get("hover_calibration")), None)
    if cal is None:
        return dict(stage="live", calibrated=False)
    t0 = rows[0][0]
    energy = []  # (t since the log's start, Wh drawn by then)
    acc = 0.0
    for t, v, c, _ in rows:
        acc += v * c * DT / 3600.0
        energy.append((t - t0, acc))
    total = energy[-1][1]

    def left(t):
        return total - max((e for tt, e in energy if tt <= t), default=0.0)

    def err(e):
        truth = left(e["t"])
        return round(100 * (e["mission_energy_wh"] / truth - 1), 1), round(truth, 2)

    with_m = [e for e in est if e.get("mission_energy_wh") is not None]
    before = [e for e in with_m if e["t"] < cal["t"]]
    after = [e for e in with_m if e["t"] >= cal["t"]]
    if not before or not after:
        return dict(stage="live", calibrated=True, hover=cal["hover_calibration"], mission=False)
    b_err, b_truth = err(before[-1])
    a_err, a_truth = err(after[0])
    vehicles = json.loads(subprocess.run([binary, "vehicles", "--data-dir", store, "--json"], capture_output=True,
                                         text=True, check=True).stdout)
    key = vehicles[0]["key"]
    plan = os.path.join(out, f"flight{i}.waypoints")
    speed, wind = FLIGHTS_BY_INDEX[i][2], FLIGHTS_BY_INDEX[i][3]
    s50, s90 = forecast(binary, plan, key, speed, wind, ["--data-dir", store])
    return dict(stage="live", calibrated=True, hover=cal["hover_calibration"], mission=True,
                t_s=cal["t"], before_p50=before[-1]["mission_energy_wh"], before_err_pct=b_err, truth_left_before=b_truth,
                after_p50=after[0]["mission_energy_wh"], after_err_pct=a_err, truth_left_after=a_truth,
                stored_key=key, stored_profile=vehicles[0].get("profile"), p50=s50, p90=s90)


def learned(binary, out, flights, results):
    """`dronewatt learn` on the first LEARN_ON flights' .tlog from the spec sheet; the flights
    after them scored with the profile it wrote (the T18 held out as before)."""
    logs = [os.path.join(out, f"flight{i}.tlog") for i in range(LEARN_ON)]
    prof = os.path.join(out, "learned")
    subprocess.run([binary, "learn", *logs, "--vehicle", os.path.join(out, "flight0-spec.toml"),
                    "--out", prof, "--data-dir", "off"], capture_output=True, text=True, check=True)
    for i, (name, legs, speed, wind) in enumerate(flights):
        if i < LEARN_ON:
            continue
        plan = os.path.join(out, f"flight{i}.waypoints")
        p50, p90 = forecast(binary, plan, os.path.join(prof, "profile.toml"), speed, wind)
        truth = results[i]["truth_wh"]
        results[i]["stages"].append(dict(stage="learned", p50=p50, p90=p90,
                                         err_pct=round(100 * (p50 / truth - 1), 1), p90_covers=bool(p90 >= truth),
                                         adapted_mape_pct=adapted_mape(binary, out, i, os.path.join(prof, "profile.toml"))))


def adapted_mape(binary, out, i, profile_path):
    """`replay` of flight i with the learned profile: the forecast model's power as the live
    adaptation gives it (`adapted` in --json) against the measured power of the same
    estimate, airborne (measured above 30 % of the flight's median): the mean absolute
    percentage error."""
    tlog = os.path.join(out, f"flight{i}.tlog")
    r = subprocess.run([binary, "replay", tlog, "--speed", "max", "-q", "--json", "-", "--vehicle", profile_path,
                        "--data-dir", "off"], capture_output=True, text=True, check=True)
    est = [json.loads(line) for line in r.stdout.splitlines() if line.startswith("{")]
    pairs = [(e["adapted"].get(e.get("forecast_model") or ""), e.get("measured_w")) for e in est
             if e.get("type") == "estimate" and e.get("adapted")]
    pairs = [(a, m) for a, m in pairs if a is not None and m]
    if not pairs:
        return None
    med = float(np.median([m for _, m in pairs]))
    errs = [abs(a - m) / m for a, m in pairs if m > 0.3 * med]
    return round(100 * float(np.mean(errs)), 1) if errs else None


def plot(res, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    keys = list(res["airframes"])
    fig, axes = plt.subplots(len(keys), 1, figsize=(10, 4.2 * len(keys)), squeeze=False)
    for ax, key in zip(axes[:, 0], keys):
        r = res["airframes"][key]
        results = r["flights"]
        x = np.arange(len(results))
        truth = [q["truth_wh"] for q in results]
        for k, (st, col) in enumerate([("spec", "tab:orange"), ("hover", "tab:blue"), ("learned", "tab:green")]):
            s = [next((q for q in fl["stages"] if q["stage"] == st), None) for fl in results]
            p50 = [q["p50"] if q else np.nan for q in s]
            p90 = [q["p90"] if q else np.nan for q in s]
            ax.bar(x + (k - 1) * 0.27, p50, 0.27, color=col, label=f"{st} P50")
            ax.scatter(x + (k - 1) * 0.27, p90, marker="_", s=120, color="k")
        ax.scatter(x, truth, marker="*", s=120, color="red", zorder=3, label="peer's energy")
        ax.set_xticks(x, [f"{q['flight']}\n{q['speed']} m/s\nwind {q['wind'][0]} m/s" for q in results], fontsize=7)
        ax.set_ylabel("plan energy, Wh (— : P90)")
        ax.set_title(f"{r['airframe']}, held out: spec sheet, after the first hover, learned on 4 logs")
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
