#!/usr/bin/env bash
# Soak benchmark (issue #26): `ucc run --local` flies a short mission ITERATIONS times in one
# process; the process's resident memory is printed every EVERY iterations. At the end it
# checks that no iteration failed (results.csv) and that memory stayed flat (within ±10 %
# of the first sample taken after WARMUP iterations).
#
#   usar-bench/soak.sh [ITERATIONS [EVERY [WARMUP]]]      (defaults: 10000 1000 1000)
#   UCC=target/release/ucc usar-bench/soak.sh               (the binary to run)
set -euo pipefail
iterations=${1:-10000}
every=${2:-1000}
warmup=${3:-$every}
ucc=${UCC:-target/release/ucc}
dir=$(mktemp -d "${TMPDIR:-/tmp}/ucc-soak.XXXXXX")
trap 'rm -rf "$dir"' EXIT

"$ucc" run --local --start 0,0,-1 --goto 0.5,0,-1 --iterations "$iterations" \
  --pictures none --log-dir "$dir" -q >"$dir/stdout.txt" 2>"$dir/stderr.txt" &
pid=$!
start=$(date +%s.%N)
next=$every
base=""
printf '%10s %10s %10s %8s\n' iterations seconds rss_kib vs_base
while kill -0 "$pid" 2>/dev/null; do
  done=$(find "$dir" -maxdepth 1 -name '*-trajectory.csv' | wc -l)
  if (( done >= next )); then
    rss=$(awk '/^VmRSS:/ {print $2}' "/proc/$pid/status" 2>/dev/null || echo 0)
    now=$(date +%s.%N)
    if [[ -z "$base" && $done -ge $warmup ]]; then base=$rss; fi
    ratio=$(awk -v r="$rss" -v b="${base:-0}" 'BEGIN { if (b > 0) printf "%+.1f%%", (r / b - 1) * 100; else print "-" }')
    printf '%10d %10.1f %10d %8s\n' "$done" "$(awk -v a="$now" -v b="$start" 'BEGIN {print a - b}')" "$rss" "$ratio"
    [[ -n "$base" ]] && echo "$rss" >>"$dir/samples.txt"
    next=$(( (done / every + 1) * every ))
  fi
  sleep 0.2
done
status=0
wait "$pid" || status=$?
results=$(find "$dir" -maxdepth 1 -name '*results.csv' | head -1)
failed=$(awk -F, 'NR > 1 && ($2 != "ok" || $6 == "inf")' "$results" | wc -l)
total=$(( $(wc -l <"$results") - 1 ))
echo "ucc exit status $status; $total iterations, $failed failed"
if [[ -s "$dir/samples.txt" ]]; then
  awk -v b="$base" '{ d = ($1 / b - 1) * 100; if (d > m) m = d; if (d < n) n = d }
    END { printf "memory after warm-up: %+.1f%% to %+.1f%% of %d KiB\n", n, m, b;
          exit (m > 10 || n < -10) }' "$dir/samples.txt" || { echo "memory not flat"; status=1; }
fi
(( failed == 0 && status == 0 ))
