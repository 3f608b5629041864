#!/usr/bin/env python3
"""Independent peer for the simulator's .tlog: decode it with pymavlink (not rust-mavlink),
count message types, check every field against its MAVLink unit and a physical range, and
print one JSON line of counts and power statistics for the Rust test to assert on.

Usage: sim_check.py FILE.tlog   (exit 1 with a message on the first violation)
"""
import json
import math
import os
import statistics
import sys

from pymavlink import mavutil


def fail(msg):
    print(f"sim_check: {msg}", file=sys.stderr)
    sys.exit(1)


def main():
    if len(sys.argv) != 2:
        fail("usage: sim_check.py FILE.tlog")
    path = sys.argv[1]
    if not path.endswith(".tlog") or not os.path.isfile(path):
        # pymavlink would take any other name for a serial port.
        fail(f"{path}: not an existing .tlog file")
    mlog = mavutil.mavlink_connection(path, dialect="ardupilotmega", robust_parsing=False)
    counts = {}
    bad = 0
    last_t = 0.0
    first_t = None
    volt = amp = None
    rel_alt = gs = 0.0
    hover_p, cruise_p, all_p = [], [], []
    home_seen_t = None
    armed_t = None
    while True:
        m = mlog.recv_match()
        if m is None:
            break
        t = m._timestamp
        typ = m.get_type()
        if typ == "BAD_DATA":
            bad += 1
            continue
        if first_t is None:
            first_t = t
        if t + 1e-9 < last_t:
            fail(f"timestamps go backwards at {t}")
        last_t = t
        counts[typ] = counts.get(typ, 0) + 1
        if typ == "HEARTBEAT":
            if m.type != 2:
                fail(f"HEARTBEAT type {m.type} is not a quadrotor")
            if m.base_mode & 128 and armed_t is None:
                armed_t = t
        elif typ == "HOME_POSITION":
            if home_seen_t is None:
                home_seen_t = t
            if not (40.4 < m.latitude / 1e7 < 40.5 and -79.9 < m.longitude / 1e7 < -79.7):
                fail(f"HOME_POSITION off site: {m.latitude} {m.longitude}")
        elif typ == "SYS_STATUS":
            volt, amp = m.voltage_battery / 1000.0, m.current_battery / 100.0
            if not 18.0 < volt < 26.2:
                fail(f"SYS_STATUS voltage {volt} V outside a 6S pack's range")
            if not -1.0 < amp < 60.0:
                fail(f"SYS_STATUS current {amp} A out of range")
            p = volt * amp
            all_p.append(p)
            if rel_alt > 20.0 and gs < 0.5:
                hover_p.append(p)
            elif rel_alt > 20.0 and gs > 8.0:
                cruise_p.append(p)
        elif typ == "BATTERY_STATUS":
            if m.voltages[0] == 65535 or any(v != 65535 for v in m.voltages[1:]):
                fail("BATTERY_STATUS voltages: total in cell 0, the rest UINT16_MAX expected")
        elif typ == "GLOBAL_POSITION_INT":
            lat, lon = m.lat / 1e7, m.lon / 1e7
            if not (40.4 < lat < 40.5 and -79.9 < lon < -79.7):
                fail(f"GLOBAL_POSITION_INT off site: {lat} {lon}")
            if not 200.0 < m.alt / 1000.0 < 800.0:
                fail(f"altitude {m.alt} mm is not metres above sea level near the site")
            rel_alt = m.relative_alt / 1000.0
            gs = math.hypot(m.vx, m.vy) / 100.0
            if gs > 25.0:
                fail(f"ground speed {gs} m/s")
        elif typ == "ATTITUDE":
            if abs(m.roll) > 0.8 or abs(m.pitch) > 0.8:
                fail(f"tilt roll {m.roll} pitch {m.pitch} rad too large for a cruise")
        elif typ == "ATTITUDE_QUATERNION":
            n = math.sqrt(m.q1 ** 2 + m.q2 ** 2 + m.q3 ** 2 + m.q4 ** 2)
            if abs(n - 1.0) > 1e-3:
                fail(f"quaternion norm {n}")
        elif typ == "RAW_IMU":
            # ArduPilot RAW_IMU: mG; level flight ≈ −1000 mG on z.
            if not -1500 < m.zacc < -500:
                fail(f"RAW_IMU zacc {m.zacc} mG: expected about -1000")
        elif typ == "HIGHRES_IMU":
            if not -15.0 < m.zacc < -5.0:
                fail(f"HIGHRES_IMU zacc {m.zacc} m/s²: expected about -9.8")
        elif typ == "NAMED_VALUE_FLOAT":
            if m.name not in ("cmd_speed", "payload_g", "cmd_alt"):
                fail(f"unexpected NAMED_VALUE_FLOAT {m.name}")
    if armed_t is None:
        fail("never armed")
    if home_seen_t is None or home_seen_t < armed_t - 1e-6:
        fail("HOME_POSITION must come once armed")
    dur = last_t - first_t
    out = {
        "counts": counts,
        "bad": bad,
        "duration_s": dur,
        "rates_hz": {k: v / dur for k, v in counts.items()},
        "hover_w": statistics.median(hover_p) if hover_p else None,
        "cruise_w": statistics.median(cruise_p) if cruise_p else None,
        "max_w": max(all_p) if all_p else None,
        "start_epoch_s": first_t,
    }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
