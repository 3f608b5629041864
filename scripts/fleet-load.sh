#!/usr/bin/env bash
# Fleet load benchmark (issue 14): recorded simulated fleet traffic through dronewatt.
#
# For each fleet size N (default 1 10 100 250): `dronewatt simulate --vehicles M` records a
# fleet's flight into a tlog (deterministic per seed). One MAVLink link holds at most 254
# vehicles (8-bit system ids), so a fleet of more than PER_LINK (default 250) is several
# links, one dronewatt each — the topology the README documents past one link: N = K × M,
# K = ceil(N / PER_LINK) instances of M = N / K vehicles, link k replaying its own tlog
# (seed k), all at once on this machine. Each size runs
#
#   paced  --speed 1 (messages at the recorded rate, as a live link delivers them) for
#          SECONDS, stopped by SIGINT (the clean shutdown path: every sink drains):
#            cpu_us_per_vs   CPU time of all instances (user+sys, /proc) / (N × SECONDS)
#            cpu_us_per_vs_handled  the instances' whole CPU (start to exit, the drain
#                            included) / (estimates / 10): the cost of a vehicle-second
#                            handled, also when the instances fall behind (then the
#                            column before counts only the share of the cores they got)
#            rss_mib         peak resident memory (VmHWM), summed over the instances
#            rss_kib_per_vehicle  rss_mib × 1024 / N
#            estimates       reports made (JSON summary `reports`, summed)
#            missed          reports a sink missed (`missed_reports`) + windows never reported
#            gaps            breaks in a sender's sequence (a live link's lost datagrams)
#            p50/p99/max_ms  message → estimate latency from each instance's JSON summary
#                            (`latency`: arrival of the newest message behind an estimate to
#                            its report going to the sinks). Over several instances: the
#                            largest instance p50/p99/max (an upper bound on the fleet's)
#   flat   (FLAT=1 only) --speed max, the instances at once over their whole tlogs:
#          windows_per_s, and the most vehicles at 10 Hz windows = windows_per_s / 10.
#
# LSTM on every window by default (label 10hz); LSTM_RATE=R runs `[fleet] lstm_rate_hz = R`
# instead (label Rhz; physics, energy and alerts stay at 10 Hz). MQTT=1 adds the MQTT sink:
# a Mosquitto of its own on a free loopback port, every instance publishing under
# `dronewatt/link<k>` as instance `link<k>`, a `mosquitto_sub` on `dronewatt/#` counting
# what arrives; the row then also has mqtt_published / mqtt_dropped (the sinks' summaries,
# summed), mqtt_received (every message the subscriber got) and mqtt_estimates_received
# (those on `…/<vehicle>/estimate`: one per report, so = estimates when nothing is lost).
#
# LIVE=1: live links instead of replays: link k is `dronewatt simulate --vehicles M --udp`
# (seed k, real time) into `dronewatt monitor udpin:127.0.0.1:PORT` (label live-…; the
# simulators' CPU is not counted, but they share the machine). A simulator computes its
# whole flight before it sends (~5 s for 250 vehicles on an idle machine, far longer on a
# busy one), so live the CPU is measured over a window of SECONDS that opens once every
# simulator sends (cpu_us_per_vs = the monitors' CPU in that window / (N × SECONDS)); the
# estimates, latency and misses are the whole run's.
#
# ONE_PROCESS=1 (with LIVE=1): the K links into ONE `monitor`, its config's `[[links]]`
# one per link, each its own network (`network = "link<k>"`: the simulators' system ids
# collide, 1..M on every link), so one process serves every link with one batched
# inference (label live-…-1proc, instances 1). Its CPU and peak RSS are that process's.
#
# SENDER=1 (with LIVE=1 ONE_PROCESS=1): instead of K simulators, one light sender
# (examples/fleet_send.rs, one thread) replays the K links' recorded fleets (TLOGS, recorded
# first as the replay rows do) at real time into the one monitor (label live-…-1proc-sender):
# the traffic of 3,000 vehicles without 12 simulators' CPU beside the monitor. The CPU window
# (SECONDS) opens a second after the sender starts.
#
# Appends rows to OUT/fleet-load.csv (OUT default target/fleet-load; a new file gets the
# header) and plots it (`cargo run --example fleet_load_plot`): fleet-load.png (CPU per
# vehicle-second), fleet-load-rss.png (peak RSS per vehicle), fleet-load-latency.png (p99
# latency). The tlogs are kept in TLOGS
# (default OUT/tlogs; ~68 MB per 250 vehicles).
#
# Usage: scripts/fleet-load.sh [SECONDS] [N ...]      (default: 30, 1 10 100 250)
#        LIVE=1 ONE_PROCESS=1 LSTM_RATE=2 scripts/fleet-load.sh 30 1000   (4 links, one process)
#        SENDER=1 LIVE=1 ONE_PROCESS=1 LSTM_RATE=2 scripts/fleet-load.sh 30 3000   (12 links, one process, one sender)
#        LSTM_RATE=2 scripts/fleet-load.sh 30 1 10 100 250 1000
#        LSTM_RATE=2 MQTT=1 scripts/fleet-load.sh 30 1000
#        NATS=2 LSTM_RATE=2 scripts/fleet-load.sh 30 300   (gateway + 2 workers over NATS, one killed)
set -euo pipefail
cd "$(dirname "$0")/.."
# NATS=W: the rows over NATS (one gateway, W workers, one of them killed), in their own
# CSV: scripts/fleet-load-nats.sh says what they measure.
if [ -n "${NATS:-}" ]; then exec scripts/fleet-load-nats.sh "$@"; fi
DUR=${1:-30}
shift || true
SIZES=${*:-1 10 100 250}
BIN=${DRONEWATT_BIN:-target/debug/dronewatt}
OUT=${OUT:-target/fleet-load}
PER_LINK=${PER_LINK:-250}
TLOGS=${TLOGS:-$OUT/tlogs}
[ -x "$BIN" ] || cargo build --locked
SEND=${FLEET_SEND_BIN:-target/debug/examples/fleet_send}
if [ "${SENDER:-0}" = 1 ]; then
  [ -x "$SEND" ] || cargo build --locked --example fleet_send
  [ "${ONE_PROCESS:-0}" = 1 ] && [ "${LIVE:-0}" = 1 ] || { echo "SENDER=1 needs LIVE=1 ONE_PROCESS=1" >&2; exit 2; }
fi
mkdir -p "$OUT" "$TLOGS"
TMP=$(mktemp -d)
PIDS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill "$p" 2> /dev/null || true; done
  # The last run's monitor log (its size and its warnings are part of the cost).
  cp "$TMP"/paced1.err "$OUT/monitor.err" 2> /dev/null || true
  rm -rf "$TMP"
}
trap cleanup EXIT
. scripts/lib-load.sh
# Live: wait until simulators 1..$1 have their flights ready (they send from then on), then
# measure the monitors ($2…) over DUR seconds into WINDOW_CPU.
live_window() {
  local k=$1 i c0
  shift
  for i in $(seq 1 "$k"); do until grep -qs "simulated mission" "$TMP/sim$i.err"; do sleep 0.2; done; done
  sleep 1
  c0=$(cpu_of "$@")
  sleep "$DUR"
  WINDOW_CPU=$(awk -v a="$c0" -v b="$(cpu_of "$@")" 'BEGIN {print b - a}')
}
WINDOW_CPU=
CSV="$OUT/fleet-load.csv"
HEAD="lstm,vehicles,instances,seconds,cpu_us_per_vs,rss_mib,rss_kib_per_vehicle,estimates,missed,gaps,p50_ms,p99_ms,max_ms,flat_windows_per_s,max_vehicles_10hz,mqtt_published,mqtt_dropped,mqtt_received,mqtt_estimates_received,cpu_us_per_vs_handled"
[ -s "$CSV" ] || echo "$HEAD" > "$CSV"

LABEL=10hz
[ "${LIVE:-0}" = 1 ] && LABEL=live-10hz
ONE=${ONE_PROCESS:-0}
if [ "$ONE" = 1 ] && [ "${LIVE:-0}" != 1 ]; then
  echo "ONE_PROCESS=1 needs LIVE=1 (replay reads one tlog: one link)" >&2
  exit 2
fi
CFG="$TMP/base.toml"
: > "$CFG"
if [ -n "${LSTM_RATE:-}" ]; then
  LABEL="${LABEL%10hz}${LSTM_RATE}hz"
  printf '[fleet]\nlstm_rate_hz = %s\n' "$LSTM_RATE" >> "$CFG"
fi
MQTT_PORT=
if [ "${MQTT:-0}" = 1 ]; then
  LABEL="$LABEL+mqtt"
  MQTT_PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
  # The subscriber is a client like any other: so that a slow moment of it is not counted
  # against dronewatt, the broker queues for it without bound.
  printf 'listener %s 127.0.0.1\nallow_anonymous true\npersistence false\nmax_queued_messages 0\nlog_dest stderr\n' "$MQTT_PORT" > "$TMP/mosquitto.conf"
  /usr/sbin/mosquitto -c "$TMP/mosquitto.conf" 2> "$TMP/mosquitto.log" &
  PIDS+=($!)
  sleep 0.5
fi

run_size() {  # $1 = N
  local n=$1 k m
  k=$(( (n + PER_LINK - 1) / PER_LINK ))
  m=$(( n / k ))
  if [ $(( m * k )) -ne "$n" ]; then echo "$n vehicles do not split evenly over $k links of ≤ $PER_LINK" >&2; exit 2; fi
  local i pids=() greps=() sub=
  if [ "$ONE" = 1 ]; then
    # One monitor, K links, each its own network; MQTT (if on) under one prefix.
    cp "$CFG" "$TMP/one.toml"
    if [ -n "$MQTT_PORT" ]; then
      printf '[sinks.mqtt]\nenabled = true\nport = %s\nprefix = "dronewatt/link1"\ninstance = "link1"\n' "$MQTT_PORT" >> "$TMP/one.toml"
    fi
    local ports=()
    for i in $(seq 1 "$k"); do
      ports+=("$(free_port SOCK_DGRAM)")
      printf '[[links]]\naddress = "udpin:127.0.0.1:%s"\nnetwork = "link%s"\n' "${ports[$((i - 1))]}" "$i" >> "$TMP/one.toml"
    done
    rm -rf "$TMP/summary1.json"
    if [ -n "$MQTT_PORT" ]; then
      mosquitto_sub -h 127.0.0.1 -p "$MQTT_PORT" -t 'dronewatt/#' -F '%t' > "$TMP/sub.txt" &
      sub=$!
      sleep 0.5
    fi
    mkfifo "$TMP/json1"
    grep -F '"type":"summary"' < "$TMP/json1" > "$TMP/summary1.json" &
    greps+=($!)
    RUST_LOG=dronewatt=info "$BIN" monitor -q --config "$TMP/one.toml" \
      --data-dir "${STORE:-off}" --json "$TMP/json1" 2> "$TMP/paced1.err" &
    pids+=($!)
    for i in $(seq 1 "$k"); do
      until grep -qs "listening on.*:${ports[$((i - 1))]}" "$TMP/paced1.err"; do sleep 0.1; done
    done
    local sims=()
    if [ "${SENDER:-0}" = 1 ]; then
      # One light sender replays every link's recorded fleet at real time (examples/fleet_send.rs).
      local pairs=()
      for i in $(seq 1 "$k"); do
        local tlog="$TLOGS/fleet${m}-seed$i.tlog"
        [ -f "$tlog" ] || "$BIN" simulate --vehicles "$m" --out "$tlog" --seed "$i" --leg-m 200 --hover-s 10 2> /dev/null
        pairs+=("$tlog=127.0.0.1:${ports[$((i - 1))]}")
      done
      "$SEND" "${pairs[@]}" 2> "$TMP/send.err" &
      sims+=($!)
      until grep -qs "^sending" "$TMP/send.err"; do sleep 0.1; done
      sleep 1
      local c0
      c0=$(cpu_of "${pids[@]}")
      sleep "$DUR"
      WINDOW_CPU=$(awk -v a="$c0" -v b="$(cpu_of "${pids[@]}")" 'BEGIN {print b - a}')
    else
      for i in $(seq 1 "$k"); do
        "$BIN" simulate --vehicles "$m" --udp "127.0.0.1:${ports[$((i - 1))]}" --seed "$i" --leg-m 200 --hover-s 10 2> "$TMP/sim$i.err" &
        sims+=($!)
      done
      live_window "$k" "${pids[@]}"
    fi
    # The sender ignores SIGINT as a background job of a script does: TERM stops it.
    for p in "${sims[@]}"; do kill -TERM "$p" || true; wait "$p" || true; done
    local lab="$LABEL-1proc"
    [ "${SENDER:-0}" = 1 ] && lab="$lab-sender"
    finish_size "$n" 1 "$lab" "$sub" "${pids[@]}" -- "${greps[@]}"
    return
  fi
  for i in $(seq 1 "$k"); do
    local tlog="$TLOGS/fleet${m}-seed$i.tlog"
    [ -f "$tlog" ] || "$BIN" simulate --vehicles "$m" --out "$tlog" --seed "$i" --leg-m 200 --hover-s 10 2> /dev/null
    cp "$CFG" "$TMP/link$i.toml"
    if [ -n "$MQTT_PORT" ]; then
      printf '[sinks.mqtt]\nenabled = true\nport = %s\nprefix = "dronewatt/link%s"\ninstance = "link%s"\n' "$MQTT_PORT" "$i" "$i" >> "$TMP/link$i.toml"
    fi
    rm -rf "$TMP/store$i" "$TMP/summary$i.json"
  done
  if [ -n "$MQTT_PORT" ]; then
    mosquitto_sub -h 127.0.0.1 -p "$MQTT_PORT" -t 'dronewatt/#' -F '%t' > "$TMP/sub.txt" &
    sub=$!
    sleep 0.5
  fi
  # Paced: every link at real time for DUR seconds. The JSON lines go through a pipe that
  # keeps only the summary (a 1,000-vehicle run writes ~10,000 lines a second).
  local sims=() port
  for i in $(seq 1 "$k"); do
    mkfifo "$TMP/json$i"
    grep -F '"type":"summary"' < "$TMP/json$i" > "$TMP/summary$i.json" &
    greps+=($!)
    if [ "${LIVE:-0}" = 1 ]; then
      port=$(free_port SOCK_DGRAM)
      RUST_LOG=dronewatt=info "$BIN" monitor "udpin:127.0.0.1:$port" -q --config "$TMP/link$i.toml" \
        --data-dir "${STORE:-off}" --json "$TMP/json$i" 2> "$TMP/paced$i.err" &
      pids+=($!)
      until grep -qs "listening on" "$TMP/paced$i.err"; do sleep 0.1; done
      "$BIN" simulate --vehicles "$m" --udp "127.0.0.1:$port" --seed "$i" --leg-m 200 --hover-s 10 2> "$TMP/sim$i.err" &
      sims+=($!)
    else
      RUST_LOG=dronewatt=info "$BIN" replay "$TLOGS/fleet${m}-seed$i.tlog" --speed 1 -q --config "$TMP/link$i.toml" \
        --data-dir "${STORE:-off}" --json "$TMP/json$i" 2> "$TMP/paced$i.err" &
      pids+=($!)
    fi
  done
  if [ "${LIVE:-0}" = 1 ]; then live_window "$k" "${pids[@]}"; else sleep "$DUR"; fi
  for p in "${sims[@]}"; do kill -INT "$p" || true; wait "$p" || true; done
  finish_size "$n" "$k" "$LABEL" "$sub" "${pids[@]}" -- "${greps[@]}"
}

# Measure the instances, stop them, and append the row.
# $1 = N, $2 = instances, $3 = label, $4 = subscriber pid (or ""), then the instances'
# pids, `--`, the summary pipes' pids.
finish_size() {
  local n=$1 k=$2 label=$3 sub=$4 pids=() greps=() p
  shift 4
  while [ "$1" != -- ]; do pids+=("$1"); shift; done
  shift
  greps=("$@")
  local m=$(( n / k ))
  local cpu hwm=0 p
  cpu=${WINDOW_CPU:-$(cpu_of "${pids[@]}")}
  WINDOW_CPU=
  for p in "${pids[@]}"; do
    hwm=$(awk -v h="$hwm" '/^VmHWM/ {print h + $2}' "/proc/$p/status")
  done
  for p in "${pids[@]}"; do kill -INT "$p" || true; done
  # Their whole CPU (start and drain included), read until they exit: over the estimates
  # made, what a vehicle-second handled cost (10 estimates a vehicle-second), whether or
  # not the instances kept up with the traffic.
  local total=0 last
  for p in "${pids[@]}"; do
    last=$(cpu_of "$p")
    while [ -e "/proc/$p/stat" ] && c=$(cpu_of "$p" 2> /dev/null); do last=$c; sleep 0.1; done
    total=$(awk -v a="$total" -v b="$last" 'BEGIN {print a + b}')
  done
  for p in "${pids[@]}"; do wait "$p" || echo "instance $p exited $?" >&2; done
  for p in "${greps[@]}"; do wait "$p" || true; done
  rm -f "$TMP"/json*
  local received=""
  if [ -n "$sub" ]; then
    # Until the subscriber has read all the broker holds for it (its count still for 2 s).
    local was=-1 now=0
    while [ "$now" != "$was" ]; do was=$now; sleep 2; now=$(wc -l < "$TMP/sub.txt"); done
    kill "$sub"; wait "$sub" 2> /dev/null || true
    grep -i "drop" "$TMP/mosquitto.log" >&2 || true
    received="$(wc -l < "$TMP/sub.txt"),$(grep -c '^dronewatt/link[0-9]*/[0-9:]*/estimate$' "$TMP/sub.txt" || true)"
  fi
  # Flat out (FLAT=1): every link's whole tlog at once.
  local t0=0 t1=0
  if [ "${FLAT:-0}" = 1 ]; then
    pids=()
    t0=$(date +%s.%N)
    for i in $(seq 1 "$k"); do
      "$BIN" replay "$TLOGS/fleet${m}-seed$i.tlog" --speed max -q --config "$CFG" --data-dir off --json "$TMP/flat$i.json" 2> /dev/null &
      pids+=($!)
    done
    for p in "${pids[@]}"; do wait "$p"; done
    t1=$(date +%s.%N)
  fi
  python3 - "$TMP" "$n" "$k" "$DUR" "$cpu" "$hwm" "$t0" "$t1" "$label" "$received" "$total" >> "$CSV" <<'PY'
import json, re, sys, glob, os
tmp, n, k, dur, cpu, hwm, t0, t1, label, received, total = sys.argv[1:]
n, k, dur, cpu, hwm = int(n), int(k), float(dur), float(cpu), int(hwm)
est = missed = gaps = 0
lat = {"p50_ms": 0.0, "p99_ms": 0.0, "max_ms": 0.0}
pub = drop = 0
for i in range(1, k + 1):
    s = json.loads(open(f"{tmp}/summary{i}.json").read().strip().splitlines()[-1])
    est += s["reports"]
    gaps += s["gaps"]
    missed += s["missed_reports"] + max(0, s["windows"] - s["reports"])
    for q in lat:
        lat[q] = max(lat[q], (s.get("latency") or {}).get(q, 0.0))
    for line in open(f"{tmp}/paced{i}.err"):
        m = re.search(r"mqtt summary: (\d+) messages published, (\d+) dropped", line)
        if m:
            pub += int(m[1]); drop += int(m[2])
wps = vmax = ""
if float(t1) > 0:
    windows = sum(1 for i in range(1, k + 1) for line in open(f"{tmp}/flat{i}.json") if line.startswith('{"type":"estimate"'))
    wps = f"{windows / (float(t1) - float(t0)):.0f}"
    vmax = f"{float(wps) / 10:.0f}"
mq = f"{pub},{drop},{received}" if received else ",,,"
print(f"{label},{n},{k},{dur},{cpu / (n * dur) * 1e6:.1f},{hwm / 1024:.1f},{hwm / n:.1f},{est},{missed},{gaps},"
      f"{lat['p50_ms']:.2f},{lat['p99_ms']:.2f},{lat['max_ms']:.2f},{wps},{vmax},{mq},"
      f"{float(total) / max(est / 10, 1) * 1e6:.1f}")
PY
  tail -1 "$CSV"
  rm -f "$TMP"/flat*.json
}

for n in $SIZES; do run_size "$n"; done
# PLOT=0: the rows only (the plot builds an example).
if [ "${PLOT:-1}" = 1 ]; then
  cargo run --locked --quiet --example fleet_load_plot -- "$CSV" "$OUT/fleet-load.png"
fi
echo "wrote $CSV (load average: $(cut -d' ' -f1-3 /proc/loadavg))"
