#!/usr/bin/env bash
# The layering of docs/architecture.md as Cargo resolves it: fails when a crate depends on a
# layer above its own, or when videtd built without the `tool` feature pulls in the tools, the
# paper's experiments or the plotting stack. Prints one line per check; exits 1 on any FAIL.
set -euo pipefail
cd "$(dirname "$0")/.."
fail=0

# Every package `$1` depends on (normal dependencies, all depths), one name per line.
deps_of() {
  cargo tree -p "$1" -e normal --prefix none "${@:2}" | awk '{print $1}' | sort -u
}

# `$1` (with cargo tree options in FLAGS) must not depend on any of the other arguments.
refuse() {
  local crate=$1
  shift
  local deps
  deps=$(deps_of "$crate" ${FLAGS:-})
  local bad=()
  for f in "$@"; do
    if grep -qx "$f" <<<"$deps"; then bad+=("$f"); fi
  done
  if [ ${#bad[@]} -gt 0 ]; then
    echo "FAIL: $crate ${FLAGS:-} depends on ${bad[*]}"
    fail=1
  else
    echo "PASS: $crate ${FLAGS:-} depends on none of: $*"
  fi
}

layers=(videt-runtime videt-viewers videt-assembly videt-service videt-tools)
for domain in videt-hal videt-can-timing videt-control videt-vision videt-drivers videt-sim \
  videt-rt-config videt-colour videt-experiments; do
  refuse "$domain" "${layers[@]}"
done
# The core knows nothing above it, and neither the hardware nor the twin (directly: the
# configuration crate reads drive description files with the drivers' EDS reader).
refuse videt-runtime videt-assembly videt-service videt-tools videt-experiments plotters
FLAGS="--depth 1" refuse videt-runtime videt-drivers videt-sim
# The viewers' topics sit on the core: the service serves them live, the tools export them.
refuse videt-viewers videt-assembly videt-service videt-tools videt-experiments plotters
refuse videt-assembly videt-service videt-tools videt-experiments plotters
refuse videt-service videt-tools videt-experiments plotters
# videtd alone: the service, without the tool's analysis, plots and experiments.
FLAGS=--no-default-features refuse videt videt-tools videt-experiments plotters

exit $fail
