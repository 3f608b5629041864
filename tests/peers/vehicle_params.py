#!/usr/bin/env python3
"""An independent autopilot (pymavlink) for `dronewatt monitor udpin:127.0.0.1:PORT`: it
streams a hover at `--power-w` and answers dronewatt's parameter protocol the way the
real firmware encodes it.

- `--autopilot ardupilot`: HEARTBEAT says MAV_AUTOPILOT_ARDUPILOTMEGA; PARAM_VALUE casts
  integers to float (BATT_CAPACITY 3300 is 3300.0), as ArduPilot does. 3S pack at 12.4 V.
- `--autopilot px4`: HEARTBEAT says MAV_AUTOPILOT_PX4; INT32 parameters are packed bytewise
  into the float (BAT1_N_CELLS 4 is the float whose bits are 0x00000004), as PX4 does.
  4S pack at 16.0 V.

The first PARAM_REQUEST_READ for the capacity parameter is dropped (not answered), so
dronewatt must send it again. A request for a parameter this vehicle does not have gets
no answer at all (as on the real firmware). MAV_CMD_REQUEST_MESSAGE(AUTOPILOT_VERSION) is
answered with uid `--uid`.

Prints one JSON line at the end: every request heard, by parameter name, with its count.
"""
import argparse
import json
import select
import struct
import time

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mav

ARDUPILOT = {  # name: (value, type)
    "BATT_CAPACITY": (3300, mav.MAV_PARAM_TYPE_INT32),
    "BATT_LOW_VOLT": (10.5, mav.MAV_PARAM_TYPE_REAL32),
    "BATT_CRT_VOLT": (9.9, mav.MAV_PARAM_TYPE_REAL32),
    "BATT_LOW_MAH": (0, mav.MAV_PARAM_TYPE_INT32),
    "MOT_THST_HOVER": (0.35, mav.MAV_PARAM_TYPE_REAL32),
    "MOT_BAT_VOLT_MAX": (12.6, mav.MAV_PARAM_TYPE_REAL32),
    "MOT_BAT_VOLT_MIN": (9.9, mav.MAV_PARAM_TYPE_REAL32),
    "FRAME_CLASS": (1, mav.MAV_PARAM_TYPE_INT8),
    # BATT_CRT_MAH deliberately missing: dronewatt must give up on it, not hang.
}
PX4 = {
    "BAT1_CAPACITY": (5000.0, mav.MAV_PARAM_TYPE_REAL32),
    "BAT1_N_CELLS": (4, mav.MAV_PARAM_TYPE_INT32),
    "BAT1_V_CHARGED": (4.2, mav.MAV_PARAM_TYPE_REAL32),
    "BAT1_V_EMPTY": (3.5, mav.MAV_PARAM_TYPE_REAL32),
}


def encode(autopilot, value, ptype):
    """The float that goes on the wire for this autopilot."""
    if ptype == mav.MAV_PARAM_TYPE_REAL32:
        return float(value)
    if autopilot == "px4":
        return struct.unpack("<f", struct.pack("<i", int(value)))[0]
    return float(value)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--autopilot", choices=["ardupilot", "px4"], required=True)
    ap.add_argument("--seconds", type=float, default=8.0)
    ap.add_argument("--power-w", type=float, default=150.0)
    ap.add_argument("--uid", type=int, default=0x1234ABCD)
    a = ap.parse_args()
    params = ARDUPILOT if a.autopilot == "ardupilot" else PX4
    capacity = "BATT_CAPACITY" if a.autopilot == "ardupilot" else "BAT1_CAPACITY"
    volts = 12.4 if a.autopilot == "ardupilot" else 16.0
    autopilot = mav.MAV_AUTOPILOT_ARDUPILOTMEGA if a.autopilot == "ardupilot" else mav.MAV_AUTOPILOT_PX4
    conn = mavutil.mavlink_connection(f"udpout:127.0.0.1:{a.port}", source_system=1, source_component=1)
    m = conn.mav
    requests = {}
    dropped = []

    def answer():
        while True:
            r = conn.recv_match(blocking=False)
            if r is None:
                return
            t = r.get_type()
            if t == "PARAM_REQUEST_READ" and r.target_system == 1:
                name = r.param_id.rstrip("\x00") if isinstance(r.param_id, str) else r.param_id.decode().rstrip("\x00")
                requests[name] = requests.get(name, 0) + 1
                if name == capacity and not dropped:
                    dropped.append(name)  # lost on the radio: dronewatt must ask again
                    continue
                if name in params:
                    v, ptype = params[name]
                    m.param_value_send(name.encode(), encode(a.autopilot, v, ptype), ptype, 900, 0)
            elif t == "COMMAND_LONG" and r.command == mav.MAV_CMD_REQUEST_MESSAGE and int(r.param1) == 148:
                requests["AUTOPILOT_VERSION"] = requests.get("AUTOPILOT_VERSION", 0) + 1
                m.autopilot_version_send(0, 0, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0, 0, a.uid)

    start = time.monotonic()
    n = 0
    rate = 10.0
    while True:
        t = n / rate
        if t > a.seconds:
            break
        target = start + t
        while time.monotonic() < target:
            answer()
            select.select([conn.port], [], [], max(0.0, target - time.monotonic()))
        boot_ms = int(t * 1000)
        current = a.power_w / volts
        if n % int(rate) == 0:
            m.heartbeat_send(mav.MAV_TYPE_QUADROTOR, autopilot, 0, 0, mav.MAV_STATE_ACTIVE)
        m.sys_status_send(0, 0, 0, 500, int(volts * 1000), int(current * 100), -1, 0, 0, 0, 0, 0, 0)
        m.global_position_int_send(boot_ms, int(47.3977419e7), int(8.5455938e7), 410_000, 10_000, 0, 0, 0, 0)
        m.attitude_send(boot_ms, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        m.raw_imu_send(boot_ms * 1000, 0, 0, -1000, 0, 0, 0, 0, 0, 0)
        m.vfr_hud_send(0.0, 0.0, 0, 40, 10.0, 0.0)
        n += 1
    end = time.monotonic() + 1.0
    while time.monotonic() < end:
        answer()
        select.select([conn.port], [], [], 0.05)
    print(json.dumps({"requests": requests, "dropped": dropped}))


if __name__ == "__main__":
    main()
