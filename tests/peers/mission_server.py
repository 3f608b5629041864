#!/usr/bin/env python3
"""A pymavlink ArduPilot-style vehicle that serves its mission over the MAVLink mission
protocol to `dronewatt monitor`, for tests/it/mission_protocol.rs.

  mission_server.py --to udpout:127.0.0.1:PORT --seconds 12 --drop-seq 2 --change-at 6

It streams telemetry at 10 Hz (HEARTBEAT and MISSION_CURRENT at 1 Hz, SYS_STATUS 500 W at
22.2 V, GLOBAL_POSITION_INT climbing to 25 m over home then flying north at 10 m/s, ATTITUDE,
RAW_IMU, VFR_HUD) and answers the mission protocol as ArduPilot does: item 0 is home
(absolute altitude), then TAKEOFF, WAYPOINT, DO_SET_CAM_TRIGG_DIST (a command dronewatt does
not model), WAYPOINT, RETURN_TO_LAUNCH. The first MISSION_REQUEST_INT for --drop-seq is
ignored (a lost request: the client must send it again). At --change-at seconds the mission
changes (one more waypoint: MISSION_CURRENT's total goes up), which must make the client
download it again.

Prints one JSON object: every MISSION_REQUEST_LIST and MISSION_REQUEST_INT heard (time,
seq), the dropped request, the MISSION_ACKs (type), the NAMED_VALUE_FLOATs heard (last
value per name), the BATTERY_STATUS frames heard (id, time_remaining, battery_remaining)
every sender heard, and every frame from component 191 ([system, sequence, type], in
arrival order).
"""
import argparse
import json
import os
import select
import time

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402
from pymavlink.dialects.v20 import ardupilotmega as mav  # noqa: E402

LAT0, LON0, HOME_AMSL = 47.3977419, 8.5455938, 400.0
VOLTS, POWER_W = 22.2, 500.0
M_PER_DEG = 111_320.0


def mission(extra):
    """(frame, command, p1, lat, lon, alt) rows; row 0 is home."""
    north = lambda m: LAT0 + m / M_PER_DEG  # noqa: E731
    rows = [
        (0, 16, 0, LAT0, LON0, HOME_AMSL),                         # home
        (3, 22, 0, 0.0, 0.0, 25.0),                                # TAKEOFF
        (3, 16, 0, north(500), LON0, 25.0),                        # WAYPOINT
        (2, 206, 25, 0.0, 0.0, 0.0),                               # DO_SET_CAM_TRIGG_DIST
        (3, 16, 5, north(500), LON0 + 300 / (M_PER_DEG * 0.676), 25.0),
    ]
    if extra:
        rows.append((3, 16, 0, north(800), LON0, 30.0))
    rows.append((3, 20, 0, 0.0, 0.0, 0.0))                          # RETURN_TO_LAUNCH
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--to", required=True)
    ap.add_argument("--seconds", type=float, default=12.0)
    ap.add_argument("--drop-seq", type=int, default=2)
    ap.add_argument("--change-at", type=float, default=None)
    a = ap.parse_args()

    conn = mavutil.mavlink_connection(a.to, source_system=1, source_component=1)
    m = conn.mav
    heard = {"request_list": [], "requests": [], "dropped": [], "acks": [], "named": {}, "battery": [], "senders": set(),
             "from_191": []}
    boot0 = time.monotonic()
    changed = False
    rows = mission(False)
    dropped = False

    def serve(r, t):
        nonlocal dropped
        heard["senders"].add((r.get_srcSystem(), r.get_srcComponent()))
        k = r.get_type()
        # Every frame from dronewatt's identity (component 191), in arrival order.
        if r.get_srcComponent() == 191:
            heard["from_191"].append([r.get_srcSystem(), r.get_seq(), k])
        if k == "MISSION_REQUEST_LIST":
            heard["request_list"].append(round(t, 3))
            m.mission_count_send(r.get_srcSystem(), r.get_srcComponent(), len(rows), 0)
        elif k in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            heard["requests"].append([round(t, 3), r.seq])
            if r.seq == a.drop_seq and not dropped:
                dropped = True
                heard["dropped"].append(r.seq)
                return
            if r.seq < len(rows):
                frame, cmd, p1, lat, lon, alt = rows[r.seq]
                m.mission_item_int_send(r.get_srcSystem(), r.get_srcComponent(), r.seq, frame, cmd, 0, 1,
                                        p1, 0, 0, 0, int(round(lat * 1e7)), int(round(lon * 1e7)), alt, 0)
        elif k == "MISSION_ACK":
            heard["acks"].append(r.type)
        elif k == "NAMED_VALUE_FLOAT":
            name = r.name if isinstance(r.name, str) else r.name.decode()
            heard["named"][name] = r.value
        elif k == "BATTERY_STATUS":
            heard["battery"].append([r.id, r.time_remaining, r.battery_remaining])

    def drain(until):
        while True:
            while True:
                r = conn.recv_match(blocking=False)
                if r is None:
                    break
                if r.get_type() != "BAD_DATA":
                    serve(r, time.monotonic() - boot0)
            left = until - time.monotonic()
            if left <= 0:
                return
            select.select([conn.port], [], [], min(left, 0.02))

    n = 0
    while n / 10.0 <= a.seconds:
        t = n / 10.0
        drain(boot0 + t)
        if a.change_at is not None and t >= a.change_at and not changed:
            changed = True
            rows = mission(True)
        boot_ms = int(t * 1000)
        alt = 25.0 * min(t / 5.0, 1.0)
        speed = 0.0 if t < 5.0 else 10.0
        lat = LAT0 + max(0.0, t - 5.0) * 10.0 / M_PER_DEG
        if n % 10 == 0:
            m.heartbeat_send(mav.MAV_TYPE_QUADROTOR, mav.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 3, mav.MAV_STATE_ACTIVE, 3)
            # total excludes ArduPilot's home item
            m.mission_current_send(1 if t < 5.0 else 2, len(rows) - 1, 0, 0)
        m.sys_status_send(0, 0, 0, 500, int(VOLTS * 1000), int(POWER_W / VOLTS * 100), -1, 0, 0, 0, 0, 0, 0)
        m.global_position_int_send(boot_ms, int(lat * 1e7), int(LON0 * 1e7), int((HOME_AMSL + alt) * 1000), int(alt * 1000),
                                   int(speed * 100), 0, int((-5.0 if t < 5.0 else 0.0) * 100), 0)
        m.attitude_send(boot_ms, 0.0, -0.1 if speed else 0.0, 0.0, 0.0, 0.0, 0.0)
        m.raw_imu_send(boot_ms * 1000, 0, 0, -1000, 0, 0, 0, 0, 0, 0)
        m.vfr_hud_send(speed, speed, 0, 50, alt, 0.0)
        n += 1
    drain(time.monotonic() + 1.0)
    conn.close()
    heard["senders"] = sorted(list(s) for s in heard["senders"])
    heard["items_final"] = len(rows)
    print(json.dumps(heard), flush=True)


if __name__ == "__main__":
    main()
