#!/usr/bin/env bash
# Fetch stereo pairs with ground truth beyond the shared test data, for held-out accuracy
# figures: Middlebury 2014 "Motorcycle" (quarter resolution, 741x500), as scikit-image ships it
# in its wheel. Written as DIR/motorcycle/{left.png,right.png,disp_left.pgm,scale.txt,
# ATTRIBUTION.txt}: the ground truth in the Middlebury 8-bit convention (disparity x scale,
# 0 = unknown), the scale in scale.txt.
#
#   bash scripts/fetch-extra-stereo.sh [DIR]      # default DIR: target/extra-stereo
#
# Needs pip and python3 (no numpy: the .npz is read with the standard library).
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-target/extra-stereo}"
version=0.26.0
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

if [ -f "$out/motorcycle/disp_left.pgm" ]; then
    echo "already there: $out/motorcycle"
    exit 0
fi
python3 -m pip download --quiet --no-deps --only-binary=:all: \
    --platform manylinux_2_28_x86_64 --python-version 3.11 \
    -d "$work" "scikit-image==$version"
wheel="$(ls "$work"/scikit_image-*.whl)"
mkdir -p "$out/motorcycle.tmp"
python3 - "$wheel" "$out/motorcycle.tmp" <<'EOF'
import ast, io, math, struct, sys, zipfile

wheel, dest = sys.argv[1], sys.argv[2]
scale = 4  # disparities reach 60 px: x4 stays below 255
with zipfile.ZipFile(wheel) as w:
    for side in ("left", "right"):
        with open(f"{dest}/{side}.png", "wb") as f:
            f.write(w.read(f"skimage/data/motorcycle_{side}.png"))
    npz = zipfile.ZipFile(io.BytesIO(w.read("skimage/data/motorcycle_disp.npz")))
    raw = npz.read(npz.namelist()[0])
if raw[:6] != b"\x93NUMPY":
    sys.exit("motorcycle_disp.npz: not a .npy array")
if raw[6] == 1:
    (length,), start = struct.unpack("<H", raw[8:10]), 10
else:
    (length,), start = struct.unpack("<I", raw[8:12]), 12
header = ast.literal_eval(raw[start:start + length].decode("latin1"))
if header["descr"] != "<f4" or header["fortran_order"]:
    sys.exit(f"motorcycle_disp.npz: unexpected array {header}")
height, width = header["shape"]
values = struct.unpack(f"<{width * height}f", raw[start + length:])
pixels = bytearray(
    0 if not math.isfinite(v) or v <= 0 else max(1, min(255, round(v * scale))) for v in values
)
with open(f"{dest}/disp_left.pgm", "wb") as f:
    f.write(b"P5\n%d %d\n255\n" % (width, height))
    f.write(pixels)
with open(f"{dest}/scale.txt", "w") as f:
    f.write(f"{scale}\n")
with open(f"{dest}/ATTRIBUTION.txt", "w") as f:
    f.write(
        "Middlebury 2014 stereo dataset, Motorcycle, quarter resolution, as distributed in\n"
        "scikit-image (skimage/data/motorcycle_*). D. Scharstein, H. Hirschmueller, Y. Kitajima,\n"
        "G. Krathwohl, N. Nesic, X. Wang and P. Westling: High-resolution stereo datasets with\n"
        "subpixel-accurate ground truth. GCPR 2014. Convention: the left pixel at x matches the\n"
        "right pixel at x - disparity on the same row.\n"
    )
print(f"motorcycle: {width}x{height}, ground truth x{scale}")
EOF
rm -rf "$out/motorcycle"
mv "$out/motorcycle.tmp" "$out/motorcycle"
echo "written $out/motorcycle"
