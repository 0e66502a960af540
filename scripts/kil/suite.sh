#!/bin/bash
# The kernel-in-the-loop suite proper. Runs inside the guest (a chroot into the host's root, so
# the host's tools and the workspace's binaries are at hand), after guest-setup.sh has loaded
# vcan, gpio-sim and vivid. Writes one line per step to $KIL_OUT/summary.txt and each step's
# output to $KIL_OUT/<step>.log; exits non-zero when a step failed.
#
# Environment (from guest-setup.sh): KIL_REPO (the workspace), KIL_OUT (writable, seen by the
# host), KIL_ACCEL (kvm or tcg), KIL_CAMERAS ("LEFT,RIGHT" vivid capture nodes).
set -uo pipefail
cd "$KIL_REPO"
# shellcheck source=/dev/null
source "$KIL_OUT/bins.env"   # DRIVERS_TESTS, SIM_TESTS, GUEST_TESTS, PEER_TESTS, PEER_PYTHON, BIN_DIR, STEREO_CALIBRATION

summary="$KIL_OUT/summary.txt"
failed=0
export VIDET_REQUIRE_DATA=1 VIDET_DATA_DIR="$KIL_REPO/../shared/data"
export VIDET_KIL_CAMERAS="$KIL_CAMERAS" VIDET_BIN_DIR="$BIN_DIR"
export VIDET_KIL_STEREO_CALIBRATION="$STEREO_CALIBRATION"
export RUST_BACKTRACE=1 VIDET_KIL_KEEP="$KIL_OUT/tests"
export VIDET_PEER_PYTHON="$PEER_PYTHON" VIDET_KIL_ACCEL="$KIL_ACCEL"

# step NAME TIMEOUT_S COMMAND...: run, time, record PASS/FAIL and the test counts it printed.
step() {
  local name=$1 limit=$2
  shift 2
  local start end rc counts
  start=$(date +%s.%N)
  timeout --kill-after=10 "$limit" "$@" >"$KIL_OUT/$name.log" 2>&1
  rc=$?
  end=$(date +%s.%N)
  counts=$(grep -E '^test result:' "$KIL_OUT/$name.log" | tail -1 | sed -E 's/^test result: [A-Z]+\. //; s/; finished.*//')
  if [ $rc -eq 0 ]; then
    printf 'PASS  %-28s %6.1f s  %s\n' "$name" "$(echo "$end - $start" | bc)" "$counts" >>"$summary"
  else
    failed=1
    [ $rc -eq 124 ] && counts="timed out after ${limit} s; $counts"
    printf 'FAIL  %-28s %6.1f s  exit %d  %s\n' "$name" "$(echo "$end - $start" | bc)" "$rc" "$counts" >>"$summary"
    tail -40 "$KIL_OUT/$name.log" | sed 's/^/      | /' >>"$summary"
  fi
}

# `kernel-in-the-loop.sh --run FILE` runs FILE instead of the suite.
if [ -f "$KIL_OUT/run" ]; then
  step run 2400 bash "$(cat "$KIL_OUT/run")"
  exit $failed
fi

# `kernel-in-the-loop.sh --filter NAME` runs only the device-mode tests named so.
if [ -f "$KIL_OUT/filter" ]; then
  step videtd-device-mode 2400 "$GUEST_TESTS" --ignored --test-threads=1 "$(cat "$KIL_OUT/filter")"
  step videtd-canopen-peer 2400 "$PEER_TESTS" --ignored --test-threads=1 "$(cat "$KIL_OUT/filter")"
  exit $failed
fi

# The tests that are ignored elsewhere for lack of a device, on the real kernel interfaces.
step drivers-socketcan-v4l2 600 "$DRIVERS_TESTS" --ignored --test-threads=1
step sim-socketcan 300 "$SIM_TESTS" --ignored --test-threads=1 socketcan
# videtd in device mode against the twin served on vcan, with gpio-sim and vivid.
step videtd-device-mode 2400 "$GUEST_TESTS" --ignored --test-threads=1
# videtd in device mode against drives served by an independent CANopen stack (python-canopen)
# with each shipped dictionary. The refusals always; the 10 s run only where the CPU is not
# emulated or when asked (`kernel-in-the-loop.sh --peer-run`): under TCG the Python stack
# answers a few tens of SYNCs a second and now and then none for 100 periods, which the
# service rightly takes for a dead drive (docs/kernel-in-the-loop.md).
if [ "$KIL_ACCEL" = kvm ] || [ -f "$KIL_OUT/peer-run" ]; then
  step videtd-canopen-peer 2400 "$PEER_TESTS" --ignored --test-threads=1 --nocapture
else
  step videtd-canopen-peer 2400 "$PEER_TESTS" --ignored --test-threads=1 --nocapture \
    --skip videtd_runs_drives_served_by_an_independent_canopen_stack
fi

# Timing: meaningful only under KVM. cyclictest first, then the control loop, back to back.
{
  echo "accelerator: $KIL_ACCEL"
  echo "kernel: $(uname -r) $(uname -v)"
  echo "realtime: $(cat /sys/kernel/realtime 2>/dev/null || echo 0)"
} >"$KIL_OUT/timing.txt"
step cyclictest 120 cyclictest -m -p 80 -i 1000 -l 10000 -q --policy=fifo
step bench-rt 120 "$BIN_DIR/videt" bench-rt --rate 1000 --seconds 10 --priority 80 --cpu 1
{
  echo "cyclictest (-m -p 80 -i 1000, 10 000 wake-ups):"
  grep -E 'Min|Avg|Max' "$KIL_OUT/cyclictest.log" | sed 's/^/  /'
  echo "videt bench-rt --rate 1000 --seconds 10:"
  sed 's/^/  /' "$KIL_OUT/bench-rt.log"
  if [ "$KIL_ACCEL" != kvm ]; then
    echo "NOTE: the guest ran under TCG (software emulation): these timings are meaningless."
  fi
} >>"$KIL_OUT/timing.txt"

exit $failed
