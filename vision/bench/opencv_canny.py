#!/usr/bin/env python3
"""OpenCV's single-thread Canny on the same image and parameters as VIDET's Canny.

Run by the `canny_vs_opencv` bench (`cargo bench -p videt-vision --bench canny_vs_opencv`),
which writes the 640x480 image and VIDET's edge map, calls this script and prints the ratio of
the two medians measured in the same run. Needs `pip install opencv-python-headless numpy`.

VIDET's detector includes the Gaussian smoothing, so the like-for-like OpenCV time is
GaussianBlur (same kernel size and sigma) + Canny (3x3 Sobel, L1 gradient, same thresholds);
OpenCV's Canny alone is reported too. With --other-image the timed calls take the two images
in turn, as the bench does for VIDET (one image over and over lets the branch predictor learn
it). The edge comparison uses --image. Prints one JSON object.
"""
import argparse
import json
import math
import time

import cv2
import numpy as np


def median_ms(fn, images, repeat):
    for k in range(20):
        fn(images[k % len(images)])
    times = []
    for k in range(repeat):
        image = images[k % len(images)]
        t0 = time.perf_counter_ns()
        fn(image)
        times.append(time.perf_counter_ns() - t0)
    times.sort()
    return times[len(times) // 2] / 1e6


def main():
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--image", required=True)
    p.add_argument("--other-image", help="a second image of the same size, timed in turn")
    p.add_argument("--videt-edges", help="VIDET's edge map (PNG, non-zero = edge) to compare")
    p.add_argument("--sigma", type=float, default=1.0)
    p.add_argument("--low", type=float, default=40)
    p.add_argument("--high", type=float, default=100)
    p.add_argument("--repeat", type=int, default=300)
    a = p.parse_args()

    cv2.setNumThreads(1)
    img = cv2.imread(a.image, cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise SystemExit(f"cannot read {a.image}")
    images = [img]
    if a.other_image:
        other = cv2.imread(a.other_image, cv2.IMREAD_GRAYSCALE)
        if other is None or other.shape != img.shape:
            raise SystemExit(f"cannot read {a.other_image} at the size of {a.image}")
        images.append(other)
    ksize = 2 * max(1, math.ceil(2 * a.sigma)) + 1
    blurred = [cv2.GaussianBlur(i, (ksize, ksize), a.sigma) for i in images]

    def blur_canny(image):
        b = cv2.GaussianBlur(image, (ksize, ksize), a.sigma)
        return cv2.Canny(b, a.low, a.high, apertureSize=3, L2gradient=False)

    def canny_only(smoothed):
        return cv2.Canny(smoothed, a.low, a.high, apertureSize=3, L2gradient=False)

    result = {
        "opencv_version": cv2.__version__,
        "threads": cv2.getNumThreads(),
        "image": a.image,
        "size": [int(img.shape[1]), int(img.shape[0])],
        "kernel": ksize,
        "images_in_turn": len(images),
        "blur_canny_ms_median": median_ms(blur_canny, images, a.repeat),
        "canny_only_ms_median": median_ms(canny_only, blurred, a.repeat),
    }
    if a.videt_edges:
        ours = cv2.imread(a.videt_edges, cv2.IMREAD_GRAYSCALE) > 0
        theirs = blur_canny(img) > 0
        near_theirs = cv2.dilate(theirs.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
        near_ours = cv2.dilate(ours.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
        result["videt_edge_pixels"] = int(ours.sum())
        result["opencv_edge_pixels"] = int(theirs.sum())
        result["videt_edges_within_1px_of_opencv"] = float((ours & near_theirs).sum() / max(1, ours.sum()))
        result["opencv_edges_within_1px_of_videt"] = float((theirs & near_ours).sum() / max(1, theirs.sum()))
    print(json.dumps(result))


if __name__ == "__main__":
    main()
