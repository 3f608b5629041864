#!/usr/bin/env python3
"""Flat-out replay benchmark (issue 47, build 4): dronewatt's whole process against pymavlink
merely parsing the same log, paired.

    .venv-py/bin/python scripts/bench_replay.py [ROUNDS] [--bin B] [--base OLD_BIN] [--unbatched] [--log FILE]

The log (unless --log): a simulated ArduCopter delivery, 389 s of flight and 17,230 messages,
`dronewatt simulate --autopilot ardupilot --leg-m 900 --hover-s 60 --out
target/bench-replay/ac.tlog` (deterministic). Each round runs, one after the other so both
see the same machine load:

- dronewatt: `replay LOG --speed max -q --data-dir off --json /dev/null`, every model, the
  whole process (start, models loaded, every report written): wall, and CPU (user + sys);
- pymavlink 2.4.50: `recv_match()` over the whole tlog (scripts/bench_pymavlink.py's loop:
  the parse alone, no interpreter start, no model);
- with --base, another dronewatt build the same way (a before/after in the same rounds);
- with --unbatched, this build again with every window run alone through the models
  (`DRONEWATT_MAX_BATCH=1`: the same output, tests/it/replay_batches.rs), what batching buys.

Prints each round, then the medians and the ratio of pymavlink's median parse to
dronewatt's median wall (the goal: >= 3), and the median of the rounds' own ratios.
"""
import argparse
import os
import resource
import statistics
import subprocess
import sys
import time

os.environ.setdefault("MAVLINK20", "1")
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_pymavlink  # noqa: E402


def run_dronewatt(binary, log, env=None):
    """Wall and CPU (user + sys) seconds of one whole `replay` process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(
        [binary, "replay", log, "--speed", "max", "-q", "--data-dir", "off", "--json", os.devnull],
        check=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=None if env is None else {**os.environ, **env},
    )
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rounds", nargs="?", type=int, default=11)
    ap.add_argument("--bin", default=os.environ.get("DRONEWATT_BIN", "target/debug/dronewatt"))
    ap.add_argument("--base", help="another dronewatt build, run in the same rounds")
    ap.add_argument("--unbatched", action="store_true",
                    help="also this build with DRONEWATT_MAX_BATCH=1, in the same rounds")
    ap.add_argument("--log", help="the log to replay (default: the simulated ArduCopter flight)")
    a = ap.parse_args()
    log = a.log
    if log is None:
        os.makedirs("target/bench-replay", exist_ok=True)
        log = "target/bench-replay/ac.tlog"
        if not os.path.exists(log):
            subprocess.run(
                [a.bin, "simulate", "--autopilot", "ardupilot", "--leg-m", "900", "--hover-s", "60",
                 "--out", log],
                check=True,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
    dw, py, base, alone = [], [], [], []
    n = 0
    for r in range(a.rounds):
        dw.append(run_dronewatt(a.bin, log))
        n, dt = bench_pymavlink.once(log)
        py.append(dt)
        line = f"round {r + 1}: dronewatt {dw[-1][0]:.3f} s wall, {dw[-1][1]:.3f} s CPU; pymavlink parse {dt:.3f} s"
        if a.base:
            base.append(run_dronewatt(a.base, log))
            line += f"; base {base[-1][0]:.3f} s wall, {base[-1][1]:.3f} s CPU"
        if a.unbatched:
            alone.append(run_dronewatt(a.bin, log, {"DRONEWATT_MAX_BATCH": "1"}))
            line += f"; unbatched {alone[-1][0]:.3f} s wall, {alone[-1][1]:.3f} s CPU"
        print(line, flush=True)
    med = statistics.median
    w, c = med(x[0] for x in dw), med(x[1] for x in dw)
    p = med(py)
    print(f"log {log}: {n} messages; {a.rounds} rounds; load average {os.getloadavg()[0]:.1f}")
    print(f"dronewatt replay (whole process, every model): median {w:.3f} s wall, {c:.3f} s CPU")
    print(f"pymavlink recv_match parse alone: median {p:.3f} s")
    print(f"ratio pymavlink parse / dronewatt wall: {p / w:.2f}x (medians), "
          f"{med(pp / d[0] for pp, d in zip(py, dw)):.2f}x (median of the rounds' ratios)")
    if base:
        bw, bc = med(x[0] for x in base), med(x[1] for x in base)
        print(f"base build: median {bw:.3f} s wall, {bc:.3f} s CPU; ratio {p / bw:.2f}x; "
              f"this build / base: wall {w / bw:.2f}, CPU {c / bc:.2f}")
    if alone:
        aw, ac = med(x[0] for x in alone), med(x[1] for x in alone)
        print(f"unbatched (DRONEWATT_MAX_BATCH=1): median {aw:.3f} s wall, {ac:.3f} s CPU; "
              f"ratio {p / aw:.2f}x; batched / unbatched: wall {w / aw:.2f}, CPU {c / ac:.2f}")


if __name__ == "__main__":
    main()
