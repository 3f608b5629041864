#!/usr/bin/env python3
"""A scripted pymavlink vehicle for dronewatt's link-fault and signing tests.

It flies a fixed, fully known flight (climb from a home at 400 m above sea level to 25 m
above it in 5 s, then cruise north at 10 m/s, 500 W ± 40 W
at 22.2 V, battery_remaining unknown) to `dronewatt monitor`, in phases given as JSON:

  vehicle.py --to udpout:127.0.0.1:PORT --plan '[{"send_s": 6}, {"quiet_s": 10}, {"send_s": 6}]'

Phase keys (all optional but one of send_s / quiet_s):
  send_s      stream telemetry this long          quiet_s   send nothing this long (still listen)
  rate_hz     ticks per second (10)               v1        every other frame MAVLink 1 (else all 2)
  reboot      before this phase: sequence numbers restart at 0, time_boot_ms at 0, a new home 1 km north
  reconnect   before this phase: close the connection and open a new one (UDP: a new source port)
  stray       a second vehicle (system 2, 2000 W) interleaves its own telemetry
  replay      at the end of this phase, send again the first N frames it recorded (signing tests)

Signing: --sign-key HEX signs every MAVLink 2 frame (pymavlink's setup_signing; it then also
verifies what it hears and drops what fails). --link-id N its link id.

Prints one JSON line: frames sent (and NAMED_VALUE_FLOATs heard) per phase, what it heard from dronewatt (NAMED_VALUE_FLOAT
count, STATUSTEXTs, senders), and pymavlink's signing counters.
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


class Vehicle:
    def __init__(self, a):
        self.a = a
        self.conn = None
        self.recorded = []
        self.heard = {"named_values": 0, "statustexts": [], "senders": set(), "heartbeats": 0}
        self.sig = {"goodsig": 0, "badsig": 0, "unsigned": 0, "reject": 0}
        self.boot0 = time.monotonic()
        self.home_lat = LAT0
        self.stray = mav.MAVLink(None, srcSystem=2, srcComponent=1)
        self.open()

    def open(self):
        if self.conn is not None:
            self.count_signing()
            self.conn.close()
        self.conn = mavutil.mavlink_connection(self.a.to, source_system=1, source_component=1)
        if self.a.sign_key:
            self.conn.setup_signing(bytes.fromhex(self.a.sign_key), sign_outgoing=True, link_id=self.a.link_id)
        # Record every frame written, for the replay phase.
        write = self.conn.write

        def recording(buf):
            if len(self.recorded) < 400:
                self.recorded.append(bytes(buf))
            write(buf)
        self.conn.write = recording

    def count_signing(self):
        s = self.conn.mav.signing
        for k in self.sig:
            self.sig[k] += getattr(s, k + "_count")

    def drain(self):
        while True:
            r = self.conn.recv_match(blocking=False)
            if r is None:
                return
            if r.get_type() == "BAD_DATA":
                continue
            self.heard["senders"].add((r.get_srcSystem(), r.get_srcComponent()))
            t = r.get_type()
            if t == "NAMED_VALUE_FLOAT":
                self.heard["named_values"] += 1
            elif t == "STATUSTEXT":
                self.heard["statustexts"].append(r.text if isinstance(r.text, str) else r.text.decode())
            elif t == "HEARTBEAT":
                self.heard["heartbeats"] += 1

    def wait_until(self, target):
        while True:
            self.drain()
            left = target - time.monotonic()
            if left <= 0:
                return
            fd = getattr(self.conn, "port", None) or getattr(self.conn, "fd", None)
            if fd is not None:
                select.select([fd], [], [], min(left, 0.05))
            else:
                time.sleep(min(left, 0.01))

    def send(self, msg, v1):
        m = self.conn.mav
        if v1:
            buf = msg.pack(m, force_mavlink1=True)
            m.seq = (m.seq + 1) % 256
            self.conn.write(buf)
        else:
            m.send(msg)

    def tick(self, t_flight, v1_phase, stray):
        """One tick's messages; t_flight is seconds since take-off (power profile and path)."""
        boot_ms = int((time.monotonic() - self.boot0) * 1000)
        alt = 25.0 * min(t_flight / 5.0, 1.0)
        speed = 0.0 if t_flight < 5.0 else 10.0
        north = max(0.0, t_flight - 5.0) * 10.0
        lat = self.home_lat + north / 111_320.0
        power = self.a.power_w + 40.0 * math.sin(2 * math.pi * t_flight / 3.0)
        current = power / VOLTS
        msgs = []
        if self.n % 10 == 0:
            msgs.append(mav.MAVLink_heartbeat_message(mav.MAV_TYPE_QUADROTOR, mav.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, mav.MAV_STATE_ACTIVE, 3))
            msgs.append(mav.MAVLink_home_position_message(int(self.home_lat * 1e7), int(LON0 * 1e7), 400_000, 0.0, 0.0, 0.0,
                                                          [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0))
        msgs.append(mav.MAVLink_sys_status_message(0, 0, 0, 500, int(VOLTS * 1000), int(current * 100), -1, 0, 0, 0, 0, 0, 0))
        vz = 5.0 if t_flight < 5.0 else 0.0
        msgs.append(mav.MAVLink_global_position_int_message(boot_ms, int(lat * 1e7), int(LON0 * 1e7), int((400.0 + alt) * 1000),
                                                            int(alt * 1000), int(speed * 100), 0, int(-vz * 100), 0))
        pitch = -0.1 if speed > 0 else 0.0
        msgs.append(mav.MAVLink_attitude_message(boot_ms, 0.0, pitch, 0.0, 0.0, 0.0, 0.0))
        msgs.append(mav.MAVLink_raw_imu_message(boot_ms * 1000, 0, 0, -1000, 0, 0, 0, 0, 0, 0))
        msgs.append(mav.MAVLink_vfr_hud_message(speed, speed, 0, 50, alt, vz))
        msgs.append(mav.MAVLink_wind_message(180.0, 2.0, 0.0))
        for i, m in enumerate(msgs):
            self.send(m, v1_phase and (self.frames + i) % 2 == 1)
        self.frames += len(msgs)
        if stray:
            # Another vehicle on the same link: 2000 W, a different place, its own heartbeat.
            cur2 = 2000.0 / VOLTS
            for m in (mav.MAVLink_heartbeat_message(mav.MAV_TYPE_QUADROTOR, mav.MAV_AUTOPILOT_PX4, 0, 0, mav.MAV_STATE_ACTIVE, 3),
                      mav.MAVLink_sys_status_message(0, 0, 0, 500, int(VOLTS * 1000), int(cur2 * 100), -1, 0, 0, 0, 0, 0, 0),
                      mav.MAVLink_global_position_int_message(boot_ms, int((LAT0 + 0.5) * 1e7), int(LON0 * 1e7), 900000,
                                                              500000, 0, 0, 0, 0)):
                self.conn.write(m.pack(self.stray))
                self.stray.seq = (self.stray.seq + 1) % 256
            self.stray_frames += 3
        self.n += 1

    def run(self, plan):
        self.n, self.frames, self.stray_frames = 0, 0, 0
        t_flight = 0.0
        report = []
        for ph in plan:
            if ph.get("reconnect"):
                self.open()
            if ph.get("reboot"):
                self.conn.mav.seq = 0
                self.boot0 = time.monotonic()
                self.home_lat = LAT0 + 1000.0 / 111_320.0  # a new home 1 km north
                t_flight = 0.0
            start = time.monotonic()
            frames0, heard0 = self.frames, self.heard["named_values"]
            if "quiet_s" in ph:
                self.wait_until(start + ph["quiet_s"])
            else:
                rate = ph.get("rate_hz", 10.0)
                k = 0
                while k / rate <= ph["send_s"]:
                    self.wait_until(start + k / rate)
                    self.tick(t_flight + k / rate, ph.get("v1", False), ph.get("stray", False))
                    k += 1
                t_flight += k / rate
            replayed = 0
            if ph.get("replay"):
                for buf in list(self.recorded[: ph["replay"]]):
                    self.conn.write(buf)
                    replayed += 1
                    time.sleep(0.001)
            report.append({"frames": self.frames - frames0, "replayed": replayed,
                           "heard": self.heard["named_values"] - heard0})
        self.wait_until(time.monotonic() + self.a.listen_after_s)
        self.count_signing()
        self.conn.close()
        h = self.heard
        print(json.dumps({
            "phases": report,
            "frames": self.frames,
            "stray_frames": self.stray_frames,
            "named_values": h["named_values"],
            "statustexts": h["statustexts"],
            "heartbeats": h["heartbeats"],
            "senders": sorted(list(s) for s in h["senders"]),
            "signing": self.sig,
        }), flush=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--to", required=True, help="pymavlink address: udpout:HOST:PORT or tcp:HOST:PORT")
    ap.add_argument("--plan", required=True)
    ap.add_argument("--power-w", type=float, default=500.0)
    ap.add_argument("--sign-key", default=None, help="32-byte key as 64 hex digits")
    ap.add_argument("--link-id", type=int, default=1)
    ap.add_argument("--listen-after-s", type=float, default=1.5)
    a = ap.parse_args()
    Vehicle(a).run(json.loads(a.plan))


if __name__ == "__main__":
    main()
