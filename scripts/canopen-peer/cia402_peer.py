#!/usr/bin/env python3
"""Simulated CiA 402 wire drives served by python-canopen: an independent CANopen peer for
testing the project's drive driver against a stack it did not write.

    python3 cia402_peer.py --interface socketcan --channel vcan0 --eds DRIVE.dcf --nodes 1,2,3

Each node is a python-canopen ``LocalNode`` (SDO server, NMT slave, heartbeat producer) with
the object dictionary of the given EDS/DCF; on top, :mod:`drive_node` adds the CiA 301 checks
python-canopen lacks, the PDOs, the CiA 402 power state machine and a motor winding a wire
into a spring. Runs until SIGTERM/SIGINT.
"""

from __future__ import annotations

import argparse
import collections
import gc
import logging
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import canopen

sys.path.insert(0, str(Path(__file__).resolve().parent))

from drive_model import WireParams  # noqa: E402
from drive_node import OPERATIONAL, DriveNode  # noqa: E402
from pdo_channels import PdoChannel  # noqa: E402

log = logging.getLogger("cia402_peer")

SYNC_COB_ID = 0x080
#: SYNC handling times kept for the statistics (a ring).
SYNC_RING = 16384
#: Longest sleep of the housekeeping thread between timer checks, s.
HOUSEKEEPING_MAX_SLEEP_S = 0.02

__all__ = ["OdImportError", "Peer", "PeerConfig", "WireParams", "load_od", "main"]


class OdImportError(Exception):
    """python-canopen could not import an EDS/DCF."""


def load_od(path: str, node_id: int) -> canopen.ObjectDictionary:
    """The object dictionary of `path` for `node_id` (a fresh one per node)."""
    try:
        return canopen.import_od(path, node_id)
    except Exception as exc:  # any parse failure of the file
        raise OdImportError(f"{Path(path).name}: {type(exc).__name__}: {exc}") from exc


@dataclass(frozen=True)
class PeerConfig:
    """What the peer serves: which file, which node ids, the model and the timings."""

    eds: str
    nodes: tuple[int, ...]
    params: WireParams = WireParams()
    torque_unit: str = "mNm"
    boot_delay_s: float = 0.05
    ready_file: str | None = None
    #: Encoder position (counts) each node starts at, in node order; empty: all at 0.
    initial_positions: tuple[int, ...] = ()


class Peer:
    """The simulated drives on one CAN bus; every callback runs under one lock."""

    def __init__(self, cfg: PeerConfig, **bus_kwargs: object) -> None:
        self.cfg = cfg
        self.params = cfg.params
        self.boot_delay_s = cfg.boot_delay_s
        self.lock = threading.RLock()
        self.network = canopen.Network()
        self.network.NOTIFIER_CYCLE = 0.1  # the receive thread notices a stop within 0.1 s
        self._bus_kwargs = bus_kwargs
        self._events: collections.deque[tuple[str, tuple[object, ...]]] = collections.deque()
        self._routes: dict[int, list[tuple[DriveNode, PdoChannel]]] = {}
        self._watched: set[int] = set()
        self._sync_ns: list[int] = [0] * SYNC_RING
        self._sync_count = 0
        self._ready = False
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._thread = threading.Thread(target=self._housekeeping, name="peer-timers",
                                        daemon=True)
        self.nodes: dict[int, DriveNode] = {}
        positions = cfg.initial_positions or (0,) * len(cfg.nodes)
        if len(positions) != len(cfg.nodes):
            raise ValueError("one initial position per node")
        for node_id, position in zip(cfg.nodes, positions):
            self.nodes[node_id] = DriveNode(node_id, load_od(cfg.eds, node_id), self, position)

    # ----- lifecycle ----------------------------------------------------------------------

    def start(self) -> None:
        """Connect, and boot every node after the boot delay."""
        if self.cfg.ready_file:
            Path(self.cfg.ready_file).unlink(missing_ok=True)
        kwargs = dict(self._bus_kwargs)
        kwargs.setdefault("can_filters", self._can_filters())
        self.network.connect(**kwargs)
        self.network.subscribe(0, self._on_nmt)
        self.network.subscribe(SYNC_COB_ID, self._on_sync)
        now = time.monotonic()
        with self.lock:
            for node in self.nodes.values():
                self.network.add_node(node)
                node.attach()
                node.schedule_boot(now + self.boot_delay_s)
                self._check_rated_torque(node)
            self.routes_changed()
        self._thread.start()

    def _can_filters(self) -> list[dict[str, int]]:
        """What a drive listens to, as the socket's kernel filters: NMT, SYNC, heartbeats, and
        its own RPDOs and SDO requests; nothing else reaches the (slow) Python side."""
        exact = 0x7FF
        filters = [
            {"can_id": 0x000, "can_mask": exact},
            {"can_id": SYNC_COB_ID, "can_mask": exact},
            {"can_id": 0x700, "can_mask": 0x780},
        ]
        for n in self.nodes:
            for base in (0x200, 0x300, 0x400, 0x500, 0x600):
                filters.append({"can_id": base + n, "can_mask": exact})
        return filters

    def stop(self) -> None:
        """Stop the timers and the heartbeats, shut the bus down, log the SYNC statistics."""
        self._stop.set()
        self._wake.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        with self.lock:
            for node in self.nodes.values():
                node.nmt.stop_heartbeat()
        self.network.disconnect()
        stats = self.sync_stats_us()
        if stats:
            self.event("SYNC handling over %d SYNCs: median %.0f us, p99 %.0f us, max %.0f us",
                       stats["count"], stats["median"], stats["p99"], stats["max"])
        self._flush_events()

    def __enter__(self) -> Peer:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def ready(self) -> bool:
        """Whether every node has sent its first boot-up."""
        return self._ready

    # ----- services for the nodes ---------------------------------------------------------

    def send(self, cob_id: int, data: bytes) -> None:
        """Send one frame."""
        self.network.send_message(cob_id, data)

    def event(self, fmt: str, *args: object) -> None:
        """Queue a log line; the housekeeping thread writes it (off the SYNC path)."""
        self._events.append((fmt, args))

    def watch_host(self, host_id: int) -> None:
        """Deliver the heartbeats of `host_id` to the nodes' consumers."""
        if host_id not in self._watched:
            self._watched.add(host_id)
            self.network.subscribe(0x700 + host_id, self._on_heartbeat)

    def routes_changed(self) -> None:
        """Subscribe the COB-IDs of every valid RPDO, and only those."""
        routes: dict[int, list[tuple[DriveNode, PdoChannel]]] = {}
        for node in self.nodes.values():
            for ch in node.rpdos:
                if ch.valid:
                    routes.setdefault(ch.cob_id, []).append((node, ch))
        for cob in set(self._routes) - set(routes):
            self.network.unsubscribe(cob, self._on_rpdo)
        for cob in set(routes) - set(self._routes):
            self.network.subscribe(cob, self._on_rpdo)
        self._routes = routes

    # ----- bus callbacks (python-can's notifier thread) -----------------------------------

    def _on_sync(self, can_id: int, data: bytearray, timestamp: float) -> None:
        t0 = time.perf_counter_ns()
        now = time.monotonic()
        with self.lock:
            for node in self.nodes.values():
                if node.nmt_state == OPERATIONAL:
                    node.on_sync(now)
        self._sync_ns[self._sync_count % SYNC_RING] = time.perf_counter_ns() - t0
        self._sync_count += 1

    def _on_rpdo(self, can_id: int, data: bytearray, timestamp: float) -> None:
        now = time.monotonic()
        with self.lock:
            for node, ch in self._routes.get(can_id, ()):
                node.on_rpdo(ch, data, now)

    def _on_nmt(self, can_id: int, data: bytearray, timestamp: float) -> None:
        if len(data) < 2:
            return
        command, target = data[0], data[1]
        now = time.monotonic()
        with self.lock:
            for node in self.nodes.values():
                if target in (0, node.id):
                    node.on_nmt(command, now)
        self._wake.set()

    def _on_heartbeat(self, can_id: int, data: bytearray, timestamp: float) -> None:
        now = time.monotonic()
        with self.lock:
            for node in self.nodes.values():
                node.on_host_heartbeat(can_id - 0x700, now)

    # ----- housekeeping thread ------------------------------------------------------------

    def _housekeeping(self) -> None:
        while not self._stop.is_set():
            with self.lock:
                now = time.monotonic()
                for node in self.nodes.values():
                    node.poll(now)
                deadline = min(n.next_deadline() for n in self.nodes.values())
                if not self._ready and all(n.booted for n in self.nodes.values()):
                    self._ready = True
                    self._write_ready_file()
            self._flush_events()
            sleep = min(max(deadline - time.monotonic(), 0.0005), HOUSEKEEPING_MAX_SLEEP_S)
            self._wake.wait(sleep)
            self._wake.clear()

    def _flush_events(self) -> None:
        while self._events:
            fmt, args = self._events.popleft()
            log.info(fmt, *args)

    def _write_ready_file(self) -> None:
        self.event("all nodes booted: %s", ",".join(map(str, self.nodes)))
        if not self.cfg.ready_file:
            return
        path = Path(self.cfg.ready_file)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        tmp.write_text(f"nodes={','.join(map(str, self.nodes))} pid={os.getpid()}\n")
        os.replace(tmp, path)

    def _check_rated_torque(self, node: DriveNode) -> None:
        """Note when the OD's 0x6076 differs from the rated torque the model uses."""
        rated = node.read_int(0x6076, 0)
        scale = 1e3 if self.cfg.torque_unit == "mNm" else 1e6
        expected = round(self.params.rated_torque_nm * scale)
        if rated is not None and rated != expected:
            self.event("node %d: 0x6076 = %d %s in the OD, the model uses %d %s "
                       "(--rated-torque-nm %g)", node.id, rated, self.cfg.torque_unit,
                       expected, self.cfg.torque_unit, self.params.rated_torque_nm)

    # ----- statistics ---------------------------------------------------------------------

    def sync_stats_us(self) -> dict[str, float]:
        """Median, p99 and max of the SYNC handling time (µs) over the last SYNCs."""
        n = min(self._sync_count, SYNC_RING)
        if not n:
            return {}
        times = sorted(self._sync_ns[:n])
        pick = lambda q: times[min(n - 1, math.ceil(q * n) - 1)] / 1000.0  # noqa: E731
        return {"count": float(n), "median": pick(0.5), "p99": pick(0.99),
                "max": times[-1] / 1000.0}

    def reset_sync_stats(self) -> None:
        """Forget the SYNC handling times measured so far."""
        self._sync_count = 0


def _int_list(text: str) -> tuple[int, ...]:
    try:
        return tuple(int(part, 0) for part in text.split(",") if part.strip())
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"comma-separated integers: {exc}") from exc


def _node_list(text: str) -> tuple[int, ...]:
    ids = _int_list(text)
    if not ids or any(not 1 <= i <= 127 for i in ids) or len(set(ids)) != len(ids):
        raise argparse.ArgumentTypeError("node ids: distinct, 1..127, comma-separated")
    return ids


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """The command line."""
    d = WireParams()
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--interface", default="socketcan", help="python-can interface")
    p.add_argument("--channel", default="vcan0", help="python-can channel")
    p.add_argument("--eds", required=True, help="EDS or DCF of every node")
    p.add_argument("--nodes", type=_node_list, default=(1,), help="node ids, e.g. 1,2,3")
    p.add_argument("--rated-torque-nm", type=float, default=d.rated_torque_nm)
    p.add_argument("--torque-unit", choices=("mNm", "uNm"), default="mNm",
                   help="unit of the OD's 0x6076, to compare it with --rated-torque-nm")
    p.add_argument("--boot-delay-ms", type=float, default=50.0)
    p.add_argument("--ready-file", help="written once every node has booted")
    p.add_argument("--log", help="event log file")
    p.add_argument("--initial-position", type=_int_list, default=(),
                   help="encoder counts each node starts at: one value, or one per node")
    p.add_argument("--counts-per-rev", type=int, default=d.counts_per_rev)
    p.add_argument("--pulley-radius-m", type=float, default=d.pulley_radius_m)
    p.add_argument("--gear-ratio", type=float, default=d.gear_ratio)
    p.add_argument("--spring-n-per-m", type=float, default=d.spring_n_per_m)
    p.add_argument("--x0-m", type=float, default=d.x0_m, help="relaxed wound-in length")
    p.add_argument("--tension-offset-n", type=float, default=d.tension_offset_n)
    p.add_argument("--inertia-kg-m2", type=float, default=d.inertia_kg_m2)
    p.add_argument("--damping-nm-s-per-rad", type=float, default=d.damping_nm_s_per_rad)
    args = p.parse_args(argv)
    if len(args.initial_position) not in (0, 1, len(args.nodes)):
        p.error("--initial-position: one value, or one per node")
    return args


def config_from_args(args: argparse.Namespace) -> PeerConfig:
    """The peer configuration the command line asks for."""
    params = WireParams(
        pulley_radius_m=args.pulley_radius_m, gear_ratio=args.gear_ratio,
        spring_n_per_m=args.spring_n_per_m, x0_m=args.x0_m,
        tension_offset_n=args.tension_offset_n, inertia_kg_m2=args.inertia_kg_m2,
        damping_nm_s_per_rad=args.damping_nm_s_per_rad, counts_per_rev=args.counts_per_rev,
        rated_torque_nm=args.rated_torque_nm)
    positions = args.initial_position
    if len(positions) == 1:
        positions = positions * len(args.nodes)
    return PeerConfig(eds=args.eds, nodes=args.nodes, params=params,
                      torque_unit=args.torque_unit, boot_delay_s=args.boot_delay_ms / 1000.0,
                      ready_file=args.ready_file, initial_positions=positions)


def _setup_logging(path: str | None) -> None:
    handler: logging.Handler = (logging.FileHandler(path) if path
                                else logging.StreamHandler(sys.stderr))
    handler.setFormatter(logging.Formatter("%(asctime)s.%(msecs)03d %(message)s", "%H:%M:%S"))
    log.addHandler(handler)
    log.setLevel(logging.INFO if path else logging.WARNING)
    log.propagate = False


def main(argv: Sequence[str] | None = None) -> int:
    """Serve the drives until SIGTERM/SIGINT; 0 on a clean stop, 2 on an unusable EDS."""
    args = parse_args(argv)
    _setup_logging(args.log)
    stop = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.set())
    try:
        peer = Peer(config_from_args(args), interface=args.interface, channel=args.channel)
    except OdImportError as exc:
        log.error("cannot import the object dictionary: %s", exc)
        print(f"cia402_peer: cannot import the object dictionary: {exc}", file=sys.stderr)
        return 2
    peer.start()
    # The object dictionaries are many long-lived objects: keep them out of the collector's
    # full passes, which would otherwise stall a SYNC now and then.
    gc.freeze()
    log.info("serving nodes %s of %s on %s %s", ",".join(map(str, args.nodes)), args.eds,
             args.interface, args.channel)
    while not stop.wait(0.2):
        pass
    log.info("stopping")
    peer.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
