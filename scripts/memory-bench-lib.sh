# Shell functions the memory benchmarks share (sourced by bench-memory.sh and
# bench-memory-cluster.sh).

# Resident set of process PID, in KiB.
rss_kb() { awk '/^VmRSS:/ {print $2}' "/proc/$1/status"; }

# The resident set of PID once idle, in KiB: bgkmapd hands its engine scratch back 2 s after the
# last change (IdleScratchRelease; a shard's QuietScratch) and the tiles packed last at most 10 s
# after the previous hand-back (HeapTrimPacer), so this waits until at least 12 s after SINCE_NS
# (date +%s%N) and until the resident set has not changed for 2 s.
#   idle_rss_kb PID SINCE_NS
idle_rss_kb() {
  local pid=$1 since=$2 r prev=-1 same=0
  for _ in $(seq 240); do
    r=$(rss_kb "$pid")
    if [ "$r" = "$prev" ]; then same=$((same + 1)); else same=0; fi
    [ "$same" -ge 4 ] && [ $(($(date +%s%N) - since)) -ge 12000000000 ] && break
    prev=$r
    sleep 0.5
  done
  echo "$r"
}
