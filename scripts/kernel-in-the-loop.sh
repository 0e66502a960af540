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

# The kernel: a pinned version first (reproducible), then whatever the archive offers now (the
# archive drops old versions). Each entry is "ABI VERSION"; all five packages come from one.
PINNED_KERNELS=("6.1.0-56 6.1.192-2")

log() { printf '== kil: %s\n' "$*" >&2; }
now() { date +%s.%N; }
since() { echo "$(now) - $1" | bc | xargs printf '%.1f'; }

skip() {
  echo "kernel-in-the-loop: SKIPPED: $*"
  if [ "${VIDET_REQUIRE_KERNEL:-0}" = 1 ]; then
    echo "kernel-in-the-loop: VIDET_REQUIRE_KERNEL=1 makes this a failure" >&2
    exit 1
  fi
  exit 0
}

# --- host tools -------------------------------------------------------------------------------
install_host_tools() {
  # The guest runs the host's own userland: these are what the suite uses in there too.
  local need=() pkg
  for pkg in qemu-system-x86 busybox-static iproute2 can-utils v4l-utils rt-tests kmod bc \
    xz-utils cpio make gcc libelf-dev python3 libclang-dev; do
    dpkg -s "$pkg" >/dev/null 2>&1 || need+=("$pkg")
  done
  if [ ${#need[@]} -gt 0 ]; then
    log "installing ${need[*]}"
    apt-get update -qq || true
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need[@]}" >/dev/null ||
      skip "cannot install ${need[*]}"
  fi
  # The independent CANopen peer (python-canopen) the drives of videtd-canopen-peer run on.
  PEER_PYTHON=$(python3 -c 'import sys; print(sys.executable)')
  if ! "$PEER_PYTHON" -c 'import canopen, can' 2>/dev/null; then
    log "installing the CANopen peer's packages (scripts/canopen-peer/requirements.txt)"
    "$PEER_PYTHON" -m pip install -q -r "$REPO/scripts/canopen-peer/requirements.txt" ||
      skip "cannot install python-canopen"
  fi
}

# --- the kernel, its modules and gpio-sim -----------------------------------------------------
# Sets KVER (e.g. 6.1.0-56-rt-amd64) and KROOT (the unpacked packages).
fetch_kernel() {
  local candidates=("${PINNED_KERNELS[@]}") meta abi version
  version=$(apt-cache policy linux-image-rt-amd64 2>/dev/null | awk '/Candidate:/ {print $2}')
  meta=$(apt-cache depends "linux-image-rt-amd64=$version" 2>/dev/null |
    sed -n 's/.*Depends: linux-image-\(6\.1\.0-[0-9]*\)-rt-amd64.*/\1/p' | head -1)
  [ -n "$meta" ] && candidates+=("$meta $version")
  for c in "${candidates[@]}"; do
    read -r abi version <<<"$c"
    KVER=$abi-rt-amd64
    KROOT=$KIL/kernel-$KVER
    if [ -f "$KROOT/.unpacked" ]; then
      return 0
    fi
    log "downloading kernel $KVER ($version)"
    local debs=$KIL/debs
    rm -rf "$debs" && mkdir -p "$debs"
    local kbuild=linux-kbuild-6.1=$version
    # Kbuild's tools are the same across 6.1 stable updates: take the archive's if the pinned
    # one is gone.
    apt-cache madison linux-kbuild-6.1 | grep -q " $version " || kbuild=linux-kbuild-6.1
    if (cd "$debs" && apt-get download -qq "linux-image-$KVER=$version" \
      "linux-headers-$KVER=$version" "linux-headers-$abi-common-rt=$version" \
      "$kbuild" "linux-source-6.1=$version" 2>/dev/null); then
      rm -rf "$KROOT" && mkdir -p "$KROOT"
      local d
      for d in "$debs"/linux-image-*.deb "$debs"/linux-headers-*.deb "$debs"/linux-kbuild-*.deb; do
        dpkg-deb -x "$d" "$KROOT"
      done
      # Only three files of the source are needed: gpio-sim, gpiolib.h and irq_sim.
      mkdir -p "$KROOT/gpio-sim"
      dpkg-deb --fsys-tarfile "$debs"/linux-source-6.1_*.deb |
        tar -xO ./usr/src/linux-source-6.1.tar.xz |
        tar -xJ -C "$KROOT/gpio-sim" --strip-components=3 \
          linux-source-6.1/drivers/gpio/gpio-sim.c linux-source-6.1/drivers/gpio/gpiolib.h \
          linux-source-6.1/kernel/irq/irq_sim.c
      rm -rf "$debs"
      touch "$KROOT/.unpacked"
      return 0
    fi
    log "kernel $KVER ($version) is not (all) in the archive; trying the next one"
  done
  return 1
}

build_gpio_sim() {
  local mod=$KROOT/gpio-sim headers=$KROOT/usr/src/linux-headers-$KVER
  local ko=$KROOT/lib/modules/$KVER/extra/gpio-sim-ko.ko
  [ -f "$ko" ] && return 0
  log "building gpio-sim + irq_sim as one out-of-tree module"
  # irq_to_desc is not exported to modules in 6.1; the sim chip's handler is
  # handle_simple_irq, which generic_handle_irq calls for it.
  sed -i 's/handle_simple_irq(irq_to_desc(irqnum));/generic_handle_irq(irqnum);/' "$mod/irq_sim.c"
  grep -q 'generic_handle_irq(irqnum)' "$mod/irq_sim.c"
  printf 'obj-m := gpio-sim-ko.o\ngpio-sim-ko-y := gpio-sim.o irq_sim.o\n' >"$mod/Kbuild"
  # The headers' Makefile includes the common headers by their installed path.
  echo "include $KROOT/usr/src/linux-headers-${KVER%-rt-amd64}-common-rt/Makefile" >"$headers/Makefile"
  make -s -C "$headers" M="$mod" modules >"$mod/build.log" 2>&1 || {
    cat "$mod/build.log" >&2
    return 1
  }
  mkdir -p "$(dirname "$ko")"
  cp "$mod/gpio-sim-ko.ko" "$ko"
  depmod -b "$KROOT" "$KVER"
}

# --- the initramfs ----------------------------------------------------------------------------
build_initramfs() {
  INITRD=$KIL/initramfs-$KVER.cpio.gz
  local stamp
  stamp=$(cat "$REPO/scripts/kil/init" "$0" | sha1sum | cut -c1-12)
  [ -f "$INITRD" ] && [ "$(cat "$INITRD.stamp" 2>/dev/null)" = "$stamp" ] && return 0
  log "building the initramfs"
  local ir=$KIL/initramfs m
  rm -rf "$ir" && mkdir -p "$ir"/{bin,dev,proc,sys,host,modules}
  cp /bin/busybox "$ir/bin/busybox"
  # The 9p-over-virtio stack, in dependency order (numbered: the init loads them sorted).
  local n=10 ko
  for ko in $(for m in virtio_pci 9pnet_virtio 9p; do
    modprobe -d "$KROOT" -S "$KVER" --show-depends "$m" | awk '$1 == "insmod" {print $2}'
  done | awk '!seen[$0]++'); do
    cp "$ko" "$ir/modules/$n-$(basename "$ko")"
    n=$((n + 1))
  done
  cp "$REPO/scripts/kil/init" "$ir/init"
  chmod +x "$ir/init"
  (cd "$ir" && find . | cpio -o -H newc --quiet | gzip -1) >"$INITRD"
  echo "$stamp" >"$INITRD.stamp"
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
  cargo build --release --features v4l --bin videtd --bin videt 2>>"$KIL/build.log" || {
    tail -30 "$KIL/build.log" >&2
    return 1
  }
  local guest drivers sim
  guest=$(test_executable -p videt --features v4l --test kernel_guest)
  peer=$(test_executable -p videt --features v4l --test kernel_guest_peer)
  drivers=$(test_executable -p videt-drivers --features v4l --lib)
  sim=$(test_executable -p videt-sim --lib)
  # A stereo calibration of 640x480 cameras for the vivid frames (the shared chessboard rig).
  "$REPO/target/release/videt" calibrate-stereo --images "$REPO/../shared/data/calib/chessboard" \
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
BIN_DIR=$REPO/target/release
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
  if [ -w /dev/kvm ]; then
    log "probing KVM (a guest that does not reach its init in 30 s means no)"
    if qemu kvm probe 30 && grep -q KIL-PROBE-OK "$OUT/console-probe.log"; then
      ACCEL=kvm
    fi
  fi
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
