#!/bin/bash
# The guest's GPIO chip (gpio-sim through configfs: 32 lines, the e-stop on line 17 pulled up,
# i.e. released) and a check that the cameras are vivid's capture nodes.
set -euo pipefail
# configfs: sys-kernel-config.mount is skipped when it runs before the module is loaded, and
# is started again later only by chance of ordering; mount it here if it is not yet.
mountpoint -q /sys/kernel/config || mount -t configfs configfs /sys/kernel/config
[ -d /sys/kernel/config/gpio-sim ] || { echo "no gpio-sim in configfs: is gpio-sim-ko loaded?"; exit 1; }
C=/sys/kernel/config/gpio-sim/videt
if [ ! -d "$C" ]; then
  mkdir "$C" "$C/bank0"
  echo 32 >"$C/bank0/num_lines"
  mkdir "$C/bank0/line17"
  echo estop >"$C/bank0/line17/name"
  echo 1 >"$C/live"
fi
chip=$(cat "$C/bank0/chip_name")
[ "$chip" = gpiochip0 ] || { echo "the simulated chip is $chip, not gpiochip0"; exit 1; }
echo pull-up >"/sys/devices/platform/$(cat "$C/dev_name")/$chip/sim_gpio17/pull"
i=0
until [ -c "/dev/$chip" ]; do
  [ $i -lt 50 ] || { echo "/dev/$chip did not appear in 5 s"; exit 1; }
  sleep 0.1
  i=$((i + 1))
done
for dev in video0 video1; do
  name=$(cat "/sys/class/video4linux/$dev/name")
  case $name in *vid-cap*) ;; *) echo "/dev/$dev is '$name', not a vivid capture node"; exit 1 ;; esac
  # A 640x480 test pattern (the HDMI input with its first timings), as the suite's camera test.
  v4l2-ctl -d "/dev/$dev" -i 3 >/dev/null
  v4l2-ctl -d "/dev/$dev" --set-dv-bt-timings index=0 >/dev/null
  v4l2-ctl -d "/dev/$dev" --set-fmt-video=width=640,height=480,pixelformat=YUYV
done
# The right camera sees the pattern 16 px to the side: a disparity, hence a scene in front.
v4l2-ctl -d /dev/video1 --set-selection target=crop,left=16,top=0,width=624,height=480
udevadm settle
echo "gpio-sim: /dev/$chip ($(stat -c '%U:%G %a' "/dev/$chip")); cameras /dev/video0, /dev/video1"
