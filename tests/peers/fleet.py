#!/usr/bin/env python3
"""A pymavlink fleet for dronewatt's fleet tests: several vehicles (each its own MAVLink
system id, its own power and place) on one link, plus a ground station's and a companion
computer's heartbeats (neither is a vehicle).

  fleet.py --to udpout:127.0.0.1:PORT [--to udpout:127.0.0.1:PORT2 …] \\
      --vehicles '[{"id": 1, "power_w": 300, "send_s": 10}, {"id": 3, "power_w": 700, "send_s": 4}]'

Each vehicle climbs from its own home to 25 m in 5 s and cruises north at 10 m/s, drawing
power_w ± 40 W at 22.2 V, for send_s seconds at 10 Hz (then falls silent). The ground
station (system 255, MAV_TYPE_GCS) and a companion computer (system 42,
MAV_TYPE_ONBOARD_CONTROLLER, MAV_AUTOPILOT_INVALID) send a heartbeat each second
throughout. Every frame goes to every --to address (a fan-out like mavlink-router's).

Listens on the first connection while it sends and for --listen-after-s after, and prints
one JSON line: what it heard from dronewatt, per sender "sys,comp": NAMED_VALUE_FLOAT
values by name, STATUSTEXTs, heartbeats.
"""
import argparse
import json
import math
import os
import select
import time

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402
from pymavlink.dialects.v20 import ardupilotmega as mav  # noqa: E402

LAT0, LON0 = 47.3977419, 8.5455938
VOLTS = 22.2


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--to", action="append", required=True, help="pymavlink address (udpout:HOST:PORT); repeat to fan out")
    ap.add_argument("--vehicles", required=True, help="JSON list of {id, power_w, send_s}")
    ap.add_argument("--listen-after-s", type=float, default=1.5)
    a = ap.parse_args()
    vehicles = json.loads(a.vehicles)
    conns = [mavutil.mavlink_connection(t, source_system=255, source_component=190) for t in a.to]
    enc = {v["id"]: mav.MAVLink(None, srcSystem=v["id"], srcComponent=1) for v in vehicles}
    gcs = mav.MAVLink(None, srcSystem=255, srcComponent=190)
    companion = mav.MAVLink(None, srcSystem=42, srcComponent=191)
    heard = {}

    def write(m, e):
        buf = m.pack(e)
        e.seq = (e.seq + 1) % 256
        for c in conns:
            c.write(buf)

    def drain():
        while True:
            r = conns[0].recv_match(blocking=False)
            if r is None:
                return
            if r.get_type() == "BAD_DATA":
                continue
            h = heard.setdefault(f"{r.get_srcSystem()},{r.get_srcComponent()}", {"values": {}, "statustexts": [], "heartbeats": 0})
            t = r.get_type()
            if t == "NAMED_VALUE_FLOAT":
                name = r.name if isinstance(r.name, str) else r.name.decode()
                h["values"].setdefault(name, []).append(r.value)
            elif t == "STATUSTEXT":
                h["statustexts"].append(r.text if isinstance(r.text, str) else r.text.decode())
            elif t == "HEARTBEAT":
                h["heartbeats"] += 1

    def wait_until(target):
        while True:
            drain()
            left = target - time.monotonic()
            if left <= 0:
                return
            select.select([conns[0].port], [], [], min(left, 0.05))

    def tick(v, t, boot_ms, n):
        e = enc[v["id"]]
        home_lat = LAT0 + 0.01 * v["id"]
        alt = 25.0 * min(t / 5.0, 1.0)
        speed = 0.0 if t < 5.0 else 10.0
        lat = home_lat + max(0.0, t - 5.0) * 10.0 / 111_320.0
        power = v["power_w"] + 40.0 * math.sin(2 * math.pi * t / 3.0)
        vz = 5.0 if t < 5.0 else 0.0
        msgs = []
        if n % 10 == 0:
            msgs.append(mav.MAVLink_heartbeat_message(mav.MAV_TYPE_QUADROTOR, mav.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, mav.MAV_STATE_ACTIVE, 3))
            msgs.append(mav.MAVLink_home_position_message(int(home_lat * 1e7), int(LON0 * 1e7), 400_000, 0.0, 0.0, 0.0,
                                                          [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0))
        msgs.append(mav.MAVLink_sys_status_message(0, 0, 0, 500, int(VOLTS * 1000), int(power / VOLTS * 100), -1, 0, 0, 0, 0, 0, 0))
        msgs.append(mav.MAVLink_global_position_int_message(boot_ms, int(lat * 1e7), int(LON0 * 1e7), int((400.0 + alt) * 1000),
                                                            int(alt * 1000), int(speed * 100), 0, int(-vz * 100), 0))
        msgs.append(mav.MAVLink_attitude_message(boot_ms, 0.0, -0.1 if speed > 0 else 0.0, 0.0, 0.0, 0.0, 0.0))
        msgs.append(mav.MAVLink_raw_imu_message(boot_ms * 1000, 0, 0, -1000, 0, 0, 0, 0, 0, 0))
        msgs.append(mav.MAVLink_vfr_hud_message(speed, speed, 0, 50, alt, vz))
        msgs.append(mav.MAVLink_wind_message(180.0, 2.0, 0.0))
        for m in msgs:
            write(m, e)
        return len(msgs)

    start = time.monotonic()
    end = max(v["send_s"] for v in vehicles)
    sent = {v["id"]: 0 for v in vehicles}
    n = 0
    while n / 10.0 <= end:
        wait_until(start + n / 10.0)
        t = n / 10.0
        boot_ms = int(t * 1000)
        if n % 10 == 0:
            write(mav.MAVLink_heartbeat_message(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, mav.MAV_STATE_ACTIVE, 3), gcs)
            write(mav.MAVLink_heartbeat_message(mav.MAV_TYPE_ONBOARD_CONTROLLER, mav.MAV_AUTOPILOT_INVALID, 0, 0,
                                                mav.MAV_STATE_ACTIVE, 3), companion)
        for v in vehicles:
            if t <= v["send_s"]:
                sent[v["id"]] += tick(v, t, boot_ms, n)
        n += 1
    wait_until(time.monotonic() + a.listen_after_s)
    for c in conns:
        c.close()
    print(json.dumps({"sent": sent, "heard": heard}), flush=True)


if __name__ == "__main__":
    main()
