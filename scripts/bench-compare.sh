#!/usr/bin/env bash
# The control path's and the vision path's benchmarks of two revisions in one run, on this
# machine, one after the other: per benchmark BASE (a commit, checked out in a temporary
# worktree), then the working tree, then BASE again, each saved as a criterion baseline. Printed:
# the working tree against BASE (criterion's change with its confidence interval), and BASE
# against itself a run later (the machine's drift over the same time: a change smaller than
# that is noise). Timings on a shared VM are noisy: read the medians and compare the ratios of
# one run, never absolutes.
#
#   scripts/bench-compare.sh BASE [SECONDS] [BENCH...]   SECONDS of measurement per benchmark
#                                                        (default 3); only the BENCHes named
#
# The shared data is taken from VIDET_DATA_DIR, else beside this checkout (both revisions must
# measure the same pairs).
#
# The benchmarks (package in BASE, package here, bench, filter):
# - the control path: one control step per device and algorithm (videt-control control_step),
#   the CiA 402 drive set's cyclic exchange (videt-drivers cia402_cycle_exchange);
# - the vision path: the stereo pipeline's stages and the whole pipeline (videt-vision
#   stereo_pipeline_stages), the relief's build and its queries from the control thread
#   (surface_build, surface_queries: in videt-vision before the relief had a crate of its own),
#   a camera frame to the control thread's relief feed (videt frame_to_force).
set -euo pipefail
cd "$(dirname "$0")/.."
BASE=${1:?usage: $0 BASE [SECONDS] [BENCH...]}
SECONDS_EACH=${2:-3}
ONLY=("${@:3}")
HERE=$(pwd)
export VIDET_DATA_DIR=${VIDET_DATA_DIR:-$(cd "$HERE/.." && pwd)/shared/data}
[ -d "$VIDET_DATA_DIR" ] || { echo "bench-compare: no shared data at $VIDET_DATA_DIR (VIDET_DATA_DIR)" >&2; exit 2; }
benches=(
  "videt-control control_step"
  "videt-drivers cia402_cycle_exchange"
  "videt-vision stereo_pipeline_stages"
  "videt-relief surface_build"
  "videt-relief surface_queries"
  "videt frame_to_force"
)
if [ ${#ONLY[@]} -gt 0 ]; then
  chosen=()
  for name in "${ONLY[@]}"; do
    found=
    for entry in "${benches[@]}"; do
      [ "${entry#* }" = "$name" ] && chosen+=("$entry") && found=1
    done
    [ -n "$found" ] || {
      echo "bench-compare: no bench $name; the benches: $(printf '%s ' "${benches[@]#* }")" >&2
      exit 2
    }
  done
  benches=("${chosen[@]}")
fi
WORK=$(mktemp -d /tmp/videt-bench-compare.XXXXXX)
# BASE's builds are kept between runs (its dependencies take long to build with the bench
# profile's LTO).
BASE_TARGET=$HERE/target/bench-base
trap 'git -C "$HERE" worktree remove --force "$WORK/base" >/dev/null 2>&1 || true; rm -rf "$WORK"' EXIT
git worktree add --detach "$WORK/base" "$BASE" >/dev/null
# Both revisions' criterion data in one place, so that each compares with the other's baseline.
export CRITERION_HOME=$WORK/criterion
# The package a bench lives in, in BASE.
base_package() {
  local package=$1 bench=$2
  if [ "$package" = videt-relief ] && [ ! -d "$WORK/base/relief" ]; then
    echo videt-vision
  else
    echo "$package"
  fi
}
criterion_args=(--warm-up-time 1 --measurement-time "$SECONDS_EACH" --noplot)
# Where a revision's benches are built.
target_of() {
  if [ "$1" = "$HERE" ]; then echo "$HERE/target"; else echo "$BASE_TARGET"; fi
}
run() {
  local dir=$1 package=$2 bench=$3
  shift 3
  (cd "$dir" && CARGO_TARGET_DIR=$(target_of "$dir") cargo bench --quiet -p "$package" --bench "$bench" -- \
    "${criterion_args[@]}" "$@")
}
build() {
  local dir=$1 package=$2 bench=$3
  (cd "$dir" && CARGO_TARGET_DIR=$(target_of "$dir") cargo bench --quiet --no-run -p "$package" \
    --bench "$bench") >&2
}
echo "== building both revisions' benches" >&2
for entry in "${benches[@]}"; do
  read -r package bench <<<"$entry"
  build "$WORK/base" "$(base_package "$package" "$bench")" "$bench"
  build "$HERE" "$package" "$bench"
done
for entry in "${benches[@]}"; do
  read -r package bench <<<"$entry"
  base_pkg=$(base_package "$package" "$bench")
  echo "== $bench: $BASE, measured (baseline base)" >&2
  run "$WORK/base" "$base_pkg" "$bench" --save-baseline base >/dev/null
  echo "== $bench: the working tree, measured (baseline head)" >&2
  run "$HERE" "$package" "$bench" --save-baseline head >/dev/null
  echo "== $bench: $BASE measured again (baseline base2)" >&2
  run "$WORK/base" "$base_pkg" "$bench" --save-baseline base2 >/dev/null
  echo "== $bench: the working tree against $BASE"
  run "$HERE" "$package" "$bench" --load-baseline head --baseline base
  echo "== $bench: $BASE against itself a run later (the machine's drift)"
  run "$WORK/base" "$base_pkg" "$bench" --load-baseline base2 --baseline base
done
