#!/usr/bin/env bash
# Builds the Debian packages with cargo-deb: videt_*.deb and videt-dbgsym_*.ddeb (the debug
# symbols) in $CARGO_TARGET_DIR/debian. First the release binaries (with V4L2 capture) and
# videt-assets, which writes the manual pages and shell completions from the command-line
# definitions into target/package-assets (Cargo.toml's deb assets take them from there); then
# `cargo deb --no-build` packs them. Then the -dbgsym package is made what debhelper makes
# (cargo-deb 3.8 writes it with Priority: extra, only recommending the package, and without the
# copyright and changelog that lintian requires): Priority optional, Depends on the exact
# videt, its doc directory a symlink to videt's (copyright, changelog), a Build-Ids field and
# md5sums.
# Prints the .deb's path on its last line.
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
"$CARGO" build --release -p videt -p videtd --bins ${FEATURES:+--features "$FEATURES"} >&2
echo "== build-deb: manual pages and completions in $ASSETS" >&2
rm -rf "$ASSETS"
"$TARGET/release/videt-assets" "$ASSETS" >/dev/null
DEB=$("$CARGO" deb --no-build | tail -n 1)
[ -f "$DEB" ] || { echo "build-deb: cargo deb printed no package path: $DEB" >&2; exit 1; }

# The -dbgsym package as debhelper's dh_strip and dh_gencontrol make it.
DDEB=$(dirname "$DEB")/$(basename "$DEB" | sed 's/^videt_/videt-dbgsym_/; s/\.deb$/.ddeb/')
if [ -f "$DDEB" ]; then
  echo "== build-deb: $(basename "$DDEB") as debhelper makes it" >&2
  tmp=$(mktemp -d)
  trap 'rm -rf "$tmp"' EXIT
  dpkg-deb -R "$DDEB" "$tmp/pkg"
  control=$tmp/pkg/DEBIAN/control
  name=$(sed -n 's/^Package: //p' "$control")
  main=${name%-dbgsym}
  version=$(sed -n 's/^Version: //p' "$control")
  build_ids=$(find "$tmp/pkg/usr/lib/debug/.build-id" -name '*.debug' -printf '%h/%f\n' |
    sed -E 's|.*/([0-9a-f]{2})/([0-9a-f]+)\.debug$|\1\2|' | sort | tr '\n' ' ' | sed 's/ $//')
  sed -i -e 's/^Priority: .*/Priority: optional/' \
    -e '/^Recommends: /d; /^Depends: /d; /^Build-Ids: /d; /^$/d' \
    -e "s/^Description: .*/Depends: $main (= $version)\nDescription: debug symbols for $main/" \
    "$control"
  [ -z "$build_ids" ] || sed -i "s/^Description: /Build-Ids: $build_ids\n&/" "$control"
  # The doc directory: a symlink to the main package's (its copyright and changelog).
  rm -rf "$tmp/pkg/usr/share/doc/$name"
  mkdir -p "$tmp/pkg/usr/share/doc"
  ln -s "$main" "$tmp/pkg/usr/share/doc/$name"
  (cd "$tmp/pkg" && find usr -type f -print0 | LC_ALL=C sort -z | xargs -0r md5sum >DEBIAN/md5sums)
  # The times of cargo-deb's entries, for the new ones too (a reproducible package).
  SOURCE_DATE_EPOCH=$(stat -c %Y "$tmp/pkg/usr/lib/debug") \
    dpkg-deb --root-owner-group -Zxz -b "$tmp/pkg" "$tmp/out.ddeb" >/dev/null
  mv "$tmp/out.ddeb" "$DDEB"
fi
echo "$DEB"
