"""Independent reader for tests/it/sim_ulog.rs: reads a PX4 .ulg with pyulog and the same
flight's .tlog with pymavlink's mavutil, and prints one JSON object: per-topic sample counts
and parameters of the .ulg, per-type counts of the .tlog, and the battery and attitude
series of each (µs from the first record).

usage: ulog_dump.py FLIGHT.ulg FLIGHT.tlog
"""
import json
import sys
from collections import Counter

from pymavlink import mavutil
from pyulog import ULog


def read_ulg(path):
    u = ULog(path)
    counts = {d.name: len(d.data["timestamp"]) for d in u.data_list if d.multi_id == 0}
    by = {d.name: d.data for d in u.data_list if d.multi_id == 0}
    b = by["battery_status"]
    bat = [[int(b["timestamp"][i]), float(b["voltage_v"][i]), float(b["current_a"][i])] for i in range(len(b["timestamp"]))]
    a = by["vehicle_attitude"]
    att = [[int(a["timestamp"][i])] + [float(a["q[%d]" % k][i]) for k in range(4)] for i in range(len(a["timestamp"]))]
    params = {k: float(v) for k, v in u.initial_parameters.items()}
    return {"counts": counts, "bat": bat, "att": att, "parm": params}


def read_tlog(path):
    r = mavutil.mavlink_connection(path, dialect="ardupilotmega")
    counts, bat, att, parm = Counter(), [], [], {}
    t0 = None
    while True:
        m = r.recv_match()
        if m is None:
            break
        t = m.get_type()
        counts[t] += 1
        us = int(round(m._timestamp * 1e6))
        t0 = us if t0 is None else t0
        if t == "BATTERY_STATUS":
            bat.append([us - t0, m.voltages[0] / 1000.0, m.current_battery / 100.0])
        elif t == "ATTITUDE_QUATERNION":
            att.append([us - t0, m.q1, m.q2, m.q3, m.q4])
        elif t == "PARAM_VALUE":
            parm[m.param_id] = m.param_value
    return {"counts": counts, "bat": bat, "att": att, "parm": parm}


print(json.dumps({"ulg": read_ulg(sys.argv[1]), "tlog": read_tlog(sys.argv[2])}))
