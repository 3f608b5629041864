#!/usr/bin/env python3
"""A vehicle on a live link, from a .tlog: sends each message of the log (pymavlink reads
it) to udpout:127.0.0.1:PORT at the pace the log's own stamps keep (real time), up to
`--until-s` seconds of the log. The vehicle's side of a link a ground station listens to;
it answers nothing (run the listener with --listen-only).

    tlog_udp.py --tlog flight.tlog --port 14550 [--until-s 50]

Prints one JSON line at the end: messages sent and the log seconds they span.
"""
import argparse
import json
import time

from pymavlink import mavutil


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--tlog", required=True)
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--until-s", type=float, default=float("inf"))
    a = ap.parse_args()
    log = mavutil.mavlink_connection(a.tlog)
    out = mavutil.mavlink_connection(f"udpout:127.0.0.1:{a.port}", source_system=1, source_component=1)
    t0 = wall0 = None
    sent, span = 0, 0.0
    while True:
        m = log.recv_match()
        if m is None:
            break
        if m.get_type() == "BAD_DATA":
            continue
        if t0 is None:
            t0, wall0 = m._timestamp, time.monotonic()
        span = m._timestamp - t0
        if span > a.until_s:
            break
        wait = wall0 + span - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        out.write(m.get_msgbuf())
        sent += 1
    print(json.dumps(dict(sent=sent, span_s=round(span, 2))))


if __name__ == "__main__":
    main()
