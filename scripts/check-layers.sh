#!/usr/bin/env bash
# The layering of docs/architecture.md as Cargo resolves it, over each crate's whole dependency
# tree: fails when a crate reaches a layer above its own, when the core reaches the hardware,
# the twin or the vision pipeline, or when videtd's package pulls in the tools, the paper's
# experiments or the plotting stack. Prints one line per check; exits 1 on any FAIL.
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

layers=(videt-runtime videt-viewers videt-assembly videt-service videt-tools videtd videt)
# The hardware and the twin: what the core never reaches, at any depth.
hardware=(videt-drivers videt-sim socketcan gpio-cdev linux-embedded-hal v4l canopen-rs)
for domain in videt-hal videt-can-timing videt-drive-description videt-control videt-relief \
  videt-vision videt-drivers videt-sim videt-config videt-colour videt-experiments; do
  refuse "$domain" "${layers[@]}"
done
# The core knows nothing above it, and neither the hardware nor the twin (the whole tree: the
# configuration reads drive description files with `videt-drive-description`, below the
# drivers; the runtime records reliefs with `videt-relief`, not the vision pipeline).
refuse videt-runtime videt-assembly videt-service videt-tools videt-experiments plotters \
  videt-vision "${hardware[@]}"
for core in videt-hal videt-drive-description videt-control videt-relief videt-config; do
  refuse "$core" videt-vision "${hardware[@]}"
done
# The viewers' topics sit on the core: the service serves them live, the tools export them.
refuse videt-viewers videt-assembly videt-service videt-tools videt-experiments plotters
refuse videt-assembly videt-service videt-tools videt-experiments plotters
refuse videt-service videt-tools videt-experiments plotters
# videtd's package: the service, without the tool's analysis, plots and experiments.
refuse videtd videt-tools videt-experiments plotters

exit $fail
