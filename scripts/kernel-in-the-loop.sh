#!/usr/bin/env bash
# Kernel in the loop: the device path of videtd on a real PREEMPT_RT Linux kernel.
#
# Boots Debian bookworm's PREEMPT_RT kernel under QEMU with the host's own root filesystem
# shared read-only over 9p (no root filesystem to build: the guest chroots into it and runs the
# workspace's binaries with the host's tools), loads vcan, an out-of-tree gpio-sim (Debian
# builds neither gpio-sim nor the irq_sim it needs) and vivid, runs scripts/kil/suite.sh inside,
# prints its summary and exits with its result.
#
#   scripts/kernel-in-the-loop.sh            build, boot, run the suite
#   scripts/kernel-in-the-loop.sh --shell    boot into a shell in the guest instead (debugging)
#   scripts/kernel-in-the-loop.sh --no-build reuse the binaries built last time
#   scripts/kernel-in-the-loop.sh --filter S run only the device-mode tests whose name has S
#   scripts/kernel-in-the-loop.sh --peer-run also run videtd for 10 s against the python-canopen
#                                            drives under TCG (too slow there to be reliable)
#   scripts/kernel-in-the-loop.sh --run FILE run the bash script FILE in the guest instead of the
#                                            suite (after the drivers are loaded; debugging)
#
# Everything it downloads or builds is cached under target/kil/. Where the guest cannot be
# booted at all (no QEMU, no kernel package) it prints SKIPPED and exits 0, unless
# VIDET_REQUIRE_KERNEL=1 (CI), when that is a failure. KVM is used when a probe boot shows that
# it works; otherwise TCG (software emulation), whose timings mean nothing.
set -euo pipefail
cd "$(dirname "$0")/.."
REPO=$PWD
KIL=$REPO/target/kil
GUEST_NAME=kernel-in-the-loop
OUT=$KIL/out
MODE=suite
BUILD=1
FILTER=
RUN=
PEER_RUN=0
while [ $# -gt 0 ]; do
  case $1 in
    --shell) MODE=shell ;;
    --no-build) BUILD=0 ;;
    --filter) FILTER=${2:?--filter needs a test name}; shift ;;
    --peer-run) PEER_RUN=1 ;;
    --run) RUN=$(realpath "${2:?--run needs a script}"); shift ;;
    *) echo "usage: $0 [--shell] [--no-build] [--filter TEST] [--run SCRIPT] [--peer-run]" >&2; exit 2 ;;
  esac
  shift
done

# shellcheck source=scripts/kil/host.sh
source "$REPO/scripts/kil/host.sh"

# --- the initramfs ----------------------------------------------------------------------------
# The 9p-over-virtio stack: the guest's root is the host's.
build_initramfs() {
  INITRD=$KIL/initramfs-$KVER.cpio.gz
  make_initramfs "$INITRD" "$REPO/scripts/kil/init" virtio_pci 9pnet_virtio 9p
}

# --- the binaries the guest runs --------------------------------------------------------------
# The path of the test executable cargo built for `cargo test --no-run ARGS`.
test_executable() {
  cargo test --no-run --message-format=json "$@" 2>>"$KIL/build.log" |
    python3 -c 'import json,sys
exe=[m["executable"] for m in map(json.loads, sys.stdin) if m.get("reason")=="compiler-artifact" and m.get("executable") and m["profile"]["test"]]
print(exe[-1])'
}

build_workspace() {
  log "building the binaries the guest runs"
  : >"$KIL/build.log"
  build_guest_binaries
  local guest drivers sim
  guest=$(test_executable -p videt --features v4l --test kernel_guest)
  peer=$(test_executable -p videt --features v4l --test kernel_guest_peer)
  drivers=$(test_executable -p videt-drivers --features v4l --lib)
  sim=$(test_executable -p videt-sim --lib)
  # A stereo calibration of 640x480 cameras for the vivid frames (the shared chessboard rig).
  "$GUEST_BIN_DIR/videt" calibrate-stereo --images "$REPO/../shared/data/calib/chessboard" \
    --board 9x6 --square 0.025 --out "$KIL/stereo.json" >>"$KIL/build.log" 2>&1 || {
    tail -30 "$KIL/build.log" >&2
    return 1
  }
  cat >"$KIL/bins.env" <<EOF
GUEST_TESTS=$guest
PEER_TESTS=$peer
PEER_PYTHON=$PEER_PYTHON
DRIVERS_TESTS=$drivers
SIM_TESTS=$sim
BIN_DIR=$GUEST_BIN_DIR
STEREO_CALIBRATION=$KIL/stereo.json
EOF
}

# --- booting ----------------------------------------------------------------------------------
# qemu ACCEL MODE TIMEOUT: boot the guest; its console goes to $OUT/console-MODE.log.
# tsc=reliable: the emulated vCPUs' TSCs fail the kernel's synchronisation check, and it would
# then clock itself on the HPET, which makes every clock_gettime() a system call and an emulated
# device read; the TSC that QEMU emulates follows the host's one clock, so it is monotonic.
qemu() {
  local accel=$1 mode=$2 limit=$3 cpu=max
  [ "$accel" = kvm ] && cpu=host
  local console=$OUT/console-$mode.log
  local args=(-accel "$accel" -cpu "$cpu" -smp 2 -m 4096 -nographic -no-reboot
    -kernel "$KROOT/boot/vmlinuz-$KVER" -initrd "$INITRD"
    -append "console=ttyS0 quiet panic=-1 tsc=reliable kil.mode=$mode kil.repo=$REPO kil.out=$OUT kil.modroot=$KROOT kil.accel=$accel"
    -virtfs "local,path=/,mount_tag=hostroot,security_model=none,readonly=on,multidevs=remap"
    -virtfs "local,path=$OUT,mount_tag=kilout,security_model=none,multidevs=remap")
  if [ "$mode" = shell ]; then
    qemu-system-x86_64 "${args[@]}"
  else
    timeout --kill-after=10 "$limit" qemu-system-x86_64 "${args[@]}" </dev/null >"$console" 2>&1
  fi
}

choose_accelerator() {
  ACCEL=tcg
  probe_kvm "$INITRD" && ACCEL=kvm
  log "accelerator: $ACCEL"
}

main() {
  local t0 t_build t_boot
  t0=$(now)
  command -v apt-get >/dev/null || skip "no apt-get to install QEMU and the kernel with"
  install_host_tools
  command -v qemu-system-x86_64 >/dev/null || skip "no qemu-system-x86_64"
  mkdir -p "$KIL"
  fetch_kernel || skip "no consistent set of PREEMPT_RT kernel packages in the archive"
  build_gpio_sim || skip "gpio-sim did not build against linux-headers-$KVER"
  build_initramfs
  log "kernel $KVER ready in $(since "$t0") s"
  rm -rf "$OUT" && mkdir -p "$OUT"
  t_build=$(now)
  if [ "$MODE" = suite ] && [ "$BUILD" = 1 ]; then
    build_workspace
  fi
  [ -f "$KIL/bins.env" ] || { echo "no binaries: run without --no-build" >&2; exit 1; }
  check_v4l_build "$(sed -n 's/^BIN_DIR=//p' "$KIL/bins.env")/videtd" || exit 1
  cp "$KIL/bins.env" "$OUT/bins.env"
  [ -n "$FILTER" ] && echo "$FILTER" >"$OUT/filter"
  [ -n "$RUN" ] && echo "$RUN" >"$OUT/run"
  [ "$PEER_RUN" = 1 ] && touch "$OUT/peer-run"
  log "binaries ready in $(since "$t_build") s"
  choose_accelerator
  t_boot=$(now)
  if [ "$MODE" = shell ]; then
    qemu "$ACCEL" shell 0
    exit 0
  fi
  log "booting the guest ($ACCEL) and running the suite"
  qemu "$ACCEL" suite 3000 || true
  local suite_s
  suite_s=$(since "$t_boot")
  echo
  echo "kernel-in-the-loop: $KVER (PREEMPT_RT) under QEMU/$ACCEL"
  if [ -f "$OUT/guest-info.txt" ]; then
    sed 's/^/  /' "$OUT/guest-info.txt"
  fi
  if [ -f "$OUT/summary.txt" ]; then
    cat "$OUT/summary.txt"
  fi
  [ -f "$OUT/timing.txt" ] && sed 's/^/  /' "$OUT/timing.txt"
  echo "times: set-up $(echo "$t_build - $t0" | bc | xargs printf '%.0f') s, build $(echo "$t_boot - $t_build" | bc | xargs printf '%.0f') s, boot + suite $suite_s s (logs in $OUT)"
  if [ ! -f "$OUT/exit-code" ]; then
    echo "kernel-in-the-loop: FAILED: the guest did not finish (console: $OUT/console-suite.log)"
    tail -40 "$OUT/console-suite.log" | sed 's/^/  | /'
    exit 1
  fi
  local rc
  rc=$(cat "$OUT/exit-code")
  if [ "$rc" = 0 ]; then
    echo "kernel-in-the-loop: PASSED"
  else
    echo "kernel-in-the-loop: FAILED (exit $rc)"
  fi
  exit "$rc"
}

main
