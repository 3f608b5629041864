#!/usr/bin/env python3
"""One pymavlink vehicle on two radios, for tests/it/source_links.rs.

  redundant.py --ports P1,P2 --seconds 12 --loss 0.3,0.3 --seed 7 [--cut 0:4:4] [--fleet P3]

It streams an ArduPilot-style flight at 10 Hz (HEARTBEAT at 1 Hz; SYS_STATUS 500 W at
22.2 V, GLOBAL_POSITION_INT, ATTITUDE, RAW_IMU, VFR_HUD) as system 1, component 1. Every
frame is packed once (one sequence number) and the same bytes go to 127.0.0.1:P1 and
127.0.0.1:P2 from two UDP sockets, each link dropping a frame with its own probability,
independently (seeded). --cut LINK:FROM_S:FOR_S drops everything on one link for a while.

--fleet P3 adds a second fleet on a third link (127.0.0.1:P3), a separate network in
dronewatt's config: another vehicle that is also system 1, component 1, with its own
sequence numbers, drawing 300 W at 14.8 V from a 60 % battery (the first: 500 W at 22.2 V,
80 %), 500 m east, nothing lost.

Prints one JSON object: frames packed, frames sent on each link, frames delivered on at
least one link (what a perfect merge hands on), on both, the frames heard back from
dronewatt on each link, and the `dw_meas_w` values (NAMED_VALUE_FLOAT) heard back on each
link as [min, max] (null when none): whose estimates went out on which link.
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
FLEET_VOLTS, FLEET_POWER_W = 14.8, 300.0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ports", required=True)
    ap.add_argument("--seconds", type=float, default=12.0)
    ap.add_argument("--loss", default="0.3,0.3")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--cut", default=None, help="LINK:FROM_S:FOR_S")
    ap.add_argument("--fleet", type=int, default=None, help="port of a second fleet's link")
    a = ap.parse_args()
    ports = [int(p) for p in a.ports.split(",")]
    pair = len(ports)
    if a.fleet:
        ports.append(a.fleet)
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
    # The second fleet's vehicle: the same system id, its own sequence numbers.
    m2 = mav.MAVLink(None, srcSystem=1, srcComponent=1)
    out = {"packed": 0, "sent": [0] * len(ports), "union": 0, "both": 0, "heard_back": [0] * len(ports),
           "fleet_sent": 0, "meas_back": [None] * len(ports)}
    parsers = [mav.MAVLink(None) for _ in ports]
    for p in parsers:
        p.robust_parsing = True

    def drain():
        for i, s in enumerate(socks):
            while True:
                try:
                    data = s.recv(65536)
                except BlockingIOError:
                    break
                out["heard_back"][i] += 1
                for msg in parsers[i].parse_buffer(data) or []:
                    if msg.get_type() == "NAMED_VALUE_FLOAT" and msg.name == "dw_meas_w":
                        mm = out["meas_back"][i]
                        out["meas_back"][i] = [min(mm[0], msg.value), max(mm[1], msg.value)] if mm else [msg.value, msg.value]

    def send(msg, t):
        buf = msg.pack(m)
        m.seq = (m.seq + 1) % 256
        out["packed"] += 1
        got = 0
        for i, s in enumerate(socks[:pair]):
            if cut and cut[0] == i and cut[1] <= t < cut[2]:
                continue
            if rng.random() < loss[i]:
                continue
            s.sendto(buf, ("127.0.0.1", ports[i]))
            out["sent"][i] += 1
            got += 1
        out["union"] += got > 0
        out["both"] += got == pair

    def send_fleet(msg):
        buf = msg.pack(m2)
        m2.seq = (m2.seq + 1) % 256
        socks[pair].sendto(buf, ("127.0.0.1", ports[pair]))
        out["fleet_sent"] += 1
        out["sent"][pair] += 1

    def fly(emit, t, n, volts, power_w, pct, lon):
        boot_ms = int(t * 1000)
        alt = 25.0 * min(t / 5.0, 1.0)
        speed = 0.0 if t < 5.0 else 10.0
        lat = LAT0 + max(0.0, t - 5.0) * 10.0 / 111_195.0
        if n % 10 == 0:
            emit(mav.MAVLink_heartbeat_message(mav.MAV_TYPE_QUADROTOR, mav.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 3,
                                               mav.MAV_STATE_ACTIVE, 3))
        emit(mav.MAVLink_sys_status_message(0, 0, 0, 500, int(volts * 1000), int(power_w / volts * 100), pct,
                                            0, 0, 0, 0, 0, 0))
        emit(mav.MAVLink_global_position_int_message(boot_ms, int(lat * 1e7), int(lon * 1e7),
                                                     int((HOME_AMSL + alt) * 1000), int(alt * 1000),
                                                     int(speed * 100), 0, int((-5.0 if t < 5.0 else 0.0) * 100), 0))
        emit(mav.MAVLink_attitude_message(boot_ms, 0.0, -0.1 if speed else 0.0, 0.0, 0.0, 0.0, 0.0))
        emit(mav.MAVLink_raw_imu_message(boot_ms * 1000, 0, 0, -1000, 0, 0, 0, 0, 0, 0))
        emit(mav.MAVLink_vfr_hud_message(speed, speed, 0, 50, alt, 0.0))

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
        fly(lambda msg: send(msg, t), t, n, VOLTS, POWER_W, -1 if not a.fleet else 80, LON0)
        if a.fleet:
            fly(send_fleet, t, n, FLEET_VOLTS, FLEET_POWER_W, 60, LON0 + 500.0 / 75_300.0)
        n += 1
    end = time.monotonic() + 1.0
    while time.monotonic() < end:
        select.select(socks, [], [], 0.05)
        drain()
    print(json.dumps(out), flush=True)


if __name__ == "__main__":
    main()
