#!/bin/bash
# Inside the guest (a chroot into the host's root, under the booted PREEMPT_RT kernel): load the
# device drivers the suite needs, then run scripts/kil/suite.sh and leave its exit code in
# $KIL_OUT/exit-code. `--setup-only` stops after the drivers (for `kernel-in-the-loop.sh --shell`).
#
# Environment (from the initramfs): KIL_REPO, KIL_OUT, KIL_MODROOT (the unpacked kernel package,
# with lib/modules/$(uname -r) and the gpio-sim module), KIL_ACCEL.
set -uo pipefail
info=$KIL_OUT/guest-info.txt
: >"$info"
fail() {
  echo "guest set-up failed: $*" | tee -a "$info"
  echo 1 >"$KIL_OUT/exit-code"
  exit 1
}
mp() { modprobe -d "$KIL_MODROOT" "$@" || fail "modprobe $*"; }

# SocketCAN: a virtual CAN interface (iproute2's ip: busybox's cannot make one).
mp can-raw
mp vcan
# The CANopen peer's heartbeats are python-can periodic sends: SocketCAN's broadcast manager.
mp can-bcm
ip link add dev vcan0 type vcan && ip link set up vcan0 || fail "vcan0"

# GPIO: gpio-sim chips are made through configfs by the tests themselves (gpiosim crate).
mp configfs
mountpoint -q /sys/kernel/config || mount -t configfs none /sys/kernel/config
mp gpio-sim-ko

# V4L2: two vivid instances with one video capture node each, as a stereo pair.
mp vivid n_devs=2 node_types=0x1,0x1
cameras=()
for dev in /sys/class/video4linux/video*; do
  case $(cat "$dev/name") in
    *vid-cap*) cameras+=("/dev/$(basename "$dev")") ;;
  esac
done
[ ${#cameras[@]} -ge 2 ] || fail "vivid gave ${#cameras[@]} capture devices"
export KIL_CAMERAS="${cameras[0]},${cameras[1]}"

# Under emulation the control thread and the rig's drives take nearly all of their CPU: the
# kernel's real-time throttling (95 % of each second) then stopped both for 50 ms at a time, the
# rig's wires ran on under the held torque, and the wire-speed limit tripped (3.6 m/s) before
# the test began. 99 %: at most 10 ms (the systemd guest does the same, checks.sh).
echo 990000 >/proc/sys/kernel/sched_rt_runtime_us || fail "kernel.sched_rt_runtime_us"

{
  echo "kernel: $(uname -r) ($(uname -v))"
  echo "PREEMPT_RT: /sys/kernel/realtime = $(cat /sys/kernel/realtime 2>/dev/null || echo absent)"
  echo "accelerator: $KIL_ACCEL; CPUs: $(nproc); memory: $(awk '/MemTotal/ {print $2 / 1024 " MiB"}' /proc/meminfo)"
  echo "real-time share: $(cat /proc/sys/kernel/sched_rt_runtime_us) µs of each $(cat /proc/sys/kernel/sched_rt_period_us) µs"
  echo "devices: vcan0; gpio-sim (configfs); cameras $KIL_CAMERAS"
} >>"$info"

[ "${1:-}" = --setup-only ] && exit 0

bash "$KIL_REPO/scripts/kil/suite.sh"
rc=$?
dmesg >"$KIL_OUT/dmesg.txt" 2>&1
echo "$rc" >"$KIL_OUT/exit-code"
exit "$rc"
