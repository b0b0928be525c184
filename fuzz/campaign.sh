#!/usr/bin/env bash
# Fuzz campaign (issues #26, #56): runs every cargo-fuzz target for MINUTES minutes (or RUNS
# executions, whichever comes first), then prints each target's executions, rate and
# findings. Not part of CI.
#
#   fuzz/campaign.sh [MINUTES [TARGET...]]          (default: 10 minutes, every target)
#   RUNS=10000000 fuzz/campaign.sh 120 codec        (stop at 10 M executions or 2 hours)
#
# Needs `cargo install cargo-fuzz --locked`. With a nightly toolchain (`cargo +nightly`) the
# targets are built with the address sanitizer; without one, on stable Rust, cargo-fuzz's
# `-Z` flags are allowed with RUSTC_BOOTSTRAP=1 and the sanitizer is `none` (the crates
# fuzzed have no `unsafe` code; libFuzzer still catches panics, overflows checked in debug
# assertions, stack overflows, timeouts and memory over -rss_limit_mb). SANITIZER=address
# (or none) overrides the choice; TOOLCHAIN=stable uses stable even where nightly is.
# Corpora are kept compact in the repository: fuzz/corpora/TARGET.tar.xz (minimised with
# `cargo fuzz cmin` after each run); they are unpacked into fuzz/corpus/ (not committed) to
# run. Findings (crashes, timeouts, out-of-memory inputs) land in fuzz/artifacts/TARGET/.
set -euo pipefail
cd "$(dirname "$0")"
minutes=${1:-10}
shift || true
targets=("$@")
if [[ "${TOOLCHAIN:-}" != stable ]] && cargo +nightly --version >/dev/null 2>&1; then
  fuzz=(cargo +nightly fuzz)
  sanitizer=${SANITIZER:-address}
else
  fuzz=(env RUSTC_BOOTSTRAP=1 cargo fuzz)
  sanitizer=${SANITIZER:-none}
fi
runs=()
if [[ -n "${RUNS:-}" ]]; then
  runs=(-runs="$RUNS")
fi
if (( ${#targets[@]} == 0 )); then
  mapfile -t targets < <(cargo fuzz list)
fi
seconds=$(awk -v m="$minutes" 'BEGIN { printf "%d", m * 60 }')
mkdir -p corpora corpus artifacts
summary=()
for t in "${targets[@]}"; do
  mkdir -p "corpus/$t" "artifacts/$t"
  if [[ -f "corpora/$t.tar.xz" ]]; then
    tar -xJf "corpora/$t.tar.xz" -C "corpus/$t"
  fi
  before=$(find "artifacts/$t" -type f | wc -l)
  log="artifacts/$t.log"
  echo "== $t: ${minutes} min"
  # -rss_limit_mb: a finding if one input takes more; -max_len: inputs of up to 4 KiB.
  "${fuzz[@]}" run -s "$sanitizer" "$t" "corpus/$t" -- -max_total_time="$seconds" "${runs[@]}" \
    -print_final_stats=1 -rss_limit_mb=1024 -max_len=4096 >"$log" 2>&1 || true
  execs=$(awk '/stat::number_of_executed_units/ { print $NF }' "$log" | tail -1)
  rate=$(awk '/stat::average_exec_per_sec/ { print $NF }' "$log" | tail -1)
  after=$(find "artifacts/$t" -type f | wc -l)
  # Keep the corpus small: minimise, then pack.
  "${fuzz[@]}" cmin -s "$sanitizer" "$t" "corpus/$t" >/dev/null 2>&1 || true
  files=$(find "corpus/$t" -type f | wc -l)
  # (A corpus another fuzzer writes to at the same time, e.g. a CI pass, makes tar warn:
  # not a reason to stop the campaign.)
  tar -cJf "corpora/$t.tar.xz" -C "corpus/$t" . || echo "warning: corpus of $t changed while packing it"
  summary+=("$(printf '%-14s %12s execs %8s/s %6s corpus files %3s findings' \
    "$t" "${execs:-?}" "${rate:-?}" "$files" "$((after - before))")")
done
echo
echo "fuzz campaign, ${minutes} min${RUNS:+ or $RUNS executions} per target, sanitizer $sanitizer, $(date -u +%Y-%m-%d)"
printf '%s\n' "${summary[@]}"
if compgen -G "artifacts/*/*" >/dev/null; then
  echo "findings:"
  find artifacts -mindepth 2 -type f
fi
