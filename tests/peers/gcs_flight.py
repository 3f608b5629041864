#!/usr/bin/env python3
"""An independent ground station (pymavlink) that plays an autopilot streaming a flight to
`dronewatt monitor udpin:127.0.0.1:PORT`, and listens on the same socket for what dronewatt
answers (NAMED_VALUE_FLOAT, STATUSTEXT, HEARTBEAT).

The flight is synthetic and fully controlled: take-off to 25 m, then a straight cruise
away from home at 10 m/s, with a power profile of `--power-w` (± a 3 s oscillation of
40 W) at 22.2 V. At 10 Hz it sends what ArduPilot sends by default (HEARTBEAT, SYS_STATUS,
BATTERY_STATUS, GLOBAL_POSITION_INT, ATTITUDE, VFR_HUD, RAW_IMU, SCALED_IMU2, WIND,
HOME_POSITION) plus ATTITUDE_QUATERNION and HIGHRES_IMU. battery_remaining is -1
(unknown) so dronewatt's energy comes from integrating V·I against its configured capacity.

Prints one JSON summary line at the end: what it heard, and for each NAMED_VALUE_FLOAT
`dw_meas_w` the delay since the latest SYS_STATUS was sent (an upper bound on ingest →
publish latency plus the resampler's grid wait), the time this script takes to send one
tick's messages, and the delay since the tick's last message was sent.
"""
import argparse
import json
import math
import select
import time

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mav


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--seconds", type=float, default=15.0)
    ap.add_argument("--rate-hz", type=float, default=10.0)
    ap.add_argument("--power-w", type=float, default=500.0)
    ap.add_argument("--listen-after-s", type=float, default=2.0)
    a = ap.parse_args()
    conn = mavutil.mavlink_connection(f"udpout:127.0.0.1:{a.port}", source_system=1, source_component=1)
    m = conn.mav
    lat0, lon0 = 47.3977419, 8.5455938
    values, texts, heartbeats, senders, delays, send_ms, end_delays = {}, [], 0, set(), [], [], []
    last_tick_end = None
    last_sys_status = None
    volts = 22.2
    start = time.monotonic()
    n = 0

    def drain():
        nonlocal heartbeats
        while True:
            r = conn.recv_match(blocking=False)
            if r is None:
                return
            if r.get_type() == "BAD_DATA":
                continue
            senders.add((r.get_srcSystem(), r.get_srcComponent()))
            t = r.get_type()
            if t == "NAMED_VALUE_FLOAT":
                name = r.name.rstrip("\x00") if isinstance(r.name, str) else r.name.decode().rstrip("\x00")
                values.setdefault(name, []).append(r.value)
                if name == "dw_meas_w" and last_sys_status is not None:
                    delays.append(time.monotonic() - last_sys_status)
                    if last_tick_end is not None and last_tick_end > last_sys_status:
                        end_delays.append(time.monotonic() - last_tick_end)
            elif t == "STATUSTEXT":
                text = r.text.rstrip("\x00") if isinstance(r.text, str) else r.text.decode().rstrip("\x00")
                texts.append({"severity": r.severity, "text": text, "t": time.monotonic() - start})
            elif t == "HEARTBEAT":
                heartbeats += 1

    while True:
        t = n / a.rate_hz
        if t > a.seconds:
            break
        target = start + t
        while time.monotonic() < target:
            drain()
            # Wake the moment a frame arrives, so the delays below are not our polling.
            select.select([conn.port], [], [], max(0.0, target - time.monotonic()))
        boot_ms = int(t * 1000)
        climb = min(t / 5.0, 1.0)
        alt = 25.0 * climb
        speed = 0.0 if t < 5.0 else 10.0
        north = max(0.0, t - 5.0) * 10.0
        lat = lat0 + north / 111_320.0
        power = a.power_w + 40.0 * math.sin(2 * math.pi * t / 3.0)
        current = power / volts
        if n % int(a.rate_hz) == 0:
            m.heartbeat_send(mav.MAV_TYPE_QUADROTOR, mav.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, mav.MAV_STATE_ACTIVE)
            m.home_position_send(int(lat0 * 1e7), int(lon0 * 1e7), 0, 0.0, 0.0, 0.0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0)
        m.sys_status_send(0, 0, 0, 500, int(volts * 1000), int(current * 100), -1, 0, 0, 0, 0, 0, 0)
        last_sys_status = time.monotonic()
        cells = [int(volts * 1000 / 6)] * 6 + [65535] * 4
        m.battery_status_send(0, 0, 0, 2500, cells, int(current * 100), -1, -1, -1)
        vz = 5.0 if t < 5.0 else 0.0  # climb rate, m/s up
        m.global_position_int_send(boot_ms, int(lat * 1e7), int(lon0 * 1e7), int((400.0 + alt) * 1000),
                                   int(alt * 1000), int(speed * 100), 0, int(-vz * 100), 0)
        pitch = -0.1 if speed > 0 else 0.0
        m.attitude_send(boot_ms, 0.0, pitch, 0.0, 0.0, 0.0, 0.0)
        cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
        m.attitude_quaternion_send(boot_ms, cp, 0.0, sp, 0.0, 0.0, 0.0, 0.0)
        m.vfr_hud_send(speed, speed, 0, 50, alt, vz)
        m.raw_imu_send(boot_ms * 1000, 0, 0, -1000, 0, 0, 0, 0, 0, 0)
        m.scaled_imu2_send(boot_ms, 0, 0, -1000, 0, 0, 0, 0, 0, 0)
        m.highres_imu_send(boot_ms * 1000, 0.0, 0.0, -9.81, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1013.0, 0.0, 0.0, 20.0, 0x1FF)
        m.wind_send(180.0, 2.0, 0.0)
        last_tick_end = time.monotonic()
        send_ms.append(1000 * (last_tick_end - last_sys_status))
        n += 1

    end = time.monotonic() + a.listen_after_s
    while time.monotonic() < end:
        drain()
        select.select([conn.port], [], [], max(0.0, end - time.monotonic()))
    delays.sort()
    end_delays.sort()
    send_ms.sort()
    print(json.dumps({
        "values": values,
        "statustexts": texts,
        "heartbeats": heartbeats,
        "senders": sorted(list(s) for s in senders),
        "delay_p50_ms": 1000 * delays[len(delays) // 2] if delays else None,
        "delay_p99_ms": 1000 * delays[int(len(delays) * 0.99)] if delays else None,
        "delays": len(delays),
        "tick_send_p50_ms": send_ms[len(send_ms) // 2] if send_ms else None,
        "after_tick_end_p50_ms": 1000 * end_delays[len(end_delays) // 2] if end_delays else None,
        "after_tick_end_p99_ms": 1000 * end_delays[int(len(end_delays) * 0.99)] if end_delays else None,
    }), flush=True)


if __name__ == "__main__":
    main()
