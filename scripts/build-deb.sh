#!/usr/bin/env bash
# Builds the Debian packages with cargo-deb: videt_*.deb and videt-dbgsym_*.ddeb (the debug
# symbols) in $CARGO_TARGET_DIR/debian. First the release binaries (with V4L2 capture) and
# videt-assets, which writes the manual pages and shell completions from the command-line
# definitions into target/package-assets (Cargo.toml's deb assets take them from there); then
# `cargo deb --no-build` packs them. Prints the .deb's path on its last line.
#
#   scripts/build-deb.sh                  CARGO_TARGET_DIR (default target) as cargo uses it
#   VIDET_DEB_FEATURES= scripts/build-deb.sh   without V4L2 capture (no libclang needed)
#
# CARGO names the cargo command (default: cargo); cargo-deb is installed when missing.
set -euo pipefail
cd "$(dirname "$0")/.."
CARGO=${CARGO:-cargo}
TARGET=${CARGO_TARGET_DIR:-target}
FEATURES=${VIDET_DEB_FEATURES-v4l}
ASSETS=target/package-assets

if ! "$CARGO" deb --version >/dev/null 2>&1; then
  echo "== build-deb: installing cargo-deb" >&2
  "$CARGO" install cargo-deb --locked >&2
fi
echo "== build-deb: release binaries (features: ${FEATURES:-none})" >&2
"$CARGO" build --release -p videt --bins ${FEATURES:+--features "$FEATURES"} >&2
echo "== build-deb: manual pages and completions in $ASSETS" >&2
rm -rf "$ASSETS"
"$TARGET/release/videt-assets" "$ASSETS" >/dev/null
"$CARGO" deb --no-build | tail -n 1
