#!/usr/bin/env python3
"""Feed for scripts/soak.sh: writes a .tlog (the demo flight, looped) to OUT — a FIFO that
`dronewatt replay` reads — until FLIGHT_S seconds of flight time have been written.

Every loop's record stamps are shifted so the clock runs on without a jump (one second of
quiet between loops, below the 60-s clock-jump threshold). Writing blocks when the reader
is behind, so the replay paces the feed, never the other way round. Standard library only.

  soak_feed.py DEMO.tlog OUT FLIGHT_S      prints {"loops", "records", "flight_s"} at the end
"""
import json
import struct
import sys


def records(path):
    """(stamp_us, frame bytes) of every record of a well-formed tlog."""
    data = open(path, "rb").read()
    out, i = [], 0
    while i + 9 < len(data):
        stamp = struct.unpack(">Q", data[i:i + 8])[0]
        stx = data[i + 8]
        if stx == 0xFE:
            n = 6 + data[i + 9] + 2
        elif stx == 0xFD:
            n = 10 + data[i + 9] + 2 + (13 if data[i + 10] & 1 else 0)
        else:
            raise SystemExit(f"{path}: byte {i + 8} is not a frame start: the soak needs a clean tlog")
        out.append((stamp, data[i + 8:i + 8 + n]))
        i += 8 + n
    return out


def main():
    demo, out_path, flight_s = sys.argv[1], sys.argv[2], float(sys.argv[3])
    recs = records(demo)
    t0 = recs[0][0]
    span_us = recs[-1][0] - t0 + 1_000_000
    loops, written = 0, 0
    try:
        with open(out_path, "wb", buffering=1 << 20) as f:
            while loops * span_us < flight_s * 1e6:
                off = loops * span_us - t0 + 1_700_000_000_000_000
                f.write(b"".join(struct.pack(">Q", s + off) + fr for s, fr in recs))
                loops += 1
                written += len(recs)
    except BrokenPipeError:
        pass  # the replay was stopped (the soak's clock ran out, or Ctrl-C)
    print(json.dumps({"loops": loops, "records": written, "flight_s": loops * span_us / 1e6}), flush=True)


if __name__ == "__main__":
    main()
