#!/usr/bin/env bash
# The control path's and the vision path's benchmarks of two revisions in one run, on this
# machine, one after the other: BASE (a commit, checked out in a temporary worktree) saves
# criterion baselines, then the working tree is measured against them (criterion prints each
# change with its confidence interval), then BASE again against the working tree's (a drift of
# the machine between the two shows as a change in both directions). Timings on a shared VM are
# noisy: read the medians and compare the ratios of one run, never absolutes.
#
#   scripts/bench-compare.sh BASE [SECONDS]   SECONDS of measurement per benchmark (default 3)
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
BASE=${1:?usage: $0 BASE [SECONDS]}
SECONDS_EACH=${2:-3}
HERE=$(pwd)
WORK=$(mktemp -d /tmp/videt-bench-compare.XXXXXX)
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
benches=(
  "videt-control control_step"
  "videt-drivers cia402_cycle_exchange"
  "videt-vision stereo_pipeline_stages"
  "videt-relief surface_build"
  "videt-relief surface_queries"
  "videt frame_to_force"
)
criterion_args=(--warm-up-time 1 --measurement-time "$SECONDS_EACH" --noplot)
run() {
  local dir=$1 package=$2 bench=$3
  shift 3
  (cd "$dir" && CARGO_TARGET_DIR=$dir/target cargo bench --quiet -p "$package" --bench "$bench" -- \
    "${criterion_args[@]}" "$@")
}
echo "== building both revisions' benches" >&2
for entry in "${benches[@]}"; do
  read -r package bench <<<"$entry"
  (cd "$WORK/base" && CARGO_TARGET_DIR=$WORK/base/target cargo bench --quiet --no-run \
    -p "$(base_package "$package" "$bench")" --bench "$bench") >&2
  (cd "$HERE" && CARGO_TARGET_DIR=$HERE/target cargo bench --quiet --no-run -p "$package" \
    --bench "$bench") >&2
done
for entry in "${benches[@]}"; do
  read -r package bench <<<"$entry"
  echo "== $bench: $BASE (baseline)"
  run "$WORK/base" "$(base_package "$package" "$bench")" "$bench" --save-baseline base >/dev/null
  echo "== $bench: the working tree against $BASE"
  run "$HERE" "$package" "$bench" --save-baseline head --baseline base
  echo "== $bench: $BASE again, against the working tree"
  run "$WORK/base" "$(base_package "$package" "$bench")" "$bench" --baseline head
done
