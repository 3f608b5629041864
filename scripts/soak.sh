#!/usr/bin/env bash
# Soak: `dronewatt replay` of a long flight (the demo tlog looped, clock continuous) at ×SPEED
# for MINUTES of wall time, with its RSS sampled, then checked:
#   - memory flat: the largest RSS after warm-up at most 5 % above the RSS at warm-up.
#     Warm-up: the first 10 % of the run (at least 20 s), and until the queues between the
#     stages last got deeper. Those queues are bounded (1024 deep per stage) but fill only
#     when a stage stalls (a busy machine), and their memory grows with their deepest mark
#     and no further; dronewatt reports that mark and when it was set (summary
#     `queue_peak`, `queue_peak_at_s`), so growth after it is not theirs. When the mark
#     was set in the last quarter of the run, too little is left to judge: FAIL, run longer;
#   - zero missed reports, and every report written: JSON estimate lines = reports = windows;
#   - counters consistent: no bad frames, no junk bytes, no clock jumps.
#
#   scripts/soak.sh MINUTES            e.g. 30 for the long run, 0.75 for the CI one
#
# Environment: SOAK_SPEED (100), DRONEWATT (target/debug/dronewatt), SOAK_OUT (target/soak),
# SOAK_SAMPLE_S (RSS sampling period, 5), SOAK_MAX_GROWTH_PCT (5: the RSS check's limit; the
# 45-s CI run loosens it, see tests/soak_short.rs), SOAK_MIN_JUDGED_FRAC (0.25: the share of the
# run that must be left after the queues' deepest mark; 0 judges from the plain warm-up then).
# Writes SOAK_OUT/rss.csv (elapsed_s,rss_kib) and SOAK_OUT/soak.json (the figures); prints one
# line; exits 1 if a check fails.
set -euo pipefail
cd "$(dirname "$0")/.."

MINUTES=${1:?usage: scripts/soak.sh MINUTES}
SPEED=${SOAK_SPEED:-100}
BIN=${DRONEWATT:-target/debug/dronewatt}
OUT=${SOAK_OUT:-target/soak}
SAMPLE_S=${SOAK_SAMPLE_S:-5}
export SOAK_MAX_GROWTH_PCT=${SOAK_MAX_GROWTH_PCT:-5}
[ -x "$BIN" ] || { echo "soak: $BIN not built (cargo build --locked)" >&2; exit 2; }

mkdir -p "$OUT"
rm -f "$OUT/feed.tlog" "$OUT/rss.csv" "$OUT/lines.txt"
mkfifo "$OUT/feed.tlog"
DURATION_S=$(python3 -c "print(round($MINUTES * 60, 1))")
# Flight for 1.5× the run at full speed: the run is ended by the clock, not by the feed.
FLIGHT_S=$(python3 -c "print($MINUTES * 60 * $SPEED * 1.5)")

python3 scripts/soak_feed.py replay/demo.tlog "$OUT/feed.tlog" "$FLIGHT_S" > "$OUT/feed.json" &
FEED=$!
# Estimate lines counted, the last one's t kept, the summary line kept: the JSON itself
# (about 1 kB a report) would fill the disk.
"$BIN" replay "$OUT/feed.tlog" --speed "$SPEED" -q --json - 2> "$OUT/dronewatt.log" > >(
  awk '/"type":"estimate"/ { n++; if (match($0, /"t":[-0-9.eE+]+/)) t = substr($0, RSTART + 4, RLENGTH - 4) }
       /"type":"summary"/ { s = $0 }
       END { print n + 0; print t + 0; print s }' > "$OUT/lines.txt"
) &
DW=$!
trap 'kill -TERM $DW $FEED 2>/dev/null || true' INT TERM

START=$(date +%s.%N)
echo "elapsed_s,rss_kib" > "$OUT/rss.csv"
while kill -0 "$DW" 2>/dev/null; do
  NOW=$(date +%s.%N)
  ELAPSED=$(python3 -c "print(round($NOW - $START, 1))")
  RSS=$(awk '/^VmRSS:/ { print $2 }' "/proc/$DW/status" 2>/dev/null || true)
  [ -n "$RSS" ] && echo "$ELAPSED,$RSS" >> "$OUT/rss.csv"
  if python3 -c "import sys; sys.exit(0 if $ELAPSED >= $DURATION_S else 1)"; then
    kill -TERM "$DW" 2>/dev/null || true   # the pipeline's own shutdown: it drains and writes the summary
    break
  fi
  sleep "$SAMPLE_S"
done
wait "$DW" || { echo "soak: dronewatt failed; see $OUT/dronewatt.log" >&2; exit 1; }
kill "$FEED" 2>/dev/null || true
wait "$FEED" 2>/dev/null || true
# The process substitution may still be flushing.
for _ in $(seq 50); do [ "$(wc -l < "$OUT/lines.txt" 2>/dev/null || echo 0)" -ge 3 ] && break; sleep 0.1; done

python3 - "$OUT" "$DURATION_S" "$SPEED" <<'EOF'
import csv, json, os, sys
limit_pct = float(os.environ["SOAK_MAX_GROWTH_PCT"])
out, duration_s, speed = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
lines = open(f"{out}/lines.txt").read().split("\n")
estimate_lines, last_t, summary = int(lines[0]), float(lines[1]), json.loads(lines[2])
rss = [(float(r["elapsed_s"]), int(r["rss_kib"])) for r in csv.DictReader(open(f"{out}/rss.csv"))]
queue_peak_at_s = float(summary.get("queue_peak_at_s", 0.0))
min_frac = float(os.environ.get("SOAK_MIN_JUDGED_FRAC", "0.25"))
warm_s = max(20.0, 0.1 * duration_s, queue_peak_at_s)
after = [(t, k) for t, k in rss if t > warm_s]
if not after or queue_peak_at_s > (1 - min_frac) * duration_s:
    if min_frac > 0:
        sys.exit(f"soak: the queues got deeper until {queue_peak_at_s:.0f} s of {duration_s:.0f} s "
                 f"(peak {summary.get('queue_peak')}): too little left to judge memory; run longer")
    # SOAK_MIN_JUDGED_FRAC=0 (the CI run): judge from the plain warm-up, queues and all.
    warm_s = max(20.0, 0.1 * duration_s)
    after = [(t, k) for t, k in rss if t > warm_s]
warm_kib, end_kib, max_kib = after[0][1], after[-1][1], max(k for _, k in after)
wall_s = rss[-1][0]
figures = {
    "minutes": duration_s / 60, "speed": speed, "wall_s": wall_s,
    "flight_s_replayed": last_t, "achieved_speed": last_t / wall_s if wall_s else 0,
    "warm_up_s": warm_s, "rss_warm_kib": warm_kib, "rss_end_kib": end_kib, "rss_max_after_warm_kib": max_kib,
    "rss_growth_pct": 100.0 * (max_kib - warm_kib) / warm_kib,
    "estimate_lines": estimate_lines, **{k: v for k, v in summary.items() if k != "type"},
}
json.dump(figures, open(f"{out}/soak.json", "w"), indent=1)
fail = []
if figures["rss_growth_pct"] > limit_pct:
    fail.append(f"RSS grew {figures['rss_growth_pct']:.1f} % after warm-up (limit {limit_pct:g} %)")
if summary["missed_reports"] != 0:
    fail.append(f"{summary['missed_reports']} missed reports")
if not (estimate_lines == summary["reports"] == summary["windows"]):
    fail.append(f"estimate lines {estimate_lines}, reports {summary['reports']}, windows {summary['windows']} differ")
for k in ("frames_bad", "junk_bytes", "clock_jumps"):
    if summary[k] != 0:
        fail.append(f"{k} = {summary[k]}")
if summary["reports"] == 0:
    fail.append("no reports at all")
print(f"soak {duration_s/60:g} min at x{speed:g}: {last_t/3600:.1f} h of flight in {wall_s:.0f} s (x{figures['achieved_speed']:.0f}), "
      f"queues deepest {summary.get('queue_peak')} at {queue_peak_at_s:.0f} s, "
      f"RSS {warm_kib/1024:.1f} MiB at warm-up ({warm_s:.0f} s), {end_kib/1024:.1f} MiB at the end, max {max_kib/1024:.1f} MiB "
      f"({figures['rss_growth_pct']:+.1f} %), reports {summary['reports']}, missed {summary['missed_reports']}, "
      f"frames ok {summary['frames_ok']} bad {summary['frames_bad']} gaps {summary['gaps']} clock jumps {summary['clock_jumps']}: "
      + ("FAIL: " + "; ".join(fail) if fail else "ok"))
sys.exit(1 if fail else 0)
EOF
