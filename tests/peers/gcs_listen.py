#!/usr/bin/env python3
"""An independent ground station (pymavlink) that only listens.

Binds udpin on 127.0.0.1 (port 0: the OS picks), prints `PORT <n>` on stdout, then
collects what dronewatt sends: NAMED_VALUE_FLOAT, STATUSTEXT, HEARTBEAT. It stops after
`--idle-s` without a frame (once something arrived) or `--max-s`, and prints one JSON
summary line. The Rust test asserts on that summary.
"""
import argparse
import json
import sys
import time

from pymavlink import mavutil


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--idle-s", type=float, default=2.0)
    ap.add_argument("--max-s", type=float, default=20.0)
    a = ap.parse_args()
    conn = mavutil.mavlink_connection("udpin:127.0.0.1:0", source_system=255, source_component=190)
    print("PORT", conn.port.getsockname()[1], flush=True)
    values, texts, heartbeats, senders = {}, [], 0, set()
    start = last = time.monotonic()
    got_any = False
    while True:
        now = time.monotonic()
        if now - start > a.max_s or (got_any and now - last > a.idle_s):
            break
        m = conn.recv_match(blocking=True, timeout=0.2)
        if m is None or m.get_type() == "BAD_DATA":
            continue
        got_any, last = True, time.monotonic()
        senders.add((m.get_srcSystem(), m.get_srcComponent()))
        t = m.get_type()
        if t == "NAMED_VALUE_FLOAT":
            name = m.name.rstrip("\x00") if isinstance(m.name, str) else m.name.decode().rstrip("\x00")
            values.setdefault(name, []).append(m.value)
        elif t == "STATUSTEXT":
            text = m.text.rstrip("\x00") if isinstance(m.text, str) else m.text.decode().rstrip("\x00")
            texts.append({"severity": m.severity, "text": text})
        elif t == "HEARTBEAT":
            heartbeats += 1
    print(json.dumps({
        "values": values,
        "statustexts": texts,
        "heartbeats": heartbeats,
        "senders": sorted(list(s) for s in senders),
    }), flush=True)


if __name__ == "__main__":
    sys.exit(main())
