#!/usr/bin/env python3
"""pymavlink peer for dronewatt's tests: the independent MAVLink implementation.

  mav_peer.py tlog OUT N          write a .tlog of N records (v1, v2 and signed v2 mixed)
  mav_peer.py send ADDRESS N      send N messages to ADDRESS (pymavlink address syntax),
                                  then wait up to 3 s for any frame back
  mav_peer.py gcs ADDRESS N       listen on ADDRESS until a HEARTBEAT from a GCS arrives,
                                  then send N messages back to its sender

Each prints one JSON object on stdout with what it did.
"""
import json
import os
import struct
import sys
import time

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402
from pymavlink.dialects.v10 import ardupilotmega as v1  # noqa: E402
from pymavlink.dialects.v20 import ardupilotmega as v2  # noqa: E402

T0_US = 1_714_564_800_000_000


def messages(mod, i):
    """The i-th message of a small autopilot-like mix."""
    t_ms = i * 100
    k = i % 4
    if k == 0:
        return mod.MAVLink_attitude_message(t_ms, 0.01 * i, -0.1, 1.0, 0.0, 0.01, 0.0)
    if k == 1:
        return mod.MAVLink_sys_status_message(0, 0, 0, 300, 22800 - i, 1050, 0, 0, 0, 0, 0, 0, 80)
    if k == 2:
        return mod.MAVLink_global_position_int_message(t_ms, 404433000 + i, -799436000, 300000, 25000, 800, -120, 5, 0)
    return mod.MAVLink_heartbeat_message(2, 3, 81, 10, 4, 3)


def cmd_tlog(out, n):
    m1 = v1.MAVLink(None, srcSystem=1, srcComponent=1)
    m2 = v2.MAVLink(None, srcSystem=1, srcComponent=1)
    m2s = v2.MAVLink(None, srcSystem=1, srcComponent=1)
    m2s.signing.secret_key = bytes(range(32))
    m2s.signing.link_id = 3
    m2s.signing.timestamp = 1
    m2s.signing.sign_outgoing = True
    counts = {"v1": 0, "v2": 0, "signed": 0}
    seq = 0
    with open(out, "wb") as f:
        for i in range(n):
            kind = ("v1", "v2", "signed")[i % 3]
            mav = {"v1": m1, "v2": m2, "signed": m2s}[kind]
            mod = v1 if kind == "v1" else v2
            mav.seq = seq  # one sequence across all three encoders, as one sender
            buf = messages(mod, i).pack(mav)
            seq = (seq + 1) % 256
            f.write(struct.pack(">Q", T0_US + i * 100_000) + buf)
            counts[kind] += 1
    print(json.dumps({"records": n, **counts}))


def cmd_send(address, n):
    conn = mavutil.mavlink_connection(address, source_system=1, source_component=1)
    for i in range(n):
        conn.mav.send(messages(v2, i))
        time.sleep(0.002)
    got = None
    deadline = time.time() + 3
    while time.time() < deadline and got is None:
        m = conn.recv_match(blocking=True, timeout=0.2)
        if m is not None and m.get_type() != "BAD_DATA":
            got = {"type": m.get_type(), "sysid": m.get_srcSystem(), "compid": m.get_srcComponent()}
        elif n > 0 and got is None:
            # Keep the link warm so a udpin peer knows where to answer.
            conn.mav.heartbeat_send(2, 3, 81, 10, 4, 3)
    print(json.dumps({"sent": n, "reply": got}))


def cmd_gcs(address, n):
    conn = mavutil.mavlink_connection(address, source_system=1, source_component=1)
    hb = None
    deadline = time.time() + 10
    while time.time() < deadline:
        m = conn.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5)
        if m is not None:
            hb = {"sysid": m.get_srcSystem(), "compid": m.get_srcComponent(), "type": m.type}
            break
    if hb is not None:
        for i in range(n):
            conn.mav.send(messages(v2, i))
            time.sleep(0.002)
    print(json.dumps({"heartbeat": hb, "sent": n if hb else 0}))


if __name__ == "__main__":
    cmd, *args = sys.argv[1:]
    {"tlog": cmd_tlog, "send": cmd_send, "gcs": cmd_gcs}[cmd](args[0], int(args[1]))
