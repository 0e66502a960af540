#!/usr/bin/env bash
# What the finger feels on every scene and device (docs/felt-force.md): records a videtd session
# of each on the HAL twin and the CAN twin with the default configuration, then prints the felt
# measure of each log as recorded (`videt log`) and replayed with every algorithm
# (`videt replay --algorithm A`).
#
#   scripts/felt-force-sessions.sh [SECONDS] [OUT_DIR]
#
# SECONDS per session (default 30). VIDETD and VIDET name the binaries (default: the release
# builds of this tree, built first). FELT_SIMS, FELT_DEVICES and FELT_SCENES pick the twins
# (default "hal can"), the devices ("wireman3 planar2 polar1") and the scenes ("wall box stereo
# camera"): runs of different picks may go side by side into different OUT_DIRs. The camera scene is the teddy_rig scene of
# docs/frame-to-force.md (needs the shared stereo pairs). Exit status 1 when any session or
# replay renders beyond the felt bound.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-30}
out=${2:-target/felt-force}
if [[ -z "${VIDETD:-}" || -z "${VIDET:-}" ]]; then
  cargo build --release --bin videtd --bin videt --example teddy_rig_camera_scene >&2
  VIDETD=${VIDETD:-target/release/videtd}
  VIDET=${VIDET:-target/release/videt}
fi
mkdir -p "$out"
read -r -a sims <<<"${FELT_SIMS:-hal can}"
read -r -a devices <<<"${FELT_DEVICES:-wireman3 planar2 polar1}"
read -r -a wanted <<<"${FELT_SCENES:-wall box stereo camera}"
scenes=()
for scene in "${wanted[@]}"; do
  if [[ $scene == camera ]]; then
    if [[ ! -f "$out/teddyrig/stereo.json" && -x target/release/examples/teddy_rig_camera_scene ]]; then
      target/release/examples/teddy_rig_camera_scene "$out/teddyrig" >&2 || true
    fi
    if [[ ! -f "$out/teddyrig/stereo.json" ]]; then
      echo "camera scene skipped: no teddy_rig scene (needs the shared stereo pairs)"
      continue
    fi
  fi
  scenes+=("$scene")
done

failed=0
session() { # sim device scene
  local sim=$1 device=$2 scene=$3 name="$1-$2-$3" config="$out/$1-$2-$3.toml"
  printf '[rig]\ndevice = "%s"\n' "$device" >"$config"
  local extra=()
  local scene_arg=$scene
  if [[ $scene == camera ]]; then
    printf '[vision]\nmax_disparity_px = 96.0\nframe_rate_hz = 15\n' >>"$config"
    scene_arg="camera:$out/teddyrig"
    extra=(--stereo-calibration "$out/teddyrig/stereo.json")
  fi
  rm -rf "${out:?}/$name"
  if ! "$VIDETD" --sim "$sim" --config "$config" --scene "$scene_arg" "${extra[@]}" \
      --duration "$seconds" --no-socket --telemetry-dir "$out/$name" >"$out/$name.stderr" 2>&1; then
    echo "$name: videtd refused or failed: $(grep -m1 -i 'error' "$out/$name.stderr" || tail -1 "$out/$name.stderr")"
    return
  fi
  local log
  log=$(ls "$out/$name"/*.vlog)
  local line
  line=$("$VIDET" log "$log" | sed -n 's/^  felt force: //p')
  echo "$name recorded: $line"
  [[ $line == 0\ of* ]] || failed=1
  for a in P1 P2 F1 F2 QP; do
    line=$("$VIDET" replay "$log" --algorithm "$a" --csv /dev/null 2>/dev/null | sed -n 's/^  felt force: //p')
    echo "$name replayed $a: $line"
    [[ $line == 0\ of* ]] || failed=1
  done
}

for sim in "${sims[@]}"; do
  for device in "${devices[@]}"; do
    for scene in "${scenes[@]}"; do
      session "$sim" "$device" "$scene"
    done
  done
done
exit $failed
