#!/usr/bin/env bash
# Debian package install test: builds the videt .deb with cargo-deb (scripts/build-deb.sh), runs
# lintian on it and on its videt-dbgsym .ddeb (no error, no warning: scripts/lintian-check.sh),
# installs it with dpkg into a clean Debian bookworm root (debootstrap minbase with systemd and
# udev, as on the backpack computer, but in a chroot where systemd is not running; man-db added
# to read the pages) and checks what the package promises: the user, the files and their owners,
# the conffile, the service neither enabled nor started, a clean `systemd-analyze verify` of the
# unit, the binaries running there (stripped, their build ids in videt-dbgsym), `man videtd`,
# `man videt-init` and `man videt.toml` and the shell completions where each shell looks; then a
# reinstall keeps an edited configuration, and remove and purge leave nothing of the package behind. A second
# round installs without systemd-sysusers (the maintainer scripts' fallback to useradd). The
# package under a running systemd is scripts/systemd-in-the-loop.sh.
#
#   scripts/deb-install-test.sh              build the package, then test it
#   scripts/deb-install-test.sh --no-build   test the newest target/guest/debian/videt_*.deb
#   scripts/deb-install-test.sh --keep       keep the root in target/deb-test/root (debugging)
#   scripts/deb-install-test.sh --root-only  only make the cached bookworm root (the systemd
#                                            guest's, scripts/systemd-in-the-loop.sh)
#
# Needs root (debootstrap, chroot, mount) and the network to a Debian mirror (the first bookworm
# mirror of this machine's apt sources, or VIDET_DEBIAN_MIRROR); crates.io when cargo-deb has to
# be installed. The package is built from the guests' binaries, in target/guest (release, with
# V4L2 capture; scripts/kil/host.sh), and written to target/guest/debian. The bootstrapped root
# is cached as target/deb-test/bookworm-minbase-systemd-udev-v4l.tar: later runs unpack it
# instead of bootstrapping (delete it to bootstrap afresh). man-db and what it needs beside that
# root (groff-base, ...) are fetched from the root's mirror on the first run, kept as .debs in
# target/deb-test/man-db-debs and installed from there into each run's root, so later runs need
# no network; the root stays that of the systemd guest. CARGO names the cargo command to run
# (default: cargo). Prints PASS/FAIL lines and exits 1 on any FAIL.
# The checks are shell snippets run inside the root: their $ expand there, not here.
# shellcheck disable=SC2016
set -euo pipefail
cd "$(dirname "$0")/.."
REPO=$PWD
WORK=$REPO/target/deb-test
ROOT=$WORK/root
SUITE=bookworm
# systemd and udev, as on the backpack computer (udev makes the device units the service waits
# for, e.g. sys-subsystem-net-devices-can0.device, and applies the package's device rules);
# v4l-utils for the systemd guest to set its emulated cameras up.
INCLUDE=systemd,udev,v4l-utils
CACHE=$WORK/$SUITE-minbase-systemd-udev-v4l.tar
# man-db's packages, fetched once for that root (removed with it when it is bootstrapped afresh).
MAN_DEBS=$WORK/man-db-debs
CARGO=${CARGO:-cargo}
export CARGO_TARGET_DIR=$REPO/target/guest
BUILD=1
KEEP=0
ROOT_ONLY=0
while [ $# -gt 0 ]; do
  case $1 in
    --no-build) BUILD=0 ;;
    --keep) KEEP=1 ;;
    --root-only) ROOT_ONLY=1 ;;
    *) echo "usage: $0 [--no-build] [--keep] [--root-only]" >&2; exit 2 ;;
  esac
  shift
done

log() { printf '== deb-install-test: %s\n' "$*" >&2; }
die() { echo "FAIL: $*"; exit 1; }
now() { date +%s; }
T0=$(now)
TIMES=()
phase_done() { TIMES+=("$1 $(($(now) - $2))s"); }

[ "$(id -u)" = 0 ] || die "needs root (debootstrap, chroot, mount)"
mkdir -p "$WORK"

# --- mounts and clean-up ----------------------------------------------------------------------
# Mount points under $1, deepest first.
mounts_under() {
  awk -v d="$1/" 'index($2, d) == 1 { print $2 }' /proc/self/mounts | sort -r
}
unmount_under() {
  local m
  for m in $(mounts_under "$1"); do
    umount "$m" 2>/dev/null || umount -l "$m"
  done
}
remove_tree() {
  [ -e "$1" ] || return 0
  unmount_under "$1"
  [ -z "$(mounts_under "$1")" ] || die "$1 still has mounts; not removing it"
  rm -rf --one-file-system "$1"
}
cleanup() {
  unmount_under "$ROOT"
  if [ "$KEEP" = 1 ]; then
    log "root kept in $ROOT"
  else
    remove_tree "$ROOT"
  fi
}
trap cleanup EXIT

# --- host tools -------------------------------------------------------------------------------
need=()
for tool in debootstrap:debootstrap chroot:coreutils; do
  command -v "${tool%%:*}" >/dev/null 2>&1 || need+=("${tool#*:}")
done
# The package's build: bindgen for V4L2 capture.
[ "$ROOT_ONLY" = 1 ] || dpkg -s libclang-dev >/dev/null 2>&1 || need+=(libclang-dev)
if [ ${#need[@]} -gt 0 ]; then
  log "installing ${need[*]}"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need[@]}" >/dev/null
fi

# --- the package ------------------------------------------------------------------------------
t=$(now)
if [ "$ROOT_ONLY" = 1 ]; then
  :
elif [ "$BUILD" = 1 ]; then
  log "building the package (release profile; log: $WORK/build.log)"
  if ! DEB=$(CARGO="$CARGO" bash scripts/build-deb.sh 2>"$WORK/build.log" | tail -n 1) || [ ! -f "$DEB" ]; then
    tail -n 30 "$WORK/build.log" >&2
    die "cargo deb failed"
  fi
else
  # shellcheck disable=SC2012 # the newest by time; the names are cargo-deb's
  DEB=$(ls -t "$CARGO_TARGET_DIR"/debian/videt_*.deb 2>/dev/null | head -n 1) || true
  [ -n "$DEB" ] || die "no $CARGO_TARGET_DIR/debian/videt_*.deb; run without --no-build"
fi
if [ "$ROOT_ONLY" = 0 ]; then
  echo "package: $DEB"
  phase_done package "$t"
  # lintian: a new error or warning fails the test (and CI).
  t=$(now)
  DBGSYM=$(dirname "$DEB")/$(basename "$DEB" | sed 's/^videt_/videt-dbgsym_/; s/\.deb$/.ddeb/')
  [ -f "$DBGSYM" ] || die "no debug symbols package $DBGSYM beside $DEB"
  echo "debug symbols: $DBGSYM"
  bash scripts/lintian-check.sh "$DEB" "$DBGSYM" || die "lintian reports errors or warnings"
  phase_done lintian "$t"
fi

# --- a clean bookworm root --------------------------------------------------------------------
# The mirror: the first one this machine's apt takes bookworm from (one-line and deb822 sources).
apt_mirror() {
  local f
  for f in /etc/apt/sources.list /etc/apt/sources.list.d/*.list; do
    [ -f "$f" ] || continue
    awk -v s="$SUITE" '$1 == "deb" { i = 2; if ($2 ~ /^\[/) { while (i <= NF && $i !~ /\]$/) i++; i++ }
      if ($(i + 1) == s) { print $i; exit } }' "$f"
  done
  for f in /etc/apt/sources.list.d/*.sources; do
    [ -f "$f" ] || continue
    awk -v s="$SUITE" 'function flush() { if (deb && on && uris != "" && (" " suites " ") ~ (" " s " "))
        { split(uris, u, " "); print u[1]; found = 1; exit } deb = 0; on = 1; uris = ""; suites = "" }
      BEGIN { on = 1 }
      /^[ \t]*$/ { flush(); next }
      tolower($1) == "types:" { for (i = 2; i <= NF; i++) if ($i == "deb") deb = 1 }
      tolower($1) == "enabled:" { on = (tolower($2) != "no") }
      tolower($1) == "uris:" { $1 = ""; uris = $0 }
      tolower($1) == "suites:" { $1 = ""; suites = $0 }
      END { if (!found) flush() }' "$f"
  done
}

t=$(now)
if [ ! -f "$CACHE" ]; then
  MIRROR=${VIDET_DEBIAN_MIRROR:-$(apt_mirror | head -n 1)}
  MIRROR=${MIRROR:-http://deb.debian.org/debian}
  log "bootstrapping $SUITE (minbase + $INCLUDE) from $MIRROR (log: $WORK/debootstrap.log)"
  remove_tree "$WORK/bootstrap"
  if ! debootstrap --variant=minbase --include="$INCLUDE" "$SUITE" "$WORK/bootstrap" "$MIRROR" \
    >"$WORK/debootstrap.log" 2>&1; then
    tail -n 30 "$WORK/debootstrap.log" >&2
    remove_tree "$WORK/bootstrap"
    die "debootstrap failed"
  fi
  unmount_under "$WORK/bootstrap"
  rm -f "$WORK/bootstrap"/var/cache/apt/archives/*.deb
  tar -C "$WORK/bootstrap" -cf "$CACHE.tmp" . && mv "$CACHE.tmp" "$CACHE"
  rm -rf "$MAN_DEBS"
  remove_tree "$WORK/bootstrap"
  phase_done bootstrap "$t"
fi
if [ "$ROOT_ONLY" = 1 ]; then
  echo "root: $CACHE"
  exit 0
fi
t=$(now)
remove_tree "$ROOT"
mkdir -p "$ROOT"
tar -C "$ROOT" -xf "$CACHE"
mount -t proc proc "$ROOT/proc"
for dev in null:1:3 zero:1:5 full:1:7 random:1:8 urandom:1:9 tty:5:0; do
  IFS=: read -r name major minor <<<"$dev"
  [ -c "$ROOT/dev/$name" ] || { rm -f "$ROOT/dev/$name"; mknod -m 666 "$ROOT/dev/$name" c "$major" "$minor"; }
done
cp "$DEB" "$ROOT/tmp/videt.deb"
cp "$DBGSYM" "$ROOT/tmp/videt-dbgsym.deb"
phase_done unpack-root "$t"

# --- checks -----------------------------------------------------------------------------------
FAILS=0
in_root() {
  chroot "$ROOT" /usr/bin/env -i PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin \
    HOME=/root LANG=C.UTF-8 DEBIAN_FRONTEND=noninteractive "$@"
}
# report NAME STATUS OUTPUT: a PASS line, or a FAIL line with the end of the output.
report() {
  if [ "$2" = 0 ]; then
    echo "PASS: $1"
  else
    echo "FAIL: $1"
    printf '%s\n' "$3" | tail -n 20 | sed 's/^/    /'
    FAILS=$((FAILS + 1))
  fi
}
# check NAME SNIPPET: runs the shell snippet in the root with `sh -ec`.
check() {
  local out rc=0
  out=$(in_root sh -ec "$2" 2>&1) || rc=$?
  report "$1" "$rc" "$out"
}
# check_host NAME SNIPPET: the same on the host, with bash (paths under $ROOT).
check_host() {
  local out rc=0
  out=$(bash -ec "$2" 2>&1) || rc=$?
  report "$1" "$rc" "$out"
}
# dpkg -i in the root; dependencies from the root's mirror if dpkg lacks them. Output in $1.
install_package() {
  if ! in_root dpkg -i /tmp/videt.deb >"$1" 2>&1; then
    log "dpkg -i failed; installing dependencies with apt-get -f"
    in_root apt-get update -qq >>"$1" 2>&1 || true
    in_root apt-get -f install -y -qq >>"$1" 2>&1 || true
  fi
}
# Processes whose root directory is the test root (a started service would be one).
root_processes() {
  local p
  for p in /proc/[0-9]*; do
    [ "$(readlink "$p/root" 2>/dev/null)" = "$ROOT" ] && echo "${p#/proc/} $(cat "$p/comm" 2>/dev/null)"
  done
  return 0
}
export ROOT
export -f root_processes
FILES="/usr/bin/videtd /usr/bin/videt /lib/systemd/system/videtd.service \
  /usr/lib/sysusers.d/videt.conf /usr/lib/udev/rules.d/60-videt.rules /etc/videt/videt.toml /usr/share/doc/videt/README.md \
  /usr/share/doc/videt/videt.example.toml /usr/share/doc/videt/copyright \
  /usr/share/doc/videt/changelog.Debian.gz /usr/share/man/man8/videtd.8.gz /usr/share/man/man1/videt.1.gz \
  /usr/share/man/man1/videt-init.1.gz /usr/share/man/man1/videt-config-check.1.gz \
  /usr/share/man/man5/videt.toml.5.gz /usr/share/bash-completion/completions/videt \
  /usr/share/zsh/vendor-completions/_videt /usr/share/fish/vendor_completions.d/videt.fish"
USER_CHECK='getent passwd videt | cut -d: -f6,7 | grep -qx "/var/lib/videt:/usr/sbin/nologin"
  groups=" $(id -nG videt) "
  for g in videt video gpio spi; do case $groups in *" $g "*) ;; *) echo "videt not in $g:$groups"; exit 1 ;; esac; done'
DIRS_CHECK='for d in /var/log/videt /var/lib/videt; do
    s=$(stat -c "%U:%G %a" "$d"); [ "$s" = "videt:videt 755" ] || { echo "$d: $s"; exit 1; }
  done'

# man-db (man, groff) as a technician's system has it: from the kept .debs, fetched with the
# root's apt on the first run. Installed before the package, so its trigger indexes the pages.
t=$(now)
if ! ls "$MAN_DEBS"/*.deb >/dev/null 2>&1; then
  log "fetching man-db for the root (once; kept in $MAN_DEBS)"
  rm -rf "$MAN_DEBS.tmp" && mkdir -p "$MAN_DEBS.tmp"
  { in_root apt-get update -qq &&
    in_root apt-get install -y -qq --download-only --no-install-recommends man-db; } \
    >"$WORK/man-db-fetch.log" 2>&1 || { tail -n 20 "$WORK/man-db-fetch.log" >&2; die "fetching man-db failed"; }
  cp "$ROOT"/var/cache/apt/archives/*.deb "$MAN_DEBS.tmp/"
  rm -rf "$MAN_DEBS" && mv "$MAN_DEBS.tmp" "$MAN_DEBS"
  rm -f "$ROOT"/var/cache/apt/archives/*.deb
fi
mkdir -p "$ROOT/tmp/man-db"
cp "$MAN_DEBS"/*.deb "$ROOT/tmp/man-db/"
in_root sh -c 'dpkg -i /tmp/man-db/*.deb' >"$WORK/man-db-install.log" 2>&1 ||
  { tail -n 20 "$WORK/man-db-install.log" >&2; die "installing man-db in the root failed"; }
rm -rf "$ROOT/tmp/man-db"
phase_done man-db "$t"

t=$(now)
echo "--- install (systemd-sysusers; systemd not running)"
install_package "$WORK/dpkg-install.log"
check "dpkg -i installs the package" \
  '[ "$(dpkg-query -W -f="\${Status}" videt)" = "install ok installed" ]'
check_host "postinst says how to configure and start the service" \
  "grep -q 'neither enabled nor started' '$WORK/dpkg-install.log' &&
   grep -q 'systemctl enable --now videtd' '$WORK/dpkg-install.log'"
check "user videt (home /var/lib/videt, nologin) in groups videt, video, gpio, spi" "$USER_CHECK"
check "files in place" "for f in $FILES; do [ -f \"\$f\" ] || { echo \"missing \$f\"; exit 1; }; done
  [ -x /usr/bin/videtd ] && [ -x /usr/bin/videt ]"
check_host "docs in /usr/share/doc/videt/docs" \
  "for f in docs/*.md docs/figures/*.png; do cmp \"\$f\" '$ROOT/usr/share/doc/videt/'\"\$f\"; done"
check "/var/log/videt and /var/lib/videt owned by videt:videt" "$DIRS_CHECK"
check "/etc/videt/videt.toml registered as a conffile" \
  'dpkg-query -W -f="\${Conffiles}\n" videt | grep -q "^ /etc/videt/videt.toml [0-9a-f]\{32\}"'
check_host "/etc/videt/videt.toml is the example configuration" \
  "cmp config/videt.example.toml '$ROOT/etc/videt/videt.toml'"
check "videtd.service not enabled" \
  '[ "$(systemctl is-enabled videtd.service 2>&1 || true)" = disabled ]
   ! find /etc/systemd/system -name videtd.service | grep .'
check_host "videtd not started (no process in the root, no /run/videt)" \
  "[ ! -e '$ROOT/run/videt' ] && [ -z \"\$(root_processes)\" ]"
rc=0
ANALYZE=$(in_root systemd-analyze verify /lib/systemd/system/videtd.service 2>&1) || rc=$?
printf 'exit %s, output: %s\n' "$rc" "${ANALYZE:-(none)}" >"$WORK/systemd-analyze.log"
[ -z "$ANALYZE" ] || [ "$rc" != 0 ] || rc=1
report "systemd-analyze verify videtd.service is clean" "$rc" "$ANALYZE"
check "videt config check /etc/videt/videt.toml (as user videt) succeeds" \
  'setpriv --reuid=videt --regid=videt --init-groups videt config check /etc/videt/videt.toml >/tmp/check.out
   head -n 1 /tmp/check.out | grep -qx "# /etc/videt/videt.toml: valid"'
check "videt --version" 'videt --version | grep -q "^videt 0\."'
check "videtd --version: built with V4L2 capture" 'videtd --version | grep -q "with V4L2 capture"'
check "videtd --help" 'videtd --help | grep -q -- "--config"'
check "videt --version and videtd --version name the commit" \
  'videt --version | grep -q "(commit [0-9a-f]\{12\}\|(commit unknown"
   videtd --version | grep -q "(commit [0-9a-f]\{12\}\|(commit unknown"'
# rustc's .debug_gdb_scripts is loaded with the program (it names gdb's pretty-printers, no
# symbol): strip keeps it, as dh_strip does.
check_host "the installed binaries are stripped (their symbols in videt-dbgsym)" \
  "for b in '$ROOT/usr/bin/videtd' '$ROOT/usr/bin/videt'; do
     left=\$(readelf -S --wide \"\$b\" | grep -e '\\.debug_' -e '\\.symtab' | grep -v '\\.debug_gdb_scripts' || true)
     [ -z \"\$left\" ] || { echo \"\$b is not stripped: \$left\"; exit 1; }
   done"
check "manual pages: gzipped, well-formed roff with a NAME section" \
  'for p in /usr/share/man/man8/videtd.8.gz /usr/share/man/man1/videt-init.1.gz /usr/share/man/man5/videt.toml.5.gz; do
     gzip -t "$p" && zcat "$p" | grep -q "^\.SH NAME"
   done
   [ "$(ls /usr/share/man/man1/videt*.1.gz | wc -l)" -ge 19 ]'
# man as a technician types it: man-db finds the page, groff formats it (no pager: not a terminal).
rc=0
MAN_OUT=$(in_root sh -ec 'for page in videtd videt-init "5 videt.toml"; do
    out=$(MANWIDTH=200 man $page 2>&1) || { printf "man %s failed: %s\n" "$page" "$out"; exit 1; }
    printf "%s\n" "$out" | sed -n "/^NAME\$/{n;s/^ *//;p;q}"
  done' 2>&1) || rc=$?
printf '%s\n' "$MAN_OUT" >"$WORK/man.log"
[ "$rc" != 0 ] || printf '%s\n' "$MAN_OUT" | grep -Eq '^videtd +- +VIDET service' || rc=1
[ "$rc" != 0 ] || printf '%s\n' "$MAN_OUT" | grep -Eq '^videt.init +- +Auto-initialize the rig' || rc=1
[ "$rc" != 0 ] || printf '%s\n' "$MAN_OUT" | grep -Eq '^videt\.toml +- ' || rc=1
report "man videtd, man videt-init, man 5 videt.toml print their NAME lines" "$rc" "$MAN_OUT"
check "videt-dbgsym installs beside videt; its doc is videt's (copyright, changelog)" \
  'dpkg -i /tmp/videt-dbgsym.deb >/dev/null
   [ "$(dpkg-query -W -f="\${Status}" videt-dbgsym)" = "install ok installed" ]
   [ "$(readlink /usr/share/doc/videt-dbgsym)" = videt ]
   [ -f /usr/share/doc/videt-dbgsym/copyright ] && [ -f /usr/share/doc/videt-dbgsym/changelog.Debian.gz ]'
check_host "videt-dbgsym holds the installed binaries' symbols, by their build ids" \
  "for b in '$ROOT/usr/bin/videtd' '$ROOT/usr/bin/videt'; do
     id=\$(readelf -n \"\$b\" | awk '/Build ID:/ { print \$3 }')
     [ -n \"\$id\" ] || { echo \"\$b: no build id\"; exit 1; }
     f='$ROOT/usr/lib/debug/.build-id/'\${id:0:2}/\${id:2}.debug
     readelf -S --wide \"\$f\" | grep -q '\\.debug_line' || { echo \"no line tables in \$f\"; exit 1; }
   done"
check "dpkg -r videt-dbgsym removes it" 'dpkg -r videt-dbgsym >/dev/null
  ! dpkg-query -W -f="\${Status}" videt-dbgsym 2>/dev/null | grep -q "ok installed"
  [ ! -e /usr/lib/debug/.build-id ] || [ -z "$(find /usr/lib/debug/.build-id -name "*.debug")" ]'
check "bash completion parses and completes the subcommands" \
  'bash -n /usr/share/bash-completion/completions/videt
   bash -c ". /usr/share/bash-completion/completions/videt; COMP_WORDS=(videt ini); COMP_CWORD=1; COMP_LINE=\"videt ini\"; COMP_POINT=9; _videt videt ini videt; printf \"%s\n\" \"\${COMPREPLY[@]}\"" | grep -qx init'

echo "--- reinstall over an edited configuration"
check "edit /etc/videt/videt.toml" 'echo "# edited for this device" >>/etc/videt/videt.toml'
install_package "$WORK/dpkg-reinstall.log"
check "dpkg -i again (upgrade path of the scripts)" \
  '[ "$(dpkg-query -W -f="\${Status}" videt)" = "install ok installed" ]'
check "the edited conffile is kept" 'tail -n 1 /etc/videt/videt.toml | grep -qx "# edited for this device"'
check "user and directories unchanged" "$USER_CHECK
  $DIRS_CHECK"

echo "--- remove and purge"
check "dpkg -r removes the package" 'dpkg -r videt
  [ "$(dpkg-query -W -f="\${Status}" videt)" = "deinstall ok config-files" ]'
check "binaries, unit and docs gone; the conffile stays" \
  'for f in /usr/bin/videtd /usr/bin/videt /lib/systemd/system/videtd.service \
     /usr/lib/sysusers.d/videt.conf /usr/lib/udev/rules.d/60-videt.rules /usr/share/doc/videt; do [ ! -e "$f" ] || { echo "left: $f"; exit 1; }; done
   [ -f /etc/videt/videt.toml ]'
check "dpkg -P purges the package" 'dpkg -P videt
  ! dpkg-query -W -f="\${Status}" videt 2>/dev/null | grep -q ok'
check "purge leaves no /etc/videt, /var/log/videt, /var/lib/videt" \
  'for d in /etc/videt /var/log/videt /var/lib/videt; do [ ! -e "$d" ] || { echo "left: $d"; exit 1; }; done'
check_host "no process left in the root" "[ -z \"\$(root_processes)\" ]"
phase_done "install-checks(sysusers)" "$t"

t=$(now)
echo "--- install without systemd-sysusers (useradd fallback)"
check "hide systemd-sysusers, delete user videt and groups gpio, spi" \
  'mv /usr/bin/systemd-sysusers /usr/bin/systemd-sysusers.hidden
   userdel videt; ! getent group videt || groupdel videt; groupdel gpio; groupdel spi'
install_package "$WORK/dpkg-install-fallback.log"
check "dpkg -i installs the package" \
  '[ "$(dpkg-query -W -f="\${Status}" videt)" = "install ok installed" ]'
check "user videt (home /var/lib/videt, nologin) in groups videt, video, gpio, spi" "$USER_CHECK"
check "/var/log/videt and /var/lib/videt owned by videt:videt" "$DIRS_CHECK"
check "videt config check /etc/videt/videt.toml (as user videt) succeeds" \
  'setpriv --reuid=videt --regid=videt --init-groups videt config check /etc/videt/videt.toml >/dev/null'
check "purge keeps a session log, and says so" \
  'touch /var/log/videt/videt-1.vlog
   dpkg -P videt >/tmp/purge.out 2>&1
   grep -q "kept /var/log/videt" /tmp/purge.out && [ -f /var/log/videt/videt-1.vlog ] && [ ! -e /var/lib/videt ]'
check "restore systemd-sysusers" 'mv /usr/bin/systemd-sysusers.hidden /usr/bin/systemd-sysusers'
phase_done "install-checks(fallback)" "$t"

echo "systemd-analyze: $(tr '\n' ' ' <"$WORK/systemd-analyze.log")"
echo "man (NAME lines): $(paste -sd '|' "$WORK/man.log" | sed 's/|/ | /g')"
echo "times: ${TIMES[*]}; total $(($(now) - T0))s"
if [ "$FAILS" -gt 0 ]; then
  echo "deb-install-test: FAIL ($FAILS failed)"
  exit 1
fi
echo "deb-install-test: PASS"
