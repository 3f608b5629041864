#!/usr/bin/env python3
"""A light sender of a recorded log, for tests/it/source_links_fast.rs.

  merge_send.py --log FILE.tlog --ports P1[,P2] --speed 20 --loss 0.3,0.3 --seed 7

It reads the log's frames as they were recorded (their bytes, sequence numbers and
arrival times untouched) and sends each one, at SPEED times the log's own pace, to
127.0.0.1:P1 and to 127.0.0.1:P2 from two UDP sockets, each link dropping a frame with its
own probability, independently (seeded; one port: nothing dropped unless --loss says so).
The sockets block, so a frame the sender means to send is sent, never refused for want of
buffer.

Prints one JSON object, the sender's ledger:
  packed      frames read from the log,
  sent        frames sent on each link,
  union       frames sent on at least one link (what a perfect merge hands on when the
              kernel delivers every datagram),
  both        frames sent on every link (what a perfect merge counts as copies),
  repeats     frames whose (system, component, sequence, message id, payload) equal a
              frame of the same sender among its previous 128: copies inside the log
              itself, which a merge may rightly drop (0 for a simulated log),
  seconds     how long the sending took, fps the frames packed per second of it.
"""
import argparse
import json
import os
import random
import socket
import time

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402


def frames(path):
    """(log time, frame bytes, key) of every frame in a tlog, in order."""
    m = mavutil.mavlink_connection(path, robust_parsing=True)
    out = []
    while True:
        msg = m.recv_msg()
        if msg is None:
            break
        if msg.get_type() == "BAD_DATA":
            continue
        buf = bytes(msg.get_msgbuf())
        h = msg.get_header()
        key = (h.srcSystem, h.srcComponent, h.seq, msg.get_msgId(), bytes(msg.get_payload() or b""))
        out.append((msg._timestamp, buf, key))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--log", required=True)
    ap.add_argument("--ports", required=True)
    ap.add_argument("--speed", type=float, default=20.0)
    ap.add_argument("--loss", default="0,0")
    ap.add_argument("--seed", type=int, default=7)
    a = ap.parse_args()
    ports = [int(p) for p in a.ports.split(",")]
    loss = [float(x) for x in a.loss.split(",")] + [0.0] * len(ports)
    rng = random.Random(a.seed)
    log = frames(a.log)
    # Copies inside the log: the same sender's same numbers and payload within its last 128.
    recent, repeats = {}, 0
    for _, _, key in log:
        sender = key[:2]
        last = recent.setdefault(sender, [])
        if key in last:
            repeats += 1
        last.append(key)
        if len(last) > 128:
            last.pop(0)
    socks = []
    for _ in ports:
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.bind(("127.0.0.1", 0))
        socks.append(s)
    out = {"packed": len(log), "sent": [0] * len(ports), "union": 0, "both": 0, "repeats": repeats}
    t_log0 = log[0][0] if log else 0.0
    t0 = time.monotonic()
    for t_log, buf, _ in log:
        due = t0 + (t_log - t_log0) / a.speed
        left = due - time.monotonic()
        # Sleep only when a millisecond or more ahead: frames due together go out together.
        if left > 0.001:
            time.sleep(left)
        got = 0
        for i, s in enumerate(socks):
            if rng.random() < loss[i]:
                continue
            s.sendto(buf, ("127.0.0.1", ports[i]))
            out["sent"][i] += 1
            got += 1
        out["union"] += got > 0
        out["both"] += got == len(ports)
    out["seconds"] = time.monotonic() - t0
    out["fps"] = len(log) / max(out["seconds"], 1e-9)
    print(json.dumps(out), flush=True)


if __name__ == "__main__":
    main()
