# shellcheck shell=bash
# What the two guests share on the host side (sourced by scripts/kernel-in-the-loop.sh and
# scripts/systemd-in-the-loop.sh): the host's tools, Debian's PREEMPT_RT kernel and the
# out-of-tree gpio-sim module, the KVM probe, and the optimized binaries built for the guests.
#
# Expects REPO (the workspace), KIL (target/kil) and GUEST_NAME (for messages) to be set.

# The kernel: a pinned version first (reproducible), then whatever the archive offers now (the
# archive drops old versions). Each entry is "ABI VERSION"; all five packages come from one.
PINNED_KERNELS=("6.1.0-56 6.1.192-2")

log() { printf '== %s: %s\n' "$GUEST_NAME" "$*" >&2; }
now() { date +%s.%N; }
since() { echo "$(now) - $1" | bc | xargs printf '%.1f'; }

skip() {
  echo "$GUEST_NAME: SKIPPED: $*"
  if [ "${VIDET_REQUIRE_KERNEL:-0}" = 1 ]; then
    echo "$GUEST_NAME: VIDET_REQUIRE_KERNEL=1 makes this a failure" >&2
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
# make_initramfs OUT INIT MODULE...: a busybox initramfs at OUT with INIT as /init and the
# kernel modules named, with their dependencies, in /modules (numbered in dependency order: the
# inits load them sorted). Rebuilt only when INIT, this file or the module list change.
make_initramfs() {
  local out=$1 init=$2
  shift 2
  local stamp
  stamp=$( (cat "$init" "$REPO/scripts/kil/host.sh"; echo "$KVER $*") | sha1sum | cut -c1-12)
  [ -f "$out" ] && [ "$(cat "$out.stamp" 2>/dev/null)" = "$stamp" ] && return 0
  log "building the initramfs"
  local ir=$out.d n=10 ko m
  rm -rf "$ir" && mkdir -p "$ir"/{bin,dev,proc,sys,host,modules}
  cp /bin/busybox "$ir/bin/busybox"
  for ko in $(for m in "$@"; do
    modprobe -d "$KROOT" -S "$KVER" --show-depends "$m" | awk '$1 == "insmod" {print $2}'
  done | awk '!seen[$0]++'); do
    cp "$ko" "$ir/modules/$n-$(basename "$ko")"
    n=$((n + 1))
  done
  cp "$init" "$ir/init"
  chmod +x "$ir/init"
  (cd "$ir" && find . | cpio -o -H newc --quiet | gzip -1) >"$out"
  rm -rf "$ir"
  echo "$stamp" >"$out.stamp"
}

# --- the accelerator --------------------------------------------------------------------------
# probe_kvm INITRD: whether a KVM guest of this kernel reaches its init (kil.mode=probe makes
# either init print KIL-PROBE-OK and power off) within 30 s. KVM accepts a VM on these
# machines but its nested guests may hang after decompression.
probe_kvm() {
  [ -w /dev/kvm ] || return 1
  log "probing KVM (a guest that does not reach its init in 30 s means no)"
  timeout --kill-after=10 30 qemu-system-x86_64 -accel kvm -cpu host -smp 1 -m 512 -nographic \
    -no-reboot -kernel "$KROOT/boot/vmlinuz-$KVER" -initrd "$1" \
    -append "console=ttyS0 quiet panic=-1 kil.mode=probe" </dev/null 2>&1 | grep -q KIL-PROBE-OK
}

# --- the binaries the guests run --------------------------------------------------------------
# The guests' optimized binaries, with the cameras' feature, build into a target directory of
# their own: a `cargo build --release` without the feature (the README's first command) then
# never leaves the binary they boot, and each build is checked for the feature before booting.
GUEST_TARGET=$REPO/target/guest
GUEST_BIN_DIR=$GUEST_TARGET/release

# check_v4l_build VIDETD: fails unless VIDETD says it was built with V4L2 capture.
check_v4l_build() {
  local version
  version=$("$1" --version 2>&1) || { echo "$1 --version failed: $version" >&2; return 1; }
  case $version in
    *"with V4L2 capture"*) return 0 ;;
    *) echo "$1 says '$version': the guests need a build with V4L2 capture (--features v4l)" >&2
       return 1 ;;
  esac
}

build_guest_binaries() {
  log "building the guests' videtd and videt (release, --features v4l, in $GUEST_TARGET)"
  CARGO_TARGET_DIR=$GUEST_TARGET cargo build --release --features v4l --bin videtd --bin videt \
    2>>"$KIL/build.log" || { tail -30 "$KIL/build.log" >&2; return 1; }
  check_v4l_build "$GUEST_BIN_DIR/videtd"
}
