#!/usr/bin/env python3
"""A pymavlink vehicle on a slow radio link, for dronewatt's link-rate tests.

Every message type comes at its own rate (default 1 Hz) and each message is late or early by
its own uniform random jitter (default ±0.25 s, seeded), as on a 57,600-baud radio; with
--burst every message of a tick shares one jitter (the radio sends its buffer as one burst,
so the whole stream is silent for about a second between bursts). The
flight: on the ground (2 W) for --ground-s, a climb to 25 m in 5 s, then north at 10 m/s at
500 W ± 40 W (a 3 s swing), on a fixed 22.2 V, battery_remaining unknown.

  slow_link.py --tlog out.tlog --seconds 60                  # a telemetry log, stamped as sent
  slow_link.py --to udpout:127.0.0.1:PORT --seconds 20       # the same, live, in real time

--only HEARTBEAT,SYS_STATUS sends only those types; --stop GLOBAL_POSITION_INT@30 stops a
type 30 s into the flight (a stream that stops).

Live, it hears what dronewatt asks: --answer grant acknowledges MAV_CMD_SET_MESSAGE_INTERVAL
(MAV_RESULT_ACCEPTED) and sends that message at the rate asked; --answer deny refuses it
(MAV_RESULT_DENIED) but obeys ArduPilot's REQUEST_DATA_STREAM; --answer ignore (the default)
answers nothing.

Prints one JSON line: the airborne interval on the log's clock (s since the epoch, as the
tlog stamps it; live: the wall clock) and counted from the first frame sent (the clock of a
replay's reports), the frames of each type sent, what was asked
(SET_MESSAGE_INTERVAL: Hz by type; REQUEST_DATA_STREAM: Hz by stream id), the rates in force
at the end, and the rates sent over the last 5 s.
"""
import argparse
import json
import math
import os
import random
import select
import struct
import time

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402
from pymavlink.dialects.v20 import ardupilotmega as mav  # noqa: E402

LAT0, LON0 = 47.3977419, 8.5455938
VOLTS = 22.2
TYPES = ["HEARTBEAT", "SYS_STATUS", "BATTERY_STATUS", "GLOBAL_POSITION_INT", "ATTITUDE", "RAW_IMU", "VFR_HUD", "WIND"]


def state(t, ground_s):
    """Altitude (m), ground speed (m/s), north (m), climb (m/s), power (W) at t s since start."""
    f = t - ground_s
    if f < 0:
        return 0.0, 0.0, 0.0, 0.0, 2.0
    alt = 25.0 * min(f / 5.0, 1.0)
    speed = 0.0 if f < 5.0 else 10.0
    north = max(0.0, f - 5.0) * 10.0
    vz = 5.0 if f < 5.0 else 0.0
    return alt, speed, north, vz, 500.0 + 40.0 * math.sin(2 * math.pi * f / 3.0)


def message(kind, t, ground_s):
    alt, speed, north, vz, power = state(t, ground_s)
    boot_ms = int(t * 1000)
    lat = LAT0 + north / 111_320.0
    if kind == "HEARTBEAT":
        return mav.MAVLink_heartbeat_message(mav.MAV_TYPE_QUADROTOR, mav.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0,
                                             mav.MAV_STATE_ACTIVE, 3)
    if kind == "SYS_STATUS":
        return mav.MAVLink_sys_status_message(0, 0, 0, 500, int(VOLTS * 1000), int(power / VOLTS * 100), -1,
                                              0, 0, 0, 0, 0, 0)
    if kind == "GLOBAL_POSITION_INT":
        return mav.MAVLink_global_position_int_message(boot_ms, int(lat * 1e7), int(LON0 * 1e7),
                                                       int((400.0 + alt) * 1000), int(alt * 1000),
                                                       int(speed * 100), 0, int(-vz * 100), 0)
    if kind == "ATTITUDE":
        return mav.MAVLink_attitude_message(boot_ms, 0.0, -0.1 if speed > 0 else 0.0, 0.0, 0.0, 0.0, 0.0)
    if kind == "RAW_IMU":
        return mav.MAVLink_raw_imu_message(boot_ms * 1000, 0, 0, -1000, 0, 0, 0, 0, 0, 0)
    if kind == "VFR_HUD":
        return mav.MAVLink_vfr_hud_message(speed, speed, 0, 50, alt, vz)
    if kind == "BATTERY_STATUS":
        cells = [int(VOLTS / 6 * 1000)] * 6 + [65535] * 4
        return mav.MAVLink_battery_status_message(0, 0, 3, 32767, cells, int(power / VOLTS * 100), -1, -1, -1)
    return mav.MAVLink_wind_message(180.0, 2.0, 0.0)


STREAMS = {1: ["RAW_IMU"], 2: ["SYS_STATUS"], 6: ["GLOBAL_POSITION_INT"], 10: ["ATTITUDE"], 11: ["VFR_HUD"],
           12: ["WIND", "BATTERY_STATUS"]}
IDS = {"HEARTBEAT": 0, "SYS_STATUS": 1, "RAW_IMU": 27, "ATTITUDE": 30, "GLOBAL_POSITION_INT": 33, "VFR_HUD": 74,
       "BATTERY_STATUS": 147, "WIND": 168}


class Peer:
    """Sends each type at its own rate with its own jitter; live, answers stream requests."""

    def __init__(self, a):
        self.a, self.rng = a, random.Random(a.seed)
        only = a.only.split(",") if a.only else TYPES
        self.stops = dict((s.split("@")[0], float(s.split("@")[1])) for s in a.stop)
        self.rate = {k: (1.0 if k == "HEARTBEAT" else a.rate_hz) for k in only}
        self.nominal = {k: 0.0 for k in only}
        self.burst = {}
        self.at = {k: self.jittered(k) for k in only}
        self.asked, self.streams, self.sent = {}, {}, {}

    def jittered(self, kind):
        if self.a.burst:
            # one jitter for everything of a tick: the radio's buffer goes out as one burst
            key = round(self.nominal[kind], 6)
            if key not in self.burst:
                self.burst[key] = self.rng.uniform(-self.a.jitter_s, self.a.jitter_s)
            return max(0.0, self.nominal[kind] + self.burst[key])
        return max(0.0, self.nominal[kind] + self.rng.uniform(-self.a.jitter_s, self.a.jitter_s))

    def set_rate(self, kind, hz, now):
        if kind in self.rate and hz > 0:
            self.rate[kind] = hz
            self.nominal[kind] = now
            self.at[kind] = now

    def next(self):
        kind = min(self.at, key=self.at.get)
        t = self.at[kind]
        self.nominal[kind] += 1.0 / self.rate[kind]
        self.at[kind] = max(self.jittered(kind), t)
        return t, kind

    def heard(self, conn, link, now):
        """Answer what dronewatt asked (live only)."""
        while True:
            m = conn.recv_match(blocking=False)
            if m is None:
                return
            t = m.get_type()
            if t == "COMMAND_LONG" and m.command == mav.MAV_CMD_SET_MESSAGE_INTERVAL:
                kind = next((k for k, i in IDS.items() if i == int(m.param1)), None)
                hz = 1e6 / m.param2 if m.param2 > 0 else 0.0
                self.asked[kind or str(int(m.param1))] = round(hz, 3)
                if self.a.answer == "ignore":
                    continue
                ok = self.a.answer == "grant" and kind in self.rate
                if ok:
                    self.set_rate(kind, hz, now)
                result = mav.MAV_RESULT_ACCEPTED if ok else mav.MAV_RESULT_DENIED
                conn.write(mav.MAVLink_command_ack_message(m.command, result).pack(link))
                link.seq = (link.seq + 1) % 256
            elif t == "REQUEST_DATA_STREAM" and m.start_stop:
                self.streams[str(m.req_stream_id)] = m.req_message_rate
                for kind in STREAMS.get(m.req_stream_id, []):
                    self.set_rate(kind, float(m.req_message_rate), now)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--tlog", default=None, help="write a telemetry log (no waiting)")
    ap.add_argument("--to", default=None, help="pymavlink address: fly live, in real time")
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--ground-s", type=float, default=5.0)
    ap.add_argument("--rate-hz", type=float, default=1.0)
    ap.add_argument("--jitter-s", type=float, default=0.25)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--burst", action="store_true", help="one jitter per tick for every type (a radio's burst)")
    ap.add_argument("--only", default=None, help="comma-separated message types to send")
    ap.add_argument("--stop", action="append", default=[], help="TYPE@S: stop a type S s into the flight")
    ap.add_argument("--answer", choices=["grant", "deny", "ignore"], default="ignore",
                    help="live: how SET_MESSAGE_INTERVAL is answered (deny: REQUEST_DATA_STREAM is obeyed)")
    a = ap.parse_args()
    link = mav.MAVLink(None, srcSystem=1, srcComponent=1)
    conn = mavutil.mavlink_connection(a.to, source_system=1, source_component=1) if a.to else None
    log = open(a.tlog, "wb") if a.tlog else None
    epoch = 1_700_000_000.0 if conn is None else time.time()
    start = time.monotonic()
    peer = Peer(a)
    # the rates sent over the last 5 s of the flight, per type
    tail, first = {}, None
    while True:
        t, kind = peer.next()
        if t > a.seconds:
            break
        if conn is not None:
            while True:
                now = time.monotonic() - start
                peer.heard(conn, link, now)
                if now >= t:
                    break
                select.select([conn.port], [], [], min(t - now, 0.05))
        if t - a.ground_s >= peer.stops.get(kind, math.inf):
            continue
        buf = message(kind, t, a.ground_s).pack(link)
        link.seq = (link.seq + 1) % 256
        if conn is not None:
            conn.write(buf)
        if log is not None:
            log.write(struct.pack(">Q", int((epoch + t) * 1e6)) + buf)
        peer.sent[kind] = peer.sent.get(kind, 0) + 1
        first = t if first is None else first
        if t >= a.seconds - 5.0:
            tail[kind] = tail.get(kind, 0) + 1
    if log is not None:
        log.close()
    first = first or 0.0
    print(json.dumps({"airborne": [epoch + a.ground_s, epoch + a.seconds],
                      "airborne_from_first": [a.ground_s - first, a.seconds - first], "sent": peer.sent,
                      "asked": peer.asked, "streams": peer.streams,
                      "rates": {k: round(peer.rate[k], 3) for k in peer.rate},
                      "tail_hz": {k: n / 5.0 for k, n in tail.items()}}), flush=True)


if __name__ == "__main__":
    main()
