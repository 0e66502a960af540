#!/usr/bin/env bash
# Fetch and make stereo pairs with ground truth beyond the shared test data, for held-out
# accuracy figures (evaluation/examples/stereo_heldout.rs). Into DIR, one directory per pair:
#
# - motorcycle: Middlebury 2014 "Motorcycle" (quarter resolution, 741x500), as scikit-image
#   ships it in its wheel;
# - syn-poster, syn-map, syn-page, syn-desk, syn-shelf: 640x480 pairs synthesised from the real
#   photographs of the same wheel printed on planes (evaluation/examples/synthesise_stereo.rs:
#   exact ground truth for both views, per-camera blur, vignetting, gain/offset and noise);
# - aloe: Middlebury 2006 "Aloe" (real, 1282x1110 JPEG with its left ground truth), as Debian's
#   opencv-doc ships it in its examples; halved and cropped to 640x480. Needs apt-get (a Debian
#   system); skipped with a note where there is none.
#
# Each as {left.png,right.png,disp_left.pgm[,disp_right.pgm],scale.txt,ATTRIBUTION.txt}: the
# ground truth in the Middlebury 8-bit convention (disparity x scale, 0 = unknown), the scale in
# scale.txt. Pairs already there are kept.
#
#   bash scripts/fetch-extra-stereo.sh [DIR]      # default DIR: target/extra-stereo
#
# Needs pip, python3 (no numpy: the .npz and the .deb are read with the standard library) and
# cargo.
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-target/extra-stereo}"
version=0.26.0
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
mkdir -p "$out"

synthetic=(syn-poster syn-map syn-page syn-desk syn-shelf)
textures=(astronaut brick camera chelsea coffee grass gravel page rocket text)

missing_synthetic=0
for name in "${synthetic[@]}"; do
    [ -f "$out/$name/disp_left.pgm" ] || missing_synthetic=1
done

wheel=""
fetch_wheel() {
    if [ -z "$wheel" ]; then
        python3 -m pip download --quiet --no-deps --only-binary=:all: \
            --platform manylinux_2_28_x86_64 --python-version 3.11 \
            -d "$work" "scikit-image==$version"
        wheel="$(ls "$work"/scikit_image-*.whl)"
    fi
}

# --- Middlebury 2014 Motorcycle, from the scikit-image wheel ---------------------------------
if [ -f "$out/motorcycle/disp_left.pgm" ]; then
    echo "already there: $out/motorcycle"
else
    fetch_wheel
    rm -rf "$out/motorcycle.tmp"
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
fi

# --- Synthesised pairs with the wheel's photographs ------------------------------------------
if [ "$missing_synthetic" = 0 ]; then
    echo "already there: ${synthetic[*]}"
else
    fetch_wheel
    mkdir -p "$work/textures"
    python3 - "$wheel" "$work/textures" "${textures[@]}" <<'EOF'
import sys, zipfile

wheel, dest, names = sys.argv[1], sys.argv[2], sys.argv[3:]
with zipfile.ZipFile(wheel) as w:
    present = set(w.namelist())
    for name in names:
        for ext in ("png", "jpg"):
            member = f"skimage/data/{name}.{ext}"
            if member in present:
                with open(f"{dest}/{name}.{ext}", "wb") as f:
                    f.write(w.read(member))
                break
        else:
            sys.exit(f"{name}: not in the wheel")
EOF
    cargo run --release --quiet -p videt-evaluation --example synthesise_stereo -- \
        "$work/textures" "$out"
fi

# --- Middlebury 2006 Aloe, from Debian's opencv-doc -------------------------------------------
if [ -f "$out/aloe/disp_left.pgm" ]; then
    echo "already there: $out/aloe"
elif ! command -v apt-get >/dev/null; then
    echo "aloe: skipped (it comes from Debian's opencv-doc package: no apt-get here)"
else
    mkdir -p "$work/deb" "$work/aloe"
    chmod 755 "$work" && chmod 777 "$work/deb" # apt-get downloads as its unprivileged user
    if ! (cd "$work/deb" && apt-get download opencv-doc); then
        echo "aloe: skipped (apt-get download opencv-doc failed; try apt-get update first)"
        exit 0
    fi
    deb="$(ls "$work"/deb/opencv-doc_*.deb)"
    python3 - "$deb" "$work/aloe" <<'EOF'
import io, os, sys, tarfile

deb, dest = sys.argv[1], sys.argv[2]
with open(deb, "rb") as f:
    data = f.read()
if data[:8] != b"!<arch>\n":
    sys.exit(f"{deb}: not a Debian package")
members, pos = {}, 8
while pos + 60 <= len(data):
    header = data[pos:pos + 60]
    name = header[:16].decode().strip().rstrip("/")
    size = int(header[48:58].decode().strip())
    members[name] = (pos + 60, size)
    pos += 60 + size + (size & 1)
name = next((n for n in members if n.startswith("data.tar")), None)
if name is None:
    sys.exit(f"{deb}: no data archive")
start, size = members[name]
want = {"aloeL.jpg", "aloeR.jpg", "aloeGT.png"}
with tarfile.open(fileobj=io.BytesIO(data[start:start + size]), mode="r:*") as t:
    for m in t:
        base = m.name.rsplit("/", 1)[-1]
        if base in want and "/examples/data/" in m.name:
            with open(os.path.join(dest, base), "wb") as f:
                f.write(t.extractfile(m).read())
            want.discard(base)
            if not want:
                break
if want:
    sys.exit(f"{deb}: missing {sorted(want)}")
version = os.path.basename(deb).split("_")[1]
with open(os.path.join(dest, "ATTRIBUTION.txt"), "w") as f:
    f.write(
        "Middlebury 2006 stereo dataset, Aloe (views 1 and 5, full size 1282x1110, JPEG, with\n"
        f"the left ground truth), as distributed in OpenCV's sample data (Debian opencv-doc\n"
        f"{version}: examples/data/aloeL.jpg, aloeR.jpg, aloeGT.png). Here halved (2 x 2 means)\n"
        "and cropped about the centre to 640x480; the left pixels the right camera cannot see\n"
        "(by the left ground truth warped into the right view) are set to 0 (unknown).\n"
        "H. Hirschmueller and D. Scharstein: Evaluation of cost functions for stereo matching.\n"
        "CVPR 2007. D. Scharstein and C. Pal: Learning conditional random fields for stereo.\n"
        "CVPR 2007. Convention: the left pixel at x matches the right pixel at x - disparity on\n"
        "the same row.\n"
    )
EOF
    # aloeGT.png holds the full-size disparities (scale 1; 0 = unknown).
    cargo run --release --quiet -p videt-evaluation --example synthesise_stereo -- --import aloe \
        "$work/aloe/aloeL.jpg" "$work/aloe/aloeR.jpg" "$work/aloe/aloeGT.png" 1 \
        "$work/aloe/ATTRIBUTION.txt" "$out"
fi
