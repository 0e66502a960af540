#!/usr/bin/env bash
# lintian on the packages scripts/build-deb.sh made: fails on any error or warning (the
# information lines are printed, not counted).
#
#   scripts/lintian-check.sh PACKAGE.deb [PACKAGE.ddeb ...]
#
# Installs lintian with apt-get when it is missing.
set -euo pipefail
[ $# -gt 0 ] || { echo "usage: $0 PACKAGE.deb [PACKAGE.ddeb ...]" >&2; exit 2; }
if ! command -v lintian >/dev/null 2>&1; then
  echo "== lintian-check: installing lintian" >&2
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq lintian >/dev/null
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
rc=0
for pkg in "$@"; do
  # lintian reads a .ddeb by the name .deb (it is one).
  case $pkg in
    *.ddeb) cp "$pkg" "$tmp/$(basename "${pkg%.ddeb}").deb"; file=$tmp/$(basename "${pkg%.ddeb}").deb ;;
    *) file=$pkg ;;
  esac
  echo "== lintian $(basename "$pkg")"
  status=0
  out=$(lintian --info --fail-on error,warning --tag-display-limit 0 "$file" 2>&1) || status=$?
  printf '%s\n' "$out" | grep -v '^running with root privileges' || true
  [ "$status" = 0 ] || { echo "FAIL: lintian $(basename "$pkg") (exit $status)"; rc=1; }
done
[ "$rc" = 0 ] && echo "lintian-check: PASS (no error, no warning)"
exit "$rc"
