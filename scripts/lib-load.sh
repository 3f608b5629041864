# Sourced by the load benchmarks (fleet-load.sh, fleet-load-nats.sh): what both measure with.

# CPU seconds (user+sys, /proc) of these processes so far.
cpu_of() {
  local c=0 p
  for p in "$@"; do c=$(awk -v t="$TICK" -v c="$c" '{print c + ($14 + $15) / t}' "/proc/$p/stat"); done
  echo "$c"
}
TICK=$(getconf CLK_TCK)

# A free loopback port: free_port SOCK_DGRAM (UDP) or SOCK_STREAM (TCP).
free_port() {
  python3 -c "import socket; s=socket.socket(socket.AF_INET, socket.$1); s.bind(('127.0.0.1',0)); print(s.getsockname()[1])"
}
