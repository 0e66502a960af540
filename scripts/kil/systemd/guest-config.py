#!/usr/bin/env python3
"""The systemd guest's device configuration: the example configuration with the guest's devices
(can0, the gpio-sim chip, the vivid cameras), tension read through the drives' analog inputs (a
PC guest has no SPI) and the emulated CPU's allowances, the same as the kernel-in-the-loop tests'
(tests/guest/mod.rs, guest_config). Paths stay the packaged ones: the service's directories.

    guest-config.py EXAMPLE.toml OUT.toml STEREO.json

STEREO.json is the stereo calibration of an ideal rig of two 640x480 cameras (f = 500 px, no
distortion, a 6 cm baseline, already rectified), as the vivid cameras are (tests/guest/mod.rs,
ideal_stereo_calibration): the identity rectification leaves their test patterns as they are.
"""
import json
import sys
import tomllib

OVERRIDES = {
    "drives": {
        "can_interface": "can0",
        # The emulated CPU answers late at times (tests/guest/mod.rs says why for each).
        "max_missed_cycles": 100,
        "pdo_wait_fraction": 0.95,
        "power_timeout_ms": 5000,
        "heartbeat_timeout_ms": 2000,
        "host_silence_timeout_ms": 2000,
        "sdo_timeout_ms": 2000,
    },
    "sensors": {
        "adc": "drive",
        "gpio_chip": "/dev/gpiochip0",
        "estop_line": 17,
        "vibrotactor_lines": [22, 23, 24],
        "newtons_per_count": [1e-3, 1e-3, 1e-3],
        "stale_after_ms": 1000,
    },
    "realtime": {"max_consecutive_overruns": 1000000},
    # The emulated loop runs at a quarter to a half of its rate, and a wall's Z-width falls with
    # the rate: the wall the parts hold there (tests/guest/mod.rs, GUEST_STIFFNESS_N_PER_M).
    "control": {"stiffness_n_per_m": 800.0},
    "vision": {
        "devices": ["/dev/video0", "/dev/video1"],
        "stereo_calibration": "/etc/videt/stereo.json",
    },
    # The 1.5 kHz vibration thread is a good part of what an emulated CPU can do.
    "colour": {"enabled": False},
    # The live view on loopback, as a technician turns it on (the unit allows IP there only).
    "live": {"enabled": True},
}


def value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, list):
        return "[" + ", ".join(value(x) for x in v) + "]"
    raise ValueError(f"cannot write {v!r}")


def ideal_stereo_calibration():
    f, cx, cy, b = 500.0, 320.0, 240.0, 0.06
    k = [[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]]
    eye = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]

    def p(tx):
        return [[f, 0.0, cx, tx], [0.0, f, cy, 0.0], [0.0, 0.0, 1.0, 0.0]]

    return {
        "format_version": 1, "image_width": 640, "image_height": 480,
        "m1": k, "d1": [0.0] * 5, "m2": k, "d2": [0.0] * 5,
        "r": eye, "t_m": [-b, 0.0, 0.0], "r1": eye, "r2": eye,
        "p1": p(0.0), "p2": p(-f * b),
        "q": [[1.0, 0.0, 0.0, -cx], [0.0, 1.0, 0.0, -cy], [0.0, 0.0, 0.0, f], [0.0, 0.0, 1.0 / b, 0.0]],
        "rms_left_px": 0.1, "rms_right_px": 0.1, "rms_stereo_px": 0.1,
        "epipolar_error_px": 0.0, "created_unix_s": 1700000000,
    }


def main(example, out, stereo):
    with open(stereo, "w") as f:
        json.dump(ideal_stereo_calibration(), f)
    with open(example, "rb") as f:
        config = tomllib.load(f)
    for section, keys in OVERRIDES.items():
        if section not in config:
            sys.exit(f"[{section}] is not in {example}")
        config[section].update(keys)
    lines = ["# The systemd guest's device (scripts/kil/systemd/guest-config.py)."]
    for section, keys in config.items():
        if not isinstance(keys, dict):
            sys.exit(f"{section} is not a table in {example}")
        lines.append(f"\n[{section}]")
        for key, v in keys.items():
            if isinstance(v, dict):
                sys.exit(f"[{section}.{key}]: nested tables are not written")
            lines.append(f"{key} = {value(v)}")
    with open(out, "w") as f:
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main(*sys.argv[1:])
