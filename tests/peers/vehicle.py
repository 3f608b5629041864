#!/usr/bin/env python3
"""A scripted pymavlink vehicle for dronewatt's link-fault and signing tests.

It flies a fixed, fully known flight (climb from a home at 400 m above sea level to 25 m
above it in 5 s, then cruise north at 10 m/s, 500 W ± 40 W
at 22.2 V, battery_remaining unknown) to `dronewatt monitor`, in phases given as JSON:

  vehicle.py --to udpout:127.0.0.1:PORT --plan '[{"send_s": 6}, {"quiet_s": 10}, {"send_s": 6}]'

Phase keys (all optional but one of send_s / quiet_s):
  ground      on the ground, motors idle (2 W), not moving: the pack rests
  send_s      stream telemetry this long          quiet_s   send nothing this long (still listen)
  rate_hz     ticks per second (10)               v1        every other frame MAVLink 1 (else all 2)
  reboot      before this phase: sequence numbers restart at 0, time_boot_ms at 0, a new home 1 km north
  reconnect   before this phase: close the connection and open a new one (UDP: a new source port)
  stray       a second vehicle (system 2, 2000 W) interleaves its own telemetry
  replay      at the end of this phase, send again the first N frames it recorded (signing tests)

--pack '{"cells": 3, "wh": 4, "rest_v": 11.45, "r0": 0.08, "r1": 0.05, "tau_s": 10}' flies a sagging pack
instead of the fixed 22.2 V: a LiPo with its own OCV table, a series resistance and one RC pair,
the current solved from the power each tick (P = V·I); the voltage falls as the pack drains.

--progpy '{"cell": "electrochem", "s": 3, "p": 1, "soc0": 0.3}' flies a NASA ProgPy pack instead: S cells in
series and P in parallel of BatteryElectroChemEOD (or BatteryCircuit), discharged from full to soc0 of its energy
and rested 30 min before the first frame (tests/peers/progpy_flights.py's cell).

--mav-type N sends HEARTBEAT type N (12 a submarine, 1 a plane, 99 a type MAVLink does not
define); --no-battery sends SYS_STATUS without voltage or current (no battery monitor);
--vtol-fw-after-s T flies an ArduPlane quadplane (Q mode and vtol_state MC, then FW after T s);
--tlog PATH also writes every frame sent to a telemetry log, for replay tests.
--params '{"BATT_LOW_VOLT": 10.5}' answers PARAM_REQUEST_READ for those parameters (REAL32).
--pack-serial S sends BATTERY_INFO (battery 0, serial_number S) with each heartbeat: the pack's
identity (pymavlink's dialects here lack message 372, so it is packed by hand: BatteryInfo).

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
import struct
import time

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402
from pymavlink.dialects.v20 import ardupilotmega as mav  # noqa: E402

LAT0, LON0 = 47.3977419, 8.5455938
VOLTS = 22.2

# A LiPo cell's resting voltage against its state of charge (the common hobby table).
LIPO = [(3.27, 0.0), (3.61, 0.05), (3.69, 0.10), (3.73, 0.20), (3.77, 0.30), (3.80, 0.40), (3.84, 0.50),
        (3.87, 0.60), (3.91, 0.65), (3.95, 0.70), (4.02, 0.80), (4.08, 0.85), (4.11, 0.90), (4.20, 1.00)]


def interp(x, xs, ys):
    if x <= xs[0]:
        return ys[0]
    for (x0, y0), (x1, y1) in zip(zip(xs, ys), zip(xs[1:], ys[1:])):
        if x <= x1:
            return y0 + (x - x0) / (x1 - x0) * (y1 - y0)
    return ys[-1]


class BatteryInfo(mav.MAVLink_message):
    """MAVLink common BATTERY_INFO (372; crc_extra 26, 140-byte payload in wire order), which this
    pymavlink's dialects do not define: battery 0, a 6S LiHV pack, the given serial."""

    msg_id, crc = 372, 26

    def __init__(self, serial):
        mav.MAVLink_message.__init__(self, BatteryInfo.msg_id, "BATTERY_INFO")
        self._fieldnames = ["serial_number"]
        self.serial_number = serial

    def pack(self, m, force_mavlink1=False):
        nan = float("nan")
        payload = struct.pack("<10f2H5B9s32s50s",
                              3.3, 0, 3.8, 4.35, 0, 22.8, 0, 0, 5.7, nan,  # V, A, Ah (NAN: not given)
                              65535, 0,                                   # cycle count unknown, weight
                              0, 0, 0, 255, 6,                            # id, function, type, SoH unknown, cells
                              b"", self.serial_number.encode(), b"Test_Pack")
        return self._pack(m, BatteryInfo.crc, payload, force_mavlink1=force_mavlink1)


class Pack:
    """A sagging pack: OCV(SoC) − R0·I − x1, dx1/dt = (R1·I − x1)/τ, SoC counted in energy."""

    def __init__(self, cells, wh, rest_v, r0, r1, tau_s):
        self.cells, self.wh, self.r0, self.r1, self.tau = cells, wh, r0, r1, tau_s
        self.soc = interp(rest_v / cells, [v for v, _ in LIPO], [s for _, s in LIPO])
        self.x1 = 0.0

    def ocv(self):
        return self.cells * interp(self.soc, [s for _, s in LIPO], [v for v, _ in LIPO])

    def draw(self, power, dt):
        c = self.ocv() - self.x1
        disc = max(c * c - 4.0 * self.r0 * power, 0.0)
        amps = (c - math.sqrt(disc)) / (2.0 * self.r0)
        volts = c - self.r0 * amps
        self.x1 += dt / self.tau * (self.r1 * amps - self.x1)
        self.soc = max(self.soc - volts * amps * dt / 3600.0 / self.wh, 0.0)
        return volts, amps


class ProgPyPack:
    """A ProgPy pack (tests/peers/progpy_flights.py's Cell): the current solved from the power each tick."""

    def __init__(self, cell="electrochem", s=3, p=1, soc0=0.3):
        import sys
        sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
        import progpy_flights as pf
        self.s, self.p = s, p
        self.cell = pf.charged_to(cell, soc0)
        for _ in range(1800):
            self.cell.step(0.0, 1.0)

    def draw(self, power, dt):
        amps = power / (self.s * self.p) / max(self.cell.v, 1.0)
        for _ in range(max(1, int(round(dt / 0.1)))):
            self.cell.step(amps, dt / max(1, int(round(dt / 0.1))))
        return self.cell.v * self.s, amps * self.p


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
        self.pack = (Pack(**json.loads(a.pack)) if a.pack else
                     ProgPyPack(**json.loads(a.progpy)) if a.progpy else None)
        self.params = json.loads(a.params) if a.params else {}
        self.tlog = open(a.tlog, "wb") if a.tlog else None
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
            if self.tlog is not None:
                # A telemetry log as ground stations write it: big-endian µs since the epoch, then the frame.
                self.tlog.write(struct.pack(">Q", int(time.time() * 1e6)) + bytes(buf))
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
            elif t == "PARAM_REQUEST_READ" and self.params:
                # --params: answer a read of a parameter it has, as ArduPilot does (REAL32)
                name = r.param_id if isinstance(r.param_id, str) else r.param_id.decode()
                if name in self.params:
                    i = list(self.params).index(name)
                    self.conn.mav.param_value_send(name.encode(), float(self.params[name]),
                                                   mav.MAV_PARAM_TYPE_REAL32, len(self.params), i)

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

    def tick(self, t_flight, v1_phase, stray, ground=False, dt=0.1):
        """One tick's messages; t_flight is seconds since take-off (power profile and path)."""
        boot_ms = int((time.monotonic() - self.boot0) * 1000)
        alt = 25.0 * min(t_flight / 5.0, 1.0)
        speed = 0.0 if t_flight < 5.0 else 10.0
        north = max(0.0, t_flight - 5.0) * 10.0
        lat = self.home_lat + north / 111_320.0
        power = 2.0 if ground else self.a.power_w + self.a.power_swing_w * math.sin(2 * math.pi * t_flight / 3.0)
        volts, current = self.pack.draw(power, dt) if self.pack else (VOLTS, power / VOLTS)
        msgs = []
        vtol = self.a.vtol_fw_after_s
        custom_mode = 0
        if vtol is not None:
            # An ArduPlane quadplane: QHOVER (18) on its lift rotors, then AUTO (10) on the wing,
            # with a one-second transition between (EXTENDED_SYS_STATE says which, every tick).
            state = (mav.MAV_VTOL_STATE_MC if t_flight < vtol else
                     mav.MAV_VTOL_STATE_TRANSITION_TO_FW if t_flight < vtol + 1.0 else mav.MAV_VTOL_STATE_FW)
            custom_mode = 18 if state == mav.MAV_VTOL_STATE_MC else 10
            msgs.append(mav.MAVLink_extended_sys_state_message(state, mav.MAV_LANDED_STATE_IN_AIR))
        if self.n % 10 == 0 or (vtol is not None and abs(t_flight - vtol) < dt / 2):
            msgs.append(mav.MAVLink_heartbeat_message(self.a.mav_type, mav.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, custom_mode,
                                                      mav.MAV_STATE_ACTIVE, 3))
            if self.a.pack_serial is not None:
                msgs.append(BatteryInfo(self.a.pack_serial))
            msgs.append(mav.MAVLink_home_position_message(int(self.home_lat * 1e7), int(LON0 * 1e7), 400_000, 0.0, 0.0, 0.0,
                                                          [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0))
        if self.a.no_battery:
            # No battery monitor: voltage unknown (UINT16_MAX), current unknown (-1).
            msgs.append(mav.MAVLink_sys_status_message(0, 0, 0, 500, 65535, -1, -1, 0, 0, 0, 0, 0, 0))
        else:
            msgs.append(mav.MAVLink_sys_status_message(0, 0, 0, 500, int(volts * 1000), int(current * 100), -1, 0, 0, 0, 0, 0, 0))
        vz = 0.0 if ground else (5.0 if t_flight < 5.0 else 0.0)
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
                    ground = ph.get("ground", False)
                    self.tick(t_flight + (0 if ground else k / rate), ph.get("v1", False), ph.get("stray", False), ground, 1.0 / rate)
                    k += 1
                if not ph.get("ground", False):
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
        if self.tlog is not None:
            self.tlog.close()
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
    ap.add_argument("--power-swing-w", type=float, default=40.0, help="amplitude of the power's 3 s swing")
    ap.add_argument("--sign-key", default=None, help="32-byte key as 64 hex digits")
    ap.add_argument("--link-id", type=int, default=1)
    ap.add_argument("--pack", default=None, help="JSON: fly a sagging pack (see the module docs)")
    ap.add_argument("--progpy", default=None, help="JSON: fly a NASA ProgPy pack (see the module docs)")
    ap.add_argument("--listen-after-s", type=float, default=1.5)
    ap.add_argument("--mav-type", type=int, default=mav.MAV_TYPE_QUADROTOR,
                    help="HEARTBEAT type (MAV_TYPE number; any 0-255, defined or not)")
    ap.add_argument("--params", default=None, help='JSON {"BATT_LOW_VOLT": 10.5, …}: parameters it answers reads of')
    ap.add_argument("--pack-serial", default=None, help="send BATTERY_INFO with this serial_number")
    ap.add_argument("--no-battery", action="store_true", help="send no voltage or current (no battery monitor)")
    ap.add_argument("--tlog", default=None, help="also write every frame sent to this telemetry log (.tlog)")
    ap.add_argument("--vtol-fw-after-s", type=float, default=None,
                    help="a quadplane: QHOVER and vtol_state MC until this many seconds of flight, then a 1 s transition, then AUTO and FW")
    a = ap.parse_args()
    Vehicle(a).run(json.loads(a.plan))


if __name__ == "__main__":
    main()
