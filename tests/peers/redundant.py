#!/usr/bin/env python3
"""One pymavlink vehicle on two radios, for tests/it/source_links.rs.

  redundant.py --ports P1,P2 --seconds 12 --loss 0.3,0.3 --seed 7 [--cut 0:4:4]

It streams an ArduPilot-style flight at 10 Hz (HEARTBEAT at 1 Hz; SYS_STATUS 500 W at
22.2 V, GLOBAL_POSITION_INT, ATTITUDE, RAW_IMU, VFR_HUD) as system 1, component 1. Every
frame is packed once (one sequence number) and the same bytes go to 127.0.0.1:P1 and
127.0.0.1:P2 from two UDP sockets, each link dropping a frame with its own probability,
independently (seeded). --cut LINK:FROM_S:FOR_S drops everything on one link for a while.

Prints one JSON object: frames packed, frames sent on each link, frames delivered on at
least one link (what a perfect merge hands on), on both, and the frames heard back from
dronewatt on each link.
"""
import argparse
import json
import os
import random
import select
import socket
import time

os.environ.setdefault("MAVLINK20", "1")
from pymavlink.dialects.v20 import ardupilotmega as mav  # noqa: E402

LAT0, LON0, HOME_AMSL = 47.3977419, 8.5455938, 400.0
VOLTS, POWER_W = 22.2, 500.0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ports", required=True)
    ap.add_argument("--seconds", type=float, default=12.0)
    ap.add_argument("--loss", default="0.3,0.3")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--cut", default=None, help="LINK:FROM_S:FOR_S")
    a = ap.parse_args()
    ports = [int(p) for p in a.ports.split(",")]
    loss = [float(x) for x in a.loss.split(",")]
    cut = None
    if a.cut:
        link, start, span = a.cut.split(":")
        cut = (int(link), float(start), float(start) + float(span))
    rng = random.Random(a.seed)
    socks = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in ports]
    for s in socks:
        s.bind(("127.0.0.1", 0))
        s.setblocking(False)
    m = mav.MAVLink(None, srcSystem=1, srcComponent=1)
    out = {"packed": 0, "sent": [0] * len(ports), "union": 0, "both": 0, "heard_back": [0] * len(ports)}

    def drain():
        for i, s in enumerate(socks):
            while True:
                try:
                    data = s.recv(65536)
                except BlockingIOError:
                    break
                out["heard_back"][i] += 1

    def send(msg, t):
        buf = msg.pack(m)
        m.seq = (m.seq + 1) % 256
        out["packed"] += 1
        got = 0
        for i, s in enumerate(socks):
            if cut and cut[0] == i and cut[1] <= t < cut[2]:
                continue
            if rng.random() < loss[i]:
                continue
            s.sendto(buf, ("127.0.0.1", ports[i]))
            out["sent"][i] += 1
            got += 1
        out["union"] += got > 0
        out["both"] += got == len(socks)

    t0 = time.monotonic()
    n = 0
    while n / 10.0 <= a.seconds:
        t = n / 10.0
        while True:
            left = t0 + t - time.monotonic()
            if left <= 0:
                break
            select.select(socks, [], [], min(left, 0.02))
            drain()
        boot_ms = int(t * 1000)
        alt = 25.0 * min(t / 5.0, 1.0)
        speed = 0.0 if t < 5.0 else 10.0
        lat = LAT0 + max(0.0, t - 5.0) * 10.0 / 111_195.0
        if n % 10 == 0:
            send(mav.MAVLink_heartbeat_message(mav.MAV_TYPE_QUADROTOR, mav.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 3,
                                               mav.MAV_STATE_ACTIVE, 3), t)
        send(mav.MAVLink_sys_status_message(0, 0, 0, 500, int(VOLTS * 1000), int(POWER_W / VOLTS * 100), -1,
                                            0, 0, 0, 0, 0, 0), t)
        send(mav.MAVLink_global_position_int_message(boot_ms, int(lat * 1e7), int(LON0 * 1e7),
                                                     int((HOME_AMSL + alt) * 1000), int(alt * 1000),
                                                     int(speed * 100), 0, int((-5.0 if t < 5.0 else 0.0) * 100), 0), t)
        send(mav.MAVLink_attitude_message(boot_ms, 0.0, -0.1 if speed else 0.0, 0.0, 0.0, 0.0, 0.0), t)
        send(mav.MAVLink_raw_imu_message(boot_ms * 1000, 0, 0, -1000, 0, 0, 0, 0, 0, 0), t)
        send(mav.MAVLink_vfr_hud_message(speed, speed, 0, 50, alt, 0.0), t)
        n += 1
    end = time.monotonic() + 1.0
    while time.monotonic() < end:
        select.select(socks, [], [], 0.05)
        drain()
    print(json.dumps(out), flush=True)


if __name__ == "__main__":
    main()
