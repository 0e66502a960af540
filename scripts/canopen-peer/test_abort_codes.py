"""The SDO abort codes the drive driver names (`drivers/src/canopen/codes.rs`), against
python-canopen's table of CiA 301's codes: every code the independent stack knows has a text of
its own in the driver's table, and no code the driver names is unknown to CiA 301.

Run: python3 -m pytest -q scripts/canopen-peer/test_abort_codes.py
"""

from __future__ import annotations

import re
from pathlib import Path

from canopen.sdo.exceptions import SdoAbortedError

CODES_RS = Path(__file__).resolve().parents[2] / "drivers" / "src" / "canopen" / "codes.rs"


def driver_abort_texts() -> dict[int, str]:
    """The match arms of `sdo_abort_description`: code -> text."""
    source = CODES_RS.read_text()
    body = source[source.index("pub fn sdo_abort_description"):]
    body = body[:body.index("\n}\n")]
    # An arm is `CODE => "text"` or, where rustfmt wraps a long text, `CODE => { "text" }`.
    arms = re.findall(r'(0x[0-9A-Fa-f_]+)\s*=>\s*\{?\s*"((?:[^"\\]|\\.|\\\n)*)"', body)
    texts = {int(code.replace("_", ""), 16): re.sub(r"\\\n\s*", "", text) for code, text in arms}
    every_arm = re.findall(r'(0x[0-9A-Fa-f_]+)\s*=>', body)
    assert len(texts) == len(every_arm), f"arms whose text was not read: {set(every_arm) - {code for code, _ in arms}}"
    assert len(texts) > 20, texts
    return texts


def test_every_cia301_abort_code_python_canopen_knows_is_named_by_the_driver() -> None:
    ours = driver_abort_texts()
    theirs = SdoAbortedError.CODES
    missing = {f"{c:#010x}": t for c, t in theirs.items() if c not in ours}
    assert not missing, f"the driver calls these 'unknown SDO abort code': {missing}"
    extra = {f"{c:#010x}": t for c, t in ours.items() if c not in theirs}
    assert not extra, f"codes the driver names that CiA 301 (python-canopen) does not: {extra}"
