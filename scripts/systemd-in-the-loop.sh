#!/usr/bin/env bash
# The service as installed: the Debian package on a booted Debian bookworm with systemd as PID 1,
# on the PREEMPT_RT kernel of the kernel-in-the-loop suite (QEMU).
#
# The root is the bookworm image of scripts/deb-install-test.sh, as an ext4 disk under a
# copy-on-write overlay (each run starts from the pristine image). The guest's drivers are the
# device's, emulated: vcan as can0 (systemd-networkd), gpio-sim and two vivid cameras;
# `videt sim-rig` serves the twin's drives on can0 as a unit of its own. Two boots:
#   1. install the package, configure the device, start and enable videtd (Type=notify checks);
#   2. the enabled service comes up with the system (boot to ready), then the watchdog, a crash,
#      a stop's ramp, journald, SCHED_FIFO and mlock, the socket's group, the write confinement,
#      an upgrade and the removal (scripts/kil/systemd/checks.sh).
#
#   scripts/systemd-in-the-loop.sh             build the package (target/guest), boot, check
#   scripts/systemd-in-the-loop.sh --no-build  use the newest target/guest/debian/videt_*.deb
#
# Cached under target/kil (kernel, image); results in target/kil/systemd/out. Prints PASS/FAIL
# lines and exits 1 on any FAIL. Where the guest cannot boot at all it prints SKIPPED and exits
# 0, unless VIDET_REQUIRE_KERNEL=1 (CI).
set -euo pipefail
cd "$(dirname "$0")/.."
REPO=$PWD
KIL=$REPO/target/kil
SD=$KIL/systemd
OUT=$SD/out
GUEST_NAME=systemd-in-the-loop
BUILD=1
while [ $# -gt 0 ]; do
  case $1 in
    --no-build) BUILD=0 ;;
    *) echo "usage: $0 [--no-build]" >&2; exit 2 ;;
  esac
  shift
done
# shellcheck source=scripts/kil/host.sh
source "$REPO/scripts/kil/host.sh"
mkdir -p "$SD"
: >"$KIL/build.log"

# --- the package ------------------------------------------------------------------------------
package() {
  if [ "$BUILD" = 1 ]; then
    log "building the package (release, with V4L2 capture, in $GUEST_TARGET)"
    DEB=$(CARGO_TARGET_DIR=$GUEST_TARGET bash "$REPO/scripts/build-deb.sh" 2>>"$KIL/build.log" | tail -n 1) ||
      { tail -30 "$KIL/build.log" >&2; return 1; }
  else
    # shellcheck disable=SC2012 # the newest by time; the names are cargo-deb's
    DEB=$(ls -t "$GUEST_TARGET"/debian/videt_*.deb 2>/dev/null | head -n 1) || true
  fi
  [ -n "$DEB" ] && [ -f "$DEB" ] || { echo "no package: run without --no-build" >&2; return 1; }
  # What the guest installs is checked, not what the target directory holds now.
  rm -rf "$SD/pkg" && mkdir -p "$SD/pkg"
  dpkg-deb -R "$DEB" "$SD/pkg"
  check_v4l_build "$SD/pkg/usr/bin/videtd"
}

# The upgrade: the same package rebuilt as a newer version (what `apt upgrade` brings).
rebuilt_package() {
  local version
  version=$(sed -n 's/^Version: //p' "$SD/pkg/DEBIAN/control")+rebuilt1
  sed -i "s/^Version: .*/Version: $version/" "$SD/pkg/DEBIAN/control"
  dpkg-deb --root-owner-group -Zxz -z1 -b "$SD/pkg" "$OUT/videt-rebuilt.deb" >/dev/null
  echo "$version" >"$OUT/rebuilt-version"
}

# --- the disk: the bookworm image, under a copy-on-write overlay -------------------------------
disk() {
  local tar=$REPO/target/deb-test/bookworm-minbase-systemd-udev-v4l.tar
  [ -f "$tar" ] || bash "$REPO/scripts/deb-install-test.sh" --root-only >&2
  local base=$SD/bookworm.img stamp
  stamp=$(stat -c '%s %Y' "$tar")
  if [ ! -f "$base" ] || [ "$(cat "$base.stamp" 2>/dev/null)" != "$stamp" ]; then
    log "making the ext4 image of $(basename "$tar")"
    local dir=$SD/rootdir
    rm -rf "$dir" && mkdir -p "$dir"
    tar -C "$dir" -xf "$tar"
    rm -f "$base"
    mke2fs -q -t ext4 -L videt-root -d "$dir" "$base" 3G
    rm -rf "$dir"
    echo "$stamp" >"$base.stamp"
  fi
  OVERLAY=$SD/overlay.qcow2
  rm -f "$OVERLAY"
  qemu-img create -q -f qcow2 -b "$base" -F raw "$OVERLAY"
}

# --- the initramfs: the disk's and 9p's modules, the init ------------------------------------
initramfs() {
  INITRD=$SD/initramfs-$KVER.cpio.gz
  make_initramfs "$INITRD" "$REPO/scripts/kil/systemd-init" virtio_pci virtio_blk ext4 9pnet_virtio 9p
}

# --- what the guest is given ------------------------------------------------------------------
share() {
  rm -rf "$OUT" && mkdir -p "$OUT/harness"
  cp "$DEB" "$OUT/videt.deb"
  rebuilt_package
  cp "$REPO"/scripts/kil/systemd/*.service "$REPO"/scripts/kil/systemd/*.sh \
    "$REPO"/scripts/kil/systemd/*.netdev "$REPO"/scripts/kil/systemd/*.network \
    "$REPO"/scripts/kil/systemd/videt-guest.* "$OUT/harness/"
  python3 "$REPO/scripts/kil/systemd/guest-config.py" "$REPO/config/videt.example.toml" \
    "$OUT/videt.toml" "$OUT/stereo.json"
}

# boot PHASE: boot the guest once; its console goes to $OUT/console-PHASE.log.
# Two CPUs: the guest's service gets both by a drop-in (scripts/kil/systemd/checks.sh,
# configure_device); four hang the emulated kernel's boot on this host's two cores.
boot() {
  local phase=$1 cpu=max
  [ "$ACCEL" = kvm ] && cpu=host
  timeout --kill-after=10 1800 qemu-system-x86_64 -accel "$ACCEL" -cpu "$cpu" -smp 2 -m 2048 \
    -nographic -no-reboot -kernel "$KROOT/boot/vmlinuz-$KVER" -initrd "$INITRD" \
    -append "console=ttyS0 panic=-1 tsc=reliable kil.mode=systemd kil.kver=$KVER kil.phase=$phase systemd.show_status=auto" \
    -drive "file=$OVERLAY,if=virtio,format=qcow2,cache=unsafe" \
    -virtfs "local,path=$KROOT/lib/modules,mount_tag=modules,security_model=none,readonly=on,multidevs=remap" \
    -virtfs "local,path=$OUT,mount_tag=kilout,security_model=none,multidevs=remap" \
    </dev/null >"$OUT/console-$phase.log" 2>&1 || true
}

main() {
  local t0 t_boot
  t0=$(now)
  [ "$(id -u)" = 0 ] || skip "needs root (the image, qemu's shares)"
  command -v apt-get >/dev/null || skip "no apt-get to install QEMU and the kernel with"
  install_host_tools
  local need=() tool
  for tool in mke2fs:e2fsprogs qemu-img:qemu-utils; do
    command -v "${tool%%:*}" >/dev/null 2>&1 || need+=("${tool#*:}")
  done
  if [ ${#need[@]} -gt 0 ]; then
    log "installing ${need[*]}"
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need[@]}" >/dev/null ||
      skip "cannot install ${need[*]}"
  fi
  command -v mke2fs >/dev/null || skip "no mke2fs (e2fsprogs)"
  command -v qemu-img >/dev/null || skip "no qemu-img"
  mkdir -p "$KIL"
  fetch_kernel || skip "no consistent set of PREEMPT_RT kernel packages in the archive"
  build_gpio_sim || skip "gpio-sim did not build against linux-headers-$KVER"
  package
  disk
  initramfs
  share
  ACCEL=tcg
  probe_kvm "$INITRD" && ACCEL=kvm
  log "set-up in $(since "$t0") s; accelerator $ACCEL"
  local phase
  for phase in install boot; do
    t_boot=$(now)
    log "boot: $phase"
    boot "$phase"
    echo "$phase $(since "$t_boot")" >>"$OUT/boot-times.txt"
    if [ ! -f "$OUT/done-$phase" ]; then
      echo "FAIL  boot '$phase' did not finish its checks (console: $OUT/console-$phase.log)" >>"$OUT/summary.txt"
      tail -30 "$OUT/console-$phase.log" | sed 's/^/      | /' >>"$OUT/summary.txt"
      break
    fi
  done
  echo
  echo "systemd-in-the-loop: $(basename "$DEB") on $KVER (PREEMPT_RT), systemd, QEMU/$ACCEL"
  cat "$OUT/summary.txt" 2>/dev/null
  echo "boots (boot, checks, power-off): $(tr '\n' ' ' <"$OUT/boot-times.txt") s"
  [ -f "$OUT/boot-to-ready.txt" ] && echo "boot to ready: $(cat "$OUT/boot-to-ready.txt") s from kernel start (QEMU/$ACCEL)"
  echo "systemd-analyze security: $(systemd-analyze security --offline=true "$REPO/packaging/videtd.service" 2>/dev/null | tail -n 1)"
  echo "total $(since "$t0") s; logs in $OUT"
  if grep -q '^FAIL' "$OUT/summary.txt" 2>/dev/null || ! grep -q '^PASS' "$OUT/summary.txt" 2>/dev/null; then
    echo "systemd-in-the-loop: FAILED"
    exit 1
  fi
  echo "systemd-in-the-loop: PASSED"
}

main
