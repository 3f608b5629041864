"""Independent reader for tests/it/sim_dataflash.rs: reads a DataFlash .bin with pymavlink's
DFReader and the same flight's .tlog with mavutil, and prints one JSON object: per-type
counts of each, and the series the test compares (battery, attitude, position, parameters).

usage: dataflash_dump.py FLIGHT.bin FLIGHT.tlog
"""
import json
import sys
from collections import Counter

from pymavlink import DFReader, mavutil


def read_bin(path):
    r = DFReader.DFReader_binary(path)
    counts, bat, att, pos, parm = Counter(), [], [], [], {}
    while True:
        m = r.recv_msg()
        if m is None:
            break
        t = m.get_type()
        counts[t] += 1
        if t == "BAT":
            bat.append([m.TimeUS, m.Volt, m.Curr, m.RemPct])
        elif t == "ATT":
            att.append([m.TimeUS, m.Roll, m.Pitch, m.Yaw])
        elif t == "POS":
            pos.append([m.TimeUS, m.Lat, m.Lng, m.Alt])
        elif t == "PARM":
            parm[m.Name] = m.Value
    return {"counts": counts, "bat": bat, "att": att, "pos": pos, "parm": parm}


def read_tlog(path):
    r = mavutil.mavlink_connection(path, dialect="ardupilotmega")
    counts, bat, att, pos, parm = Counter(), [], [], [], {}
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
            bat.append([us - t0, m.voltages[0] / 1000.0, m.current_battery / 100.0, m.battery_remaining])
        elif t == "ATTITUDE":
            att.append([us - t0, m.roll, m.pitch, m.yaw])
        elif t == "GLOBAL_POSITION_INT":
            pos.append([us - t0, m.lat * 1e-7, m.lon * 1e-7, m.alt * 1e-3])
        elif t == "PARAM_VALUE":
            parm[m.param_id] = m.param_value
    return {"counts": counts, "bat": bat, "att": att, "pos": pos, "parm": parm}


print(json.dumps({"bin": read_bin(sys.argv[1]), "tlog": read_tlog(sys.argv[2])}))
