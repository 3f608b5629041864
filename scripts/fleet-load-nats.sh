#!/usr/bin/env bash
# The NATS rows of the fleet load benchmark (`NATS=W scripts/fleet-load.sh SECONDS N…` runs
# this): N vehicles through one `dronewatt gateway` into nats-server (JetStream, loopback,
# a throwaway store) and W workers (`monitor --nats`), then one worker SIGKILLed.
#
# The traffic: PER_LINK (250) vehicles at most per link, K = ceil(N / PER_LINK) links of
# M = N / K recorded vehicles each (`simulate --vehicles M --seed k`, kept in TLOGS as the
# replay rows keep theirs), replayed at real time by the light sender (examples/fleet_send.rs)
# into the gateway's K `[[links]]`, each its own network. A viewer (a raw NATS client in
# Python, no library) subscribes to `dronewatt.estimates.>` and stamps each estimate.
#
# Steady window: SECONDS from a second after the sender starts.
#   cpu_us_per_vs   CPU (user+sys, /proc) of gateway + workers + nats-server / (N × SECONDS);
#                   gateway_cores, workers_cores, server_cores: each part's share
#   p50_ms, p99_ms  gateway arrival → estimate at the viewer (the estimate's `t` + the
#                   stream's creation time, against the viewer's clock; same machine), the
#                   estimates received within the window
#   worker_p99_ms   the largest p99 of the surviving workers' own summaries (message off
#                   the stream → report to the sinks)
# Then worker W is SIGKILLed and the run goes on TAKEOVER_WAIT (20) s:
#   takeover_s      kill → the last partition taken "from worker" by a survivor (its log)
#   hole_s          the longest wait between two estimates of one vehicle at the viewer,
#                   across the kill (the takeover, then the replay of the stream)
# At the end (sender stopped, survivors stopped by SIGINT):
#   estimates       estimates the viewer received (all run)
#   missed          reports the survivors' sinks missed (missed_reports)
#   held_back       the survivors' windows not reported (windows − reports): the takeover's
#                   replay of what the killed worker had already published, held back so
#                   that nothing goes out twice (and any window never reported)
#   lost            datagrams the kernel dropped on the gateway's sockets (/proc/net/udp)
#                   + frames the gateway could not store in the stream (the workers read
#                   the stream, not the links: their summaries' `gaps` say nothing here)
#
# Appends to OUT/fleet-load-nats.csv (a new file gets the header).
# Usage: NATS=2 LSTM_RATE=2 scripts/fleet-load.sh 30 300
set -euo pipefail
cd "$(dirname "$0")/.."
DUR=${1:-30}
shift || true
SIZES=${*:-300}
W=${NATS:-2}
[ "$W" -ge 2 ] || { echo "NATS=W needs 2 or more workers (one is killed)" >&2; exit 2; }
BIN=${DRONEWATT_BIN:-target/debug/dronewatt}
SEND=${FLEET_SEND_BIN:-target/debug/examples/fleet_send}
OUT=${OUT:-target/fleet-load}
PER_LINK=${PER_LINK:-250}
TLOGS=${TLOGS:-$OUT/tlogs}
WAIT=${TAKEOVER_WAIT:-20}
[ -x "$BIN" ] || cargo build --locked --bin dronewatt
[ -x "$SEND" ] || cargo build --locked --example fleet_send
command -v nats-server > /dev/null || { echo "nats-server is not installed (scripts/setup-nats.sh)" >&2; exit 2; }
mkdir -p "$OUT" "$TLOGS"
TMP=$(mktemp -d)
PIDS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill -KILL "$p" 2> /dev/null || true; done
  rm -rf "$TMP"
}
trap cleanup EXIT
. scripts/lib-load.sh
CSV="$OUT/fleet-load-nats.csv"
HEAD="lstm,vehicles,workers,seconds,cpu_us_per_vs,gateway_cores,workers_cores,server_cores,estimates,missed,held_back,lost,p50_ms,p99_ms,worker_p99_ms,takeover_s,hole_s"
[ -s "$CSV" ] || echo "$HEAD" > "$CSV"
LABEL=nats-10hz
: > "$TMP/base.toml"
if [ -n "${LSTM_RATE:-}" ]; then
  LABEL="nats-${LSTM_RATE}hz"
  printf '[fleet]\nlstm_rate_hz = %s\n' "$LSTM_RATE" >> "$TMP/base.toml"
fi

# The viewer: a raw NATS client (the protocol is text) stamping each estimate as
# "recv_unix net sys t"; first line: the stream's creation time (unix s).
cat > "$TMP/viewer.py" << 'PY'
import json, socket, sys, time, datetime
port, out = int(sys.argv[1]), open(sys.argv[2], "w", buffering=1)
s = socket.create_connection(("127.0.0.1", port))
f = s.makefile("rb")
f.readline()  # INFO
s.sendall(b'CONNECT {"verbose":false,"pedantic":false,"headers":false}\r\n'
          b"SUB _INBOX.viewer 1\r\nSUB dronewatt.estimates.> 2\r\n"
          b"PUB $JS.API.STREAM.INFO.DRONEWATT_FRAMES _INBOX.viewer 0\r\n\r\n")
while True:
    line = f.readline()
    if not line:
        break
    if line.startswith(b"PING"):
        s.sendall(b"PONG\r\n")
        continue
    if not line.startswith(b"MSG"):
        continue
    parts = line.split()
    body = f.read(int(parts[-1]) + 2)[:-2]
    now = time.time()
    v = json.loads(body)
    if parts[2] == b"1":
        c = v["created"]  # RFC 3339 with nanoseconds
        base, frac = c.rstrip("Z").split(".") if "." in c else (c.rstrip("Z"), "0")
        t0 = datetime.datetime.fromisoformat(base).replace(tzinfo=datetime.timezone.utc).timestamp()
        out.write(f"epoch {t0 + float('0.' + frac):.6f}\n")
    else:
        out.write(f"{now:.6f} {v.get('network', 0)} {v['system_id']} {v['t']}\n")
PY

run_size() {
  local n=$1 k m i
  k=$(( (n + PER_LINK - 1) / PER_LINK ))
  m=$(( n / k ))
  [ $(( m * k )) -eq "$n" ] || { echo "$n vehicles do not split evenly over $k links" >&2; exit 2; }
  local nport
  nport=$(free_port SOCK_STREAM)
  rm -rf "$TMP/js"
  nats-server -js -a 127.0.0.1 -p "$nport" -sd "$TMP/js" 2> "$TMP/nats.err" &
  local server=$!
  PIDS+=("$server")
  until python3 -c "import socket; socket.create_connection(('127.0.0.1', $nport))" 2> /dev/null; do sleep 0.1; done
  local url="nats://127.0.0.1:$nport" ports=() pairs=()
  cp "$TMP/base.toml" "$TMP/gw.toml"
  for i in $(seq 1 "$k"); do
    ports+=("$(free_port SOCK_DGRAM)")
    printf '[[links]]\naddress = "udpin:127.0.0.1:%s"\nnetwork = "link%s"\n' "${ports[$((i - 1))]}" "$i" >> "$TMP/gw.toml"
    local tlog="$TLOGS/fleet${m}-seed$i.tlog"
    [ -f "$tlog" ] || "$BIN" simulate --vehicles "$m" --out "$tlog" --seed "$i" --leg-m 200 --hover-s 10 2> /dev/null
    pairs+=("$tlog=127.0.0.1:${ports[$((i - 1))]}")
  done
  RUST_LOG=dronewatt=info "$BIN" gateway --config "$TMP/gw.toml" --nats "$url" 2> "$TMP/gateway.err" &
  local gateway=$!
  PIDS+=("$gateway")
  for i in $(seq 1 "$k"); do
    until grep -qs "listening on.*:${ports[$((i - 1))]}" "$TMP/gateway.err"; do sleep 0.1; done
  done
  local workers=() greps=()
  for i in $(seq 1 "$W"); do
    mkfifo "$TMP/json$i"
    grep -F '"type":"summary"' < "$TMP/json$i" > "$TMP/summary$i.json" &
    greps+=($!)
    RUST_LOG=dronewatt=info "$BIN" monitor --nats "$url" -q --config "$TMP/base.toml" \
      --data-dir off --json "$TMP/json$i" 2> "$TMP/worker$i.err" &
    workers+=($!)
    PIDS+=($!)
  done
  # The workers share the partitions (a few lease ticks).
  sleep 4
  python3 "$TMP/viewer.py" "$nport" "$TMP/seen.txt" &
  local viewer=$!
  PIDS+=("$viewer")
  sleep 0.5
  "$SEND" "${pairs[@]}" 2> "$TMP/send.err" &
  local sender=$!
  PIDS+=("$sender")
  until grep -qs "^sending" "$TMP/send.err"; do sleep 0.1; done
  sleep 1
  local w0 w1 g0 g1 s0 s1 t0 t1 killed
  t0=$(date +%s.%N)
  w0=$(cpu_of "${workers[@]}"); g0=$(cpu_of "$gateway"); s0=$(cpu_of "$server")
  sleep "$DUR"
  w1=$(cpu_of "${workers[@]}"); g1=$(cpu_of "$gateway"); s1=$(cpu_of "$server")
  t1=$(date +%s.%N)
  # One worker dies.
  kill -KILL "${workers[$((W - 1))]}"
  killed=$(date +%s.%N)
  sleep "$WAIT"
  # The kernel's drops on the gateway's sockets, before they close.
  local drops=0 p hex
  for p in "${ports[@]}"; do
    hex=$(printf '%04X' "$p")
    drops=$(( drops + $(awk -v h=":$hex" '$2 ~ h"$" {d += $NF} END {print d + 0}' /proc/net/udp) ))
  done
  kill -TERM "$sender" || true
  wait "$sender" || true
  for i in $(seq 1 $((W - 1))); do kill -INT "${workers[$((i - 1))]}" || true; done
  for i in $(seq 1 $((W - 1))); do wait "${workers[$((i - 1))]}" || echo "worker $i exited $?" >&2; done
  kill -INT "$gateway" || true
  wait "$gateway" || true
  kill "$viewer" || true
  kill "$server" || true
  wait "$server" 2> /dev/null || true
  for p in "${greps[@]}"; do kill "$p" 2> /dev/null || true; done
  python3 - "$TMP" "$n" "$W" "$DUR" "$LABEL" "$t0" "$t1" "$killed" "$drops" \
    "$(awk -v a="$w0" -v b="$w1" 'BEGIN {print b - a}')" \
    "$(awk -v a="$g0" -v b="$g1" 'BEGIN {print b - a}')" \
    "$(awk -v a="$s0" -v b="$s1" 'BEGIN {print b - a}')" >> "$CSV" << 'PY'
import json, re, sys, datetime, collections
tmp, n, w, dur, label, t0, t1, killed, drops, cw, cg, cs = sys.argv[1:]
n, w, dur, t0, t1, killed, drops = int(n), int(w), float(dur), float(t0), float(t1), float(killed), int(drops)
cw, cg, cs = float(cw), float(cg), float(cs)
epoch, lat, times = None, [], collections.defaultdict(list)
for line in open(f"{tmp}/seen.txt"):
    a = line.split()
    if a[0] == "epoch":
        epoch = float(a[1]); continue
    now, key, t = float(a[0]), (a[1], a[2]), float(a[3])
    times[key].append(now)
    if epoch is not None and t0 <= now <= t1:
        lat.append(1e3 * (now - (epoch + t)))
lat.sort()
q = lambda p: lat[min(len(lat) - 1, int(p * len(lat)))] if lat else float("nan")
hole = max((b - a for ts in times.values() for a, b in zip(ts, ts[1:]) if b > killed - 1), default=0.0)
missed = held = 0; wp99 = 0.0
for i in range(1, w):
    s = json.loads(open(f"{tmp}/summary{i}.json").read().strip().splitlines()[-1])
    missed += s["missed_reports"]
    held += max(0, s["windows"] - s["reports"])
    wp99 = max(wp99, (s.get("latency") or {}).get("p99_ms", 0.0))
taken = 0.0
for i in range(1, w):
    for line in open(f"{tmp}/worker{i}.err"):
        if "took partition" in line and "from worker" in line:
            ts = datetime.datetime.fromisoformat(line.split()[0][:26]).replace(tzinfo=datetime.timezone.utc).timestamp()
            if ts > killed:
                taken = max(taken, ts - killed)
notstored = 0
for line in open(f"{tmp}/gateway.err"):
    m = re.search(r"stopped; (\d+) frames stored, (\d+) not", line)
    if m:
        notstored = int(m[2])
total = cw + cg + cs
print(f"lost: {drops} datagrams dropped by the kernel on the gateway's sockets, {notstored} frames "
      f"not stored; {len(lat)} estimates in the steady window", file=sys.stderr)
print(f"{label},{n},{w},{dur:.0f},{total / (n * dur) * 1e6:.1f},{cg / dur:.2f},{cw / dur:.2f},{cs / dur:.2f},"
      f"{sum(len(v) for v in times.values())},{missed},{held},{drops + notstored},{q(0.5):.1f},{q(0.99):.1f},"
      f"{wp99:.2f},{taken:.2f},{hole:.2f}")
PY
  tail -1 "$CSV"
  rm -f "$TMP"/json* "$TMP"/summary* "$TMP/seen.txt"
}

for n in $SIZES; do run_size "$n"; done
echo "wrote $CSV (load average: $(cut -d' ' -f1-3 /proc/loadavg))"
