#!/usr/bin/env bash
# What the finger feels on every scene and device (docs/felt-force.md): records a videtd session
# of each on the HAL twin and the CAN twin with the default configuration, then prints the felt
# measure of each log as recorded (`videt log`) and replayed with every algorithm
# (`videt replay --algorithm A`).
#
#   scripts/felt-force-sessions.sh [SECONDS] [OUT_DIR]
#
# SECONDS per session (default 30). VIDETD and VIDET name the binaries (default: the release
# builds of this tree, built first). The camera scene is the teddy_rig scene of
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
scenes=(wall box stereo)
if [[ -x target/release/examples/teddy_rig_camera_scene ]]; then
  if [[ ! -f "$out/teddyrig/stereo.json" ]]; then
    target/release/examples/teddy_rig_camera_scene "$out/teddyrig" >&2 || true
  fi
  [[ -f "$out/teddyrig/stereo.json" ]] && scenes+=(camera)
fi

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

# The stereo and camera scenes run on the HAL twin only (the CAN twin touches the wall), and
# the planar and one-wire devices touch the wall scene alone.
for sim in hal can; do
  for scene in "${scenes[@]}"; do
    [[ $sim == can && ( $scene == stereo || $scene == camera ) ]] && continue
    session "$sim" wireman3 "$scene"
  done
  for device in planar2 polar1; do
    session "$sim" "$device" wall
  done
done
exit $failed
