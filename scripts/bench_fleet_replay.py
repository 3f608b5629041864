#!/usr/bin/env python3
"""Flat-out fleet replay, CPU per vehicle-second (issue 47, build 3): two dronewatt builds
paired, the order alternating.

    python3 scripts/bench_fleet_replay.py [ROUNDS] --base OLD_BIN [--bin NEW_BIN] [--vehicles 250] [--same]

The fleet: `dronewatt simulate --vehicles 250 --seed 1 --leg-m 200 --hover-s 10 --out
target/fleet-load/tlogs/fleet250-seed1.tlog` (scripts/fleet-load.sh's recording, made
here if missing; ~68 MB, deterministic). Each round runs both builds on it, one after the
other (the base first in odd rounds, the new first in even ones), so each pair sees the
same machine load:

    replay TLOG -c CFG --speed max -q --data-dir off --json /dev/null

with `[fleet] lstm_rate_hz = 2` in CFG (every model, every report written): CPU (user +
sys of the whole process) and wall. The vehicle-seconds are the run's estimates over 10
(a 10 Hz window), counted once from a `--json` file of each build, which also shows the
two builds' output is the same (`--same`: byte for byte once sorted, the summary line's
run-to-run timing fields, `latency`, `queue_peak` and `queue_peak_at_s`, aside; the
vehicles' lines interleave differently from run to run).

Prints each round, then the medians, the median of the rounds' new/base ratios, and each
build's CPU per vehicle-second (µs; the goal: <= 300).
"""
import argparse
import hashlib
import json
import os
import resource
import statistics
import subprocess
import sys
import time

SCRATCH = "target/scratch/bench-fleet-replay"


def replay(binary, tlog, cfg, json_out=os.devnull):
    """Wall and CPU (user + sys) seconds of one whole `replay` process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(
        [binary, "replay", tlog, "-c", cfg, "--speed", "max", "-q", "--data-dir", "off",
         "--json", json_out],
        check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def output(binary, tlog, cfg, name):
    """The digests of the build's lines, sorted (its summary without the timing fields); its
    estimate count. Digests, not the lines: the 250-vehicle run writes ~640,000 lines."""
    path = f"{SCRATCH}/{name}.json"
    replay(binary, tlog, cfg, path)
    lines, estimates = [], 0
    with open(path) as f:
        for line in f:
            if line.startswith('{"type":"summary"'):
                s = json.loads(line)
                for k in ("latency", "queue_peak", "queue_peak_at_s"):
                    s.pop(k, None)
                line = json.dumps(s, sort_keys=True) + "\n"
            elif line.startswith('{"type":"estimate"'):
                estimates += 1
            lines.append(hashlib.blake2b(line.encode(), digest_size=16).digest())
    os.remove(path)
    lines.sort()
    return lines, estimates


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rounds", nargs="?", type=int, default=7)
    ap.add_argument("--bin", default=os.environ.get("DRONEWATT_BIN", "target/debug/dronewatt"))
    ap.add_argument("--base", required=True, help="the build before, run in the same rounds")
    ap.add_argument("--vehicles", type=int, default=250)
    ap.add_argument("--same", action="store_true",
                    help="first check both builds write the same lines (sorted)")
    a = ap.parse_args()
    os.makedirs(SCRATCH, exist_ok=True)
    tlog = f"target/fleet-load/tlogs/fleet{a.vehicles}-seed1.tlog"
    if not os.path.exists(tlog):
        os.makedirs(os.path.dirname(tlog), exist_ok=True)
        subprocess.run([a.bin, "simulate", "--vehicles", str(a.vehicles), "--out", tlog,
                        "--seed", "1", "--leg-m", "200", "--hover-s", "10"],
                       check=True, stderr=subprocess.DEVNULL)
    cfg = f"{SCRATCH}/lstm2hz.toml"
    with open(cfg, "w") as f:
        f.write("[fleet]\nlstm_rate_hz = 2\n")
    new_lines, estimates = output(a.bin, tlog, cfg, "new")
    if a.same:
        base_lines, base_estimates = output(a.base, tlog, cfg, "base")
        same = base_lines == new_lines
        print(f"output: {len(new_lines)} lines, {'the same' if same else 'DIFFERENT'} "
              f"(sorted; estimates {base_estimates} before, {estimates} after)")
        if not same:
            sys.exit(1)
    del new_lines
    vs = estimates / 10
    rows = []
    print(f"{estimates} estimates = {vs:.0f} vehicle-seconds; load {os.getloadavg()[0]:.1f}")
    print("round  base wall  base CPU  new wall  new CPU  new/base CPU  load")
    for i in range(a.rounds):
        order = [("base", a.base), ("new", a.bin)]
        if i % 2:
            order.reverse()
        got = {k: replay(b, tlog, cfg) for k, b in order}
        (bw, bc), (nw, nc) = got["base"], got["new"]
        rows.append((bw, bc, nw, nc, nc / bc))
        print(f"{i + 1:5}  {bw:8.2f}  {bc:8.2f}  {nw:8.2f}  {nc:7.2f}  {nc / bc:12.3f}  "
              f"{os.getloadavg()[0]:4.1f}", flush=True)
    med = [statistics.median(c) for c in zip(*rows)]
    lower = sum(r[3] < r[1] for r in rows)
    print(f"medians: base {med[0]:.2f} s wall, {med[1]:.2f} s CPU = {med[1] / vs * 1e6:.0f} µs "
          f"per vehicle-second; new {med[2]:.2f} s wall, {med[3]:.2f} s CPU = "
          f"{med[3] / vs * 1e6:.0f} µs per vehicle-second; median ratio {med[4]:.3f}; "
          f"new lower in {lower} of {len(rows)}")


if __name__ == "__main__":
    main()
