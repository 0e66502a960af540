"""`videt log FILE.vlog --mcap OUT.mcap`, read back by an MCAP reader the project did not write:
the PyPI `mcap` package (the reader Foxglove publishes) and `mcap-protobuf-support`, which
decodes every message from the schema stored in the file.

Two twin sessions are recorded by `videtd` (a wall, and the bas-relief box), converted with
`videt`, and the MCAP files are checked against the session logs, which this file parses on its
own from the documented format (docs/telemetry.md, versions 3 and 4, the compressed blocks
decoded with the PyPI `zstandard` package): the channels and schemas, one message per
period on every fast topic, non-decreasing log times, one `/scene/relief` message per recorded
surface version, the safety messages, the attachments and metadata, and at least one decoded
message per schema.

Run (from the repository root):

    cargo build --release --bin videtd --bin videt
    python3 -m pip install -r scripts/viewer-readers/requirements.txt
    python3 -m pytest -q scripts/viewer-readers

The binaries are taken from `VIDET_BIN_DIR` when set, else from target/release, else
target/debug (the newer of the two when both hold them).
"""

from __future__ import annotations

import json
import os
import struct
import subprocess
import zlib
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory
import zstandard

ROOT = Path(__file__).resolve().parents[2]
FAST_TOPICS = ["/thimble/pose", "/scene/wires", "/scene/forces", "/tension", "/timing"]
SCHEMAS = {
    "/thimble/pose": "foxglove.PoseInFrame",
    "/scene/wires": "foxglove.SceneUpdate",
    "/scene/forces": "foxglove.SceneUpdate",
    "/scene/relief": "foxglove.SceneUpdate",
    "/tension": "tension.Tension",
    "/safety": "safety.Safety",
    "/timing": "timing.Timing",
}
SESSION_S = 2


def binaries() -> tuple[Path, Path]:
    """videtd and videt: VIDET_BIN_DIR, else the newer of target/release and target/debug."""
    dirs = (
        [Path(os.environ["VIDET_BIN_DIR"])]
        if "VIDET_BIN_DIR" in os.environ
        else [ROOT / "target" / "release", ROOT / "target" / "debug"]
    )
    found = [d for d in dirs if (d / "videtd").is_file() and (d / "videt").is_file()]
    if not found:
        pytest.fail(
            f"no videtd and videt in {', '.join(map(str, dirs))}: "
            "build them with `cargo build --release --bin videtd --bin videt`"
        )
    d = max(found, key=lambda d: (d / "videt").stat().st_mtime)
    return d / "videtd", d / "videt"


@dataclass
class VlogFacts:
    """What a session log holds, read from its frames (docs/telemetry.md, versions 3 and 4)."""

    periods: int = 0
    first_time_ns: int | None = None
    surfaces: list[int] = field(default_factory=list)
    lost: list[int] = field(default_factory=list)
    calibrations: int = 0
    session: bool = False
    safety: list[tuple[int, int, int]] = field(default_factory=list)
    # The end frame: (last period, periods written, periods dropped, reason code).
    end: tuple[int, int, int, int] | None = None


MASK = (1 << 64) - 1
FIELDS = 52  # eight-byte fields of a 416-byte period


def unzigzag(z: int) -> int:
    return (z >> 1) ^ (-(z & 1) & MASK)


def block_frames(payload: bytes) -> list[tuple[int, bytes]]:
    """The frames of a version 4 block, decoded from its documented layout (docs/telemetry.md,
    "Format (version 4)"): the frame stream and the period table, each a zstd frame; each
    field's residuals undone by its prediction."""
    stream_len, rows, stream_zlen = struct.unpack_from("<III", payload, 0)
    predictions = payload[12:12 + FIELDS]
    unzstd = zstandard.ZstdDecompressor()
    stream = unzstd.decompress(payload[64:64 + stream_zlen], max_output_size=stream_len)
    assert len(stream) == stream_len
    table = unzstd.decompress(payload[64 + stream_zlen:], max_output_size=rows * 416) if rows else b""
    assert len(table) == rows * 416
    values = [[0] * FIELDS for _ in range(rows)]
    for f in range(FIELDS):
        column = table[f * 8 * rows:(f + 1) * 8 * rows]
        planes = [column[b * rows:(b + 1) * rows] for b in range(8)]
        p = predictions[f]
        before = before2 = 0
        for row in range(rows):
            r = sum(planes[b][row] << (8 * b) for b in range(8))
            if p == 0:
                v = r ^ before
            elif p == 1:
                v = (unzigzag(r) + before) & MASK
            elif p == 2:
                v = (unzigzag(r) + 2 * before - before2) & MASK
            else:
                g = p - 3
                assert g < f, f"field {f} follows field {g}"
                step = (values[row][g] - (values[row - 1][g] if row else 0)) & MASK
                v = (unzigzag(r) + before + step) & MASK
            values[row][f] = v
            before2, before = before, v
    periods = [b"".join(v.to_bytes(8, "little") for v in row) for row in values]
    frames, at, taken = [], 0, 0
    while at < len(stream):
        kind = stream[at]
        (n,) = struct.unpack_from("<I", stream, at + 4)
        if kind == 4 and n == 0:
            frames.append((kind, periods[taken]))
            taken += 1
        else:
            frames.append((kind, stream[at + 8:at + 8 + n]))
        at += 8 + n
    assert taken == rows, f"{rows} periods in the table, {taken} period frames"
    return frames


def read_vlog(path: Path) -> VlogFacts:
    data = path.read_bytes()
    assert data[:8] == b"VIDETLOG", "not a session log"
    version, period_bytes = struct.unpack_from("<II", data, 8)
    assert version in (3, 4) and period_bytes == 416, (version, period_bytes)
    facts = VlogFacts()
    at = 32
    last_safety = None
    frames: list[tuple[int, bytes]] = []
    while at + 8 <= len(data):
        kind = data[at]
        (n,) = struct.unpack_from("<I", data, at + 4)
        end = at + 8 + n
        if end + 4 > len(data):
            break
        (crc,) = struct.unpack_from("<I", data, end)
        assert zlib.crc32(data[at:end]) == crc, f"CRC mismatch at byte {at}"
        payload = data[at + 8 : end]
        if version == 4:
            assert kind == 7, f"a frame of kind {kind} outside a block at byte {at}"
            frames.extend(block_frames(payload))
        else:
            frames.append((kind, payload))
        at = end + 4
    for kind, payload in frames:
        if kind == 1:
            facts.session = True
        elif kind == 2:
            facts.calibrations += 1
        elif kind == 3:
            facts.surfaces.append(struct.unpack_from("<Q", payload, 0)[0])
        elif kind == 4:
            facts.periods += 1
            (time_ns,) = struct.unpack_from("<Q", payload, 8)
            if facts.first_time_ns is None:
                facts.first_time_ns = time_ns
            # The released wire and the stale flag go to /safety too.
            (flags,) = struct.unpack_from("<I", payload, 248)
            state = (*payload[252:255], payload[255], flags & 2)
            if state != last_safety:
                facts.safety.append(state)
                last_safety = state
        elif kind == 5:
            facts.lost.append(struct.unpack_from("<Q", payload, 0)[0])
        elif kind == 6:
            facts.end = (*struct.unpack_from("<QQQ", payload, 0), payload[24])
    return facts


@dataclass
class Session:
    vlog: Path
    mcap: Path
    facts: VlogFacts
    summary: dict
    convert_stdout: str


def record_and_convert(tmp: Path, name: str, *scene: str) -> Session:
    videtd, videt = binaries()
    logs = tmp / name
    logs.mkdir()
    subprocess.run(
        [str(videtd), "--sim", *scene, "--duration", str(SESSION_S), "--no-socket",
         "--telemetry-dir", str(logs)],
        check=True, capture_output=True, timeout=120,
    )
    (vlog,) = logs.glob("videt-*.vlog")
    out = tmp / f"{name}.mcap"
    convert = subprocess.run(
        [str(videt), "log", str(vlog), "--mcap", str(out)],
        check=True, capture_output=True, text=True, timeout=300,
    )
    summary = json.loads(
        subprocess.run(
            [str(videt), "log", str(vlog), "--json"],
            check=True, capture_output=True, text=True, timeout=120,
        ).stdout
    )
    return Session(vlog, out, read_vlog(vlog), summary, convert.stdout)


@pytest.fixture(scope="module")
def sessions(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Session]:
    tmp = tmp_path_factory.mktemp("viewer-readers")
    return {
        "wall": record_and_convert(tmp, "wall"),
        "box": record_and_convert(tmp, "box", "--scene", "box"),
    }


SCENES = ["wall", "box"]


def messages_by_topic(path: Path) -> dict[str, list[int]]:
    times: dict[str, list[int]] = defaultdict(list)
    with path.open("rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages(log_time_order=False):
            times[channel.topic].append(message.log_time)
    return times


@pytest.mark.parametrize("scene", SCENES)
def test_channels_and_schemas_are_the_documented_ones(sessions, scene):
    with sessions[scene].mcap.open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    channels = {c.topic: summary.schemas[c.schema_id] for c in summary.channels.values()}
    assert set(channels) == set(SCHEMAS)
    for topic, schema in channels.items():
        assert schema.name == SCHEMAS[topic], topic
        assert schema.encoding == "protobuf"
    for c in summary.channels.values():
        assert c.message_encoding == "protobuf"
    assert {c.compression for c in summary.chunk_indexes} == {"zstd"}


@pytest.mark.parametrize("scene", SCENES)
def test_one_message_per_period_in_order_and_one_per_surface_version(sessions, scene):
    s = sessions[scene]
    assert s.facts.periods == s.summary["records"] > 1000
    times = messages_by_topic(s.mcap)
    for topic in FAST_TOPICS:
        assert len(times[topic]) == s.facts.periods, topic
        assert times[topic][0] == s.facts.first_time_ns, topic
    for topic, t in times.items():
        assert all(a <= b for a, b in zip(t, t[1:])), f"{topic}: log times go back"
    assert len(times["/scene/relief"]) == len(s.facts.surfaces) >= 1
    assert sorted(s.facts.surfaces) == sorted(set(s.facts.surfaces))
    assert len(times["/safety"]) == len(s.facts.safety)
    assert f"{s.facts.periods} periods" in s.convert_stdout
    assert not s.mcap.with_name(s.mcap.name + ".partial").exists()


@pytest.mark.parametrize("scene", SCENES)
def test_configuration_and_calibrations_are_attached(sessions, scene):
    s = sessions[scene]
    with s.mcap.open("rb") as f:
        reader = make_reader(f)
        attachments = {a.name: a for a in reader.iter_attachments()}
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
    assert s.facts.session and s.facts.calibrations >= 1
    expected = {"config.toml"} | {f"calibration-{n}.json" for n in range(s.facts.calibrations)}
    assert set(attachments) == expected
    config = attachments["config.toml"].data.decode()
    assert "[control]" in config and "t_max_n" in config
    calibration = json.loads(attachments["calibration-0.json"].data)
    assert len(calibration["guides_m"]) == 3 and calibration["calibrated"] is True
    session = metadata["videt.session"]
    assert session["records"] == str(s.facts.periods)
    # Closed by the service when its duration elapsed (reason 3), after every period written.
    assert s.facts.end is not None
    assert (s.facts.end[1], s.facts.end[3]) == (s.facts.periods, 3)
    assert session["closed"] == "true" and "duration elapsed" in session["end"]
    assert session["device"] == "wireman3"
    assert ("box" in session["what"]) == (scene == "box")


@pytest.mark.parametrize("scene", SCENES)
def test_every_schema_decodes(sessions, scene):
    s = sessions[scene]
    first: dict[str, object] = {}
    counts: Counter[str] = Counter()
    with s.mcap.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _schema, channel, _message, decoded in reader.iter_decoded_messages():
            counts[channel.topic] += 1
            first.setdefault(channel.topic, decoded)
    assert set(first) == set(SCHEMAS)

    pose = first["/thimble/pose"]
    assert pose.frame_id == "rig"
    assert 0.0 < pose.pose.position.z < 1.0
    assert pose.pose.orientation.w == 1.0

    wires = first["/scene/wires"].entities[0]
    assert wires.frame_id == "rig" and len(wires.lines) == 3
    assert all(len(line.points) == 2 for line in wires.lines)

    relief = first["/scene/relief"].entities[0]
    (triangles,) = relief.triangles
    assert len(triangles.indices) % 3 == 0 and len(triangles.indices) >= 6
    assert max(triangles.indices) < len(triangles.points)
    kinds = {kv.key: kv.value for kv in relief.metadata}
    assert kinds["kind"] == ("relief" if scene == "box" else "plane")

    tension = first["/tension"]
    assert len(tension.measured_n) == len(tension.setpoint_n) == 3
    assert len(tension.velocity_m_s) == 3 and tension.speed_m_s >= 0.0

    safety = first["/safety"]
    assert safety.state in ("normal", "minimum-tension", "power-off")
    assert safety.released_wire == -1

    timing = first["/timing"]
    assert timing.wake_latency_us == pytest.approx(timing.wake_latency_ns * 1e-3)
    assert counts["/timing"] == s.facts.periods


def test_every_n_decimates_the_fast_topics_only(sessions, tmp_path):
    s = sessions["box"]
    _, videt = binaries()
    out = tmp_path / "every10.mcap"
    subprocess.run(
        [str(videt), "log", str(s.vlog), "--mcap", str(out), "--every", "10"],
        check=True, capture_output=True, timeout=300,
    )
    times = messages_by_topic(out)
    for topic in FAST_TOPICS:
        assert len(times[topic]) == (s.facts.periods + 9) // 10, topic
    assert len(times["/scene/relief"]) == len(s.facts.surfaces)
    assert len(times["/safety"]) == len(s.facts.safety)
    assert out.stat().st_size < s.mcap.stat().st_size


def test_a_failed_conversion_leaves_the_existing_output_alone(sessions, tmp_path):
    _, videt = binaries()
    out = tmp_path / "kept.mcap"
    out.write_bytes(b"previous")
    # Not a session log: an error, and the output untouched.
    bad = tmp_path / "bad.vlog"
    bad.write_bytes(b"#!/bin/sh\n")
    r = subprocess.run([str(videt), "log", str(bad), "--mcap", str(out)],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and "not a VIDET session log" in r.stderr
    # The partial file cannot be written.
    (tmp_path / "kept.mcap.partial").mkdir()
    r = subprocess.run([str(videt), "log", str(sessions["wall"].vlog), "--mcap", str(out)],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and "kept.mcap.partial" in r.stderr
    assert out.read_bytes() == b"previous"
    r = subprocess.run([str(videt), "log", str(sessions["wall"].vlog), "--mcap", str(out),
                        "--every", "0"], capture_output=True, text=True, timeout=60)
    assert r.returncode != 0 and "--every" in r.stderr
