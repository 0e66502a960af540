#!/usr/bin/env bash
# Fuzz every parser of external input (fuzz/, cargo-fuzz and libFuzzer) for SECONDS_PER_TARGET
# seconds each (default 20), starting from the committed seeds in fuzz/seeds/<target>/.
#
#   scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET...]
#
# Prints one line per target (executions, executions per second, crashes) and exits non-zero
# when a target crashed, naming the input that crashes it (fuzz/artifacts/<target>/...).
# Environment: FUZZ_SANITIZER (address, the default, or none), FUZZ_RSS_LIMIT_MB (2048),
# FUZZ_TIMEOUT_S (one input longer than this is a hang, reported as a crash; 30).
# cargo-fuzz passes unstable compiler flags; RUSTC_BOOTSTRAP=1 lets the stable toolchain take
# them. Cargo runs through `flock /tmp/cargo.lock` when flock exists: one build at a time.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)

seconds=${1:-20}
shift || true
if ! [[ "$seconds" =~ ^[0-9]+$ ]] || [ "$seconds" -lt 1 ]; then
  echo "usage: scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET...]" >&2
  exit 2
fi
sanitizer=${FUZZ_SANITIZER:-address}
rss_limit_mb=${FUZZ_RSS_LIMIT_MB:-2048}
timeout_s=${FUZZ_TIMEOUT_S:-30}
export RUSTC_BOOTSTRAP=1
export CARGO_TERM_COLOR=${CARGO_TERM_COLOR:-never}

cargo_locked() {
  if command -v flock >/dev/null 2>&1; then
    flock /tmp/cargo.lock cargo "$@"
  else
    cargo "$@"
  fi
}

if ! cargo fuzz --version >/dev/null 2>&1; then
  echo "== installing cargo-fuzz"
  cargo_locked install cargo-fuzz --locked --version 0.13.2
fi

cd fuzz
if [ $# -gt 0 ]; then
  targets=("$@")
else
  mapfile -t targets < <(cargo fuzz list)
fi

echo "== building the fuzz targets (sanitizer: $sanitizer)"
start=$(date +%s)
# One build of all targets; the runs below execute the binaries directly, without cargo.
cargo_locked fuzz build --sanitizer "$sanitizer"
echo "== built in $(($(date +%s) - start)) s"

host=$(rustc -vV | sed -n 's/^host: //p')
bin_dir="$root/fuzz/target/$host/release"
logs=$(mktemp -d)
trap 'rm -rf "$logs"' EXIT

failed=()
start=$(date +%s)
printf '%-20s %12s %10s %8s\n' target executions exec/s crashes
for t in "${targets[@]}"; do
  seeds="$root/fuzz/seeds/$t"
  corpus="$root/fuzz/corpus/$t"
  artifacts="$root/fuzz/artifacts/$t"
  mkdir -p "$corpus" "$artifacts"
  [ -d "$seeds" ] || { echo "$t: no seeds in $seeds" >&2; exit 2; }
  log="$logs/$t.log"
  dict=()
  [ -f "$root/fuzz/dicts/$t.dict" ] && dict=(-dict="$root/fuzz/dicts/$t.dict")
  status=0
  # New inputs go to the first directory (fuzz/corpus, not committed); the seeds are only read.
  "$bin_dir/$t" \
    -max_total_time="$seconds" \
    -rss_limit_mb="$rss_limit_mb" \
    -timeout="$timeout_s" \
    -print_final_stats=1 \
    -artifact_prefix="$artifacts/" \
    "${dict[@]}" \
    "$corpus" "$seeds" >"$log" 2>&1 || status=$?
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
  artifact=$(sed -n 's/.*Test unit written to \(.*\)$/\1/p' "$log" | tail -1)
  if [ "$status" -eq 0 ]; then
    crashes=0
  else
    crashes=1
    failed+=("$t")
  fi
  printf '%-20s %12s %10s %8s\n' "$t" "${runs:-?}" "${rate:-?}" "$crashes"
  if [ "$status" -ne 0 ]; then
    echo "---- $t exited with status $status:"
    # The panic or sanitizer report, then the end of libFuzzer's log.
    grep -a -m 3 -A 2 -e 'panicked at' -e '==ERROR:' -e 'ERROR: libFuzzer' "$log" || true
    echo "---- the end of its log:"
    tail -n 15 "$log"
    echo "---- $t: crashing input: ${artifact:-(none written; see the log above)}"
    echo "---- reproduce (in fuzz/): RUSTC_BOOTSTRAP=1 cargo fuzz run $t ${artifact:-ARTIFACT}"
  fi
done
echo "== fuzzed ${#targets[@]} targets for ${seconds} s each in $(($(date +%s) - start)) s"
if [ ${#failed[@]} -gt 0 ]; then
  echo "== crashes in: ${failed[*]} (inputs under fuzz/artifacts/)" >&2
  exit 1
fi
