#!/usr/bin/env python3
"""Write a `.tlog` (pymavlink's encoder, 8-byte big-endian µs stamps) of an ArduCopter
hovering on a 3S pack: a ground station's parameter fetch logged near the start
(PARAM_VALUE BATT_CAPACITY = 3300 mAh, cast to float as ArduPilot sends it, plus
BATT_LOW_VOLT), then `--seconds` of flight at `--power-w` and 12.4 V with
battery_remaining -1 (unknown), at 10 Hz.

`--no-params` leaves the PARAM_VALUE messages out (the same flight, nothing said about the
pack).
"""
import argparse
import struct

from pymavlink.dialects.v20 import ardupilotmega as mav


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", required=True)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--power-w", type=float, default=150.0)
    ap.add_argument("--no-params", action="store_true")
    a = ap.parse_args()
    m = mav.MAVLink(None, srcSystem=1, srcComponent=1)
    t0_us = 1_700_000_000_000_000
    volts = 12.4
    with open(a.out, "wb") as f:
        def put(t_s, msg):
            f.write(struct.pack(">Q", t0_us + int(t_s * 1e6)) + msg.pack(m))

        n = 0
        while n / 10.0 <= a.seconds:
            t = n / 10.0
            boot_ms = int(t * 1000)
            if n % 10 == 0:
                put(t, mav.MAVLink_heartbeat_message(mav.MAV_TYPE_QUADROTOR, mav.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, mav.MAV_STATE_ACTIVE, 3))
            if n == 5 and not a.no_params:
                put(t, mav.MAVLink_param_value_message(b"BATT_CAPACITY", 3300.0, mav.MAV_PARAM_TYPE_INT32, 900, 10))
                put(t, mav.MAVLink_param_value_message(b"BATT_LOW_VOLT", 10.5, mav.MAV_PARAM_TYPE_REAL32, 900, 11))
            current = a.power_w / volts
            put(t, mav.MAVLink_sys_status_message(0, 0, 0, 500, int(volts * 1000), int(current * 100), -1, 0, 0, 0, 0, 0, 0))
            put(t, mav.MAVLink_global_position_int_message(boot_ms, int(47.3977419e7), int(8.5455938e7), 410_000, 10_000, 0, 0, 0, 0))
            put(t, mav.MAVLink_attitude_message(boot_ms, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
            put(t, mav.MAVLink_raw_imu_message(boot_ms * 1000, 0, 0, -1000, 0, 0, 0, 0, 0, 0))
            put(t, mav.MAVLink_vfr_hud_message(0.0, 0.0, 0, 40, 10.0, 0.0))
            n += 1


if __name__ == "__main__":
    main()
