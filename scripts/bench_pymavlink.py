#!/usr/bin/env python3
"""pymavlink's side of the parse benchmark (benches/parse.rs writes the file).

    cargo bench --bench parse          # writes target/bench-parse.tlog, prints Rust's time
    .venv-py/bin/python scripts/bench_pymavlink.py target/bench-parse.tlog [REPEATS]

Times pymavlink 2.4.50's `recv_match()` loop over the whole .tlog (timestamps parsed, as
`mavutil.mavlink_connection` does for a .tlog) REPEATS times and prints the median
messages per second. Compare with criterion's median for `parse_tlog/decode_tlog_100k`.
"""
import os
import statistics
import sys
import time

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402


def once(path):
    m = mavutil.mavlink_connection(path, dialect="ardupilotmega")
    n = 0
    t0 = time.perf_counter()
    while True:
        msg = m.recv_match()
        if msg is None:
            break
        n += 1
    dt = time.perf_counter() - t0
    m.close()
    return n, dt


def main():
    path = sys.argv[1] if len(sys.argv) > 1 else "target/bench-parse.tlog"
    repeats = int(sys.argv[2]) if len(sys.argv) > 2 else 5
    runs = [once(path) for _ in range(repeats)]
    n = runs[0][0]
    med = statistics.median(dt for _, dt in runs)
    print(f"pymavlink {mavutil.mavlink.__name__}: {n} messages, median {med:.3f} s over {repeats} runs "
          f"= {n / med:,.0f} msg/s")


if __name__ == "__main__":
    main()
