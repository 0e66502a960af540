"""What the live view costs: CPU share of its threads at the configured rate with one client
subscribed to every topic and reading, and the control loop's figures beside the same session
without the view. Not a test (pytest does not collect it); run from the repository root:

    cargo build --release --bin videtd
    python3 scripts/viewer-readers/live_cost.py [SECONDS] [SCENE]

Prints a Markdown table. Timings on a shared machine are noisy: compare the rows of one run.
"""

import asyncio
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import websockets

ROOT = Path(__file__).resolve().parents[2]
VIDETD = ROOT / "target" / "release" / "videtd"
TICK = os.sysconf("SC_CLK_TCK")


def thread_times(pid):
    """{thread name: CPU seconds} summed over threads of the same name."""
    out = {}
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            stat = (task / "stat").read_text()
        except OSError:
            continue
        name = stat[stat.index("(") + 1:stat.rindex(")")]
        fields = stat[stat.rindex(")") + 2:].split()
        out[name] = out.get(name, 0.0) + (int(fields[11]) + int(fields[12])) / TICK
    return out


def run(seconds, scene, live):
    err = tempfile.NamedTemporaryFile("w+", suffix=".err", delete=False)
    args = [str(VIDETD), "--sim", "--scene", scene, "--duration", str(seconds),
            "--no-socket", "--no-telemetry"]
    if live:
        args += ["--live", "127.0.0.1:0"]
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=err)
    received = [0, 0]
    before = after = {}
    if live:
        port = None
        while port is None and proc.poll() is None:
            m = re.search(r"ws://127\.0\.0\.1:(\d+)", Path(err.name).read_text())
            port = m and int(m.group(1))
            time.sleep(0.05)
        times = {}
        asyncio.run(read_all(port, seconds - 2, received, proc.pid, times))
        before, after, wall = times["before"], times["after"], times["wall"]
    proc.wait()
    log = Path(err.name).read_text()
    m = re.search(r"cycles=(\d+) overruns=(\d+) .*wake_p99_us=([\d.]+) wake_max_us=([\d.]+) "
                  r"compute_p99_us=([\d.]+)", log)
    loop = dict(zip(["cycles", "overruns", "wake_p99_us", "wake_max_us", "compute_p99_us"],
                    map(float, m.groups())))
    shares = {}
    if live:
        for name in after:
            if name.startswith("videt-live"):
                shares[name] = (after[name] - before.get(name, 0.0)) / wall
    return loop, shares, received


async def read_all(port, seconds, received, pid, times):
    """Subscribe to every topic and read for `seconds`; the threads' CPU times while connected
    go into `times` (before, after, wall)."""
    async with websockets.connect(f"ws://127.0.0.1:{port}",
                                  subprotocols=["foxglove.websocket.v1"], max_size=None) as ws:
        times["before"] = thread_times(pid)
        start = time.monotonic()
        channels = {}
        deadline = time.monotonic() + seconds
        subscribed = False
        while time.monotonic() < deadline:
            try:
                raw = await asyncio.wait_for(ws.recv(), 0.5)
            except asyncio.TimeoutError:
                continue
            if isinstance(raw, str):
                msg = json.loads(raw)
                if msg["op"] == "advertise":
                    channels.update({c["id"]: c for c in msg["channels"]})
                    if not subscribed and len(channels) >= 7:
                        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                            {"id": i, "channelId": c} for i, c in enumerate(channels)]}))
                        subscribed = True
            else:
                received[0] += 1
                received[1] += len(raw)
        times["after"] = thread_times(pid)
        times["wall"] = time.monotonic() - start


def main():
    seconds = int(sys.argv[1]) if len(sys.argv) > 1 else 60
    scene = sys.argv[2] if len(sys.argv) > 2 else "box"
    without, _, _ = run(seconds, scene, live=False)
    with_live, shares, received = run(seconds, scene, live=True)
    print(f"| | without the live view | with it, one client reading |")
    print("|---|---|---|")
    for key in ["overruns", "wake_p99_us", "wake_max_us", "compute_p99_us"]:
        print(f"| control loop {key} | {without[key]:g} | {with_live[key]:g} |")
    for name, share in sorted(shares.items()):
        print(f"| CPU of thread `{name}` | — | {100 * share:.2f} % of one core |")
    print(f"| CPU of the live view, all its threads | — | {100 * sum(shares.values()):.2f} % of one core |")
    rate = received[0] / (seconds - 2)
    print(f"| messages / bytes to the client | — | {rate:.0f} /s, {received[1] / (seconds - 2) / 1e3:.1f} kB/s |")


if __name__ == "__main__":
    main()
