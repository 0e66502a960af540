"""PDOs of a simulated node: the CiA 301 rules for (re)configuring them over SDO, and each
PDO's layout precomputed for the SYNC path (slices to unpack, byte strings to join)."""

from __future__ import annotations

from typing import Protocol

from canopen import objectdictionary as cod
from canopen.sdo import SdoAbortedError

ABORT_UNSUPPORTED_ACCESS = 0x06010000
ABORT_CANNOT_MAP = 0x06040041
ABORT_PDO_TOO_LONG = 0x06040042
ABORT_INVALID_VALUE = 0x06090030

PDO_INVALID = 0x8000_0000
CAN_ID_MASK = 0x1FFF_FFFF
MAX_PDO_BITS = 64

RPDO_COMM, RPDO_MAP, TPDO_COMM, TPDO_MAP = 0x1400, 0x1600, 0x1800, 0x1A00


class ObjectAccess(Protocol):
    """What the PDO rules need of a node: its OD and its current values."""

    object_dictionary: cod.ObjectDictionary
    data_store: dict[int, dict[int, bytes]]

    def read_int(self, index: int, subindex: int) -> int | None:
        """The current value of a numeric object, None when the OD lacks it."""


def classify(index: int) -> tuple[bool, bool, int] | None:
    """(is_tpdo, is_mapping, pdo number from 0) of a PDO parameter index, else None."""
    for base, tpdo, mapping in ((RPDO_COMM, False, False), (RPDO_MAP, False, True),
                                (TPDO_COMM, True, False), (TPDO_MAP, True, True)):
        if base <= index < base + 0x200:
            return tpdo, mapping, index - base
    return None


def find_variable(od: cod.ObjectDictionary, index: int, sub: int) -> cod.ODVariable | None:
    """The OD variable at index:sub, None when absent (a plain VAR only has sub 0)."""
    obj = od.get(index)
    if obj is None:
        return None
    if isinstance(obj, cod.ODVariable):
        return obj if sub == 0 else None
    return obj.subindices.get(sub)


def check_entry(od: cod.ObjectDictionary, entry: int, tpdo: bool) -> int:
    """Validate one mapping entry (index << 16 | sub << 8 | bits); return its bit length.

    Refused with 0x06040041 when the object is absent, not PDO-mappable, not readable (TPDO)
    or writable (RPDO), or when the length differs from the object's type. Dummy entries
    (index 1..7) are accepted in RPDOs when the OD declares them.
    """
    index, sub, bits = entry >> 16, (entry >> 8) & 0xFF, entry & 0xFF
    var = find_variable(od, index, sub)
    if var is None or bits == 0 or len(var) != bits:
        raise SdoAbortedError(ABORT_CANNOT_MAP)
    if index < 0x20:
        if tpdo:
            raise SdoAbortedError(ABORT_CANNOT_MAP)
        return bits
    if not var.pdo_mappable or (tpdo and not var.readable) or (not tpdo and not var.writable):
        raise SdoAbortedError(ABORT_CANNOT_MAP)
    return bits


def check_write(node: ObjectAccess, index: int, sub: int, value: int) -> None:
    """Refuse an SDO write to a PDO parameter that CiA 301 does not allow now."""
    kind = classify(index)
    if kind is None:
        return
    tpdo, mapping, number = kind
    comm = (TPDO_COMM if tpdo else RPDO_COMM) + number
    cob = node.read_int(comm, 1)
    valid = cob is not None and not cob & PDO_INVALID
    if not mapping:
        _check_comm_write(sub, value, cob, tpdo)
        return
    if valid:
        raise SdoAbortedError(ABORT_UNSUPPORTED_ACCESS)
    if sub == 0:
        _check_count(node, index, value, tpdo)
    elif node.read_int(index, 0):
        raise SdoAbortedError(ABORT_UNSUPPORTED_ACCESS)
    elif value:
        check_entry(node.object_dictionary, value, tpdo)


def _check_comm_write(sub: int, value: int, cob: int | None, tpdo: bool) -> None:
    if sub == 1 and cob is not None and not cob & PDO_INVALID and not value & PDO_INVALID:
        if (value ^ cob) & CAN_ID_MASK:
            raise SdoAbortedError(ABORT_INVALID_VALUE)  # CAN-ID of an existing PDO
    elif sub == 2 and 241 <= value <= (253 if not tpdo else 251):
        raise SdoAbortedError(ABORT_INVALID_VALUE)


def _check_count(node: ObjectAccess, map_index: int, count: int, tpdo: bool) -> None:
    if count > MAX_PDO_BITS:
        raise SdoAbortedError(ABORT_PDO_TOO_LONG)
    total = 0
    for sub in range(1, count + 1):
        entry = node.read_int(map_index, sub)
        if entry is None:
            raise SdoAbortedError(ABORT_PDO_TOO_LONG)
        total += check_entry(node.object_dictionary, entry, tpdo)
    if total > MAX_PDO_BITS:
        raise SdoAbortedError(ABORT_PDO_TOO_LONG)


class PdoChannel:
    """One PDO with its parameters as last loaded from the OD, and its runtime state."""

    def __init__(self, tpdo: bool, number: int) -> None:
        self.tpdo = tpdo
        self.number = number
        self.comm_index = (TPDO_COMM if tpdo else RPDO_COMM) + number
        self.map_index = (TPDO_MAP if tpdo else RPDO_MAP) + number
        self.cob_id = 0
        self.valid = False
        self.trans_type = 255
        self.inhibit_s = 0.0
        self.event_s = 0.0
        self.length = 0
        #: TPDO: (store dict of the index, sub) per mapped object, joined in order.
        self.sources: list[tuple[dict[int, bytes], int]] = []
        #: RPDO: (store dict of the index, sub, start, end) per mapped non-dummy object.
        self.sinks: list[tuple[dict[int, bytes], int, int, int]] = []
        self.sync_count = 0
        self.last_data: bytes | None = None
        self.last_sent = 0.0
        self.pending: bytes | None = None

    @property
    def synchronous(self) -> bool:
        """Transmission types 0..240 act at SYNC."""
        return self.trans_type <= 240

    def load(self, node: ObjectAccess) -> None:
        """Re-read the parameters and precompute the layout; resets the runtime state."""
        cob = node.read_int(self.comm_index, 1)
        self.cob_id = (cob or 0) & 0x7FF
        self.trans_type = node.read_int(self.comm_index, 2) or 0
        self.inhibit_s = (node.read_int(self.comm_index, 3) or 0) * 1e-4 if self.tpdo else 0.0
        self.event_s = (node.read_int(self.comm_index, 5) or 0) * 1e-3
        self.sources, self.sinks, offset = [], [], 0
        layout_ok = True
        for sub in range(1, (node.read_int(self.map_index, 0) or 0) + 1):
            entry = node.read_int(self.map_index, sub) or 0
            index, esub, nbytes = entry >> 16, (entry >> 8) & 0xFF, (entry & 0xFF) // 8
            if find_variable(node.object_dictionary, index, esub) is None or not nbytes:
                layout_ok = False
                break
            store = node.data_store.setdefault(index, {})
            store.setdefault(esub, bytes(nbytes))
            if self.tpdo:
                self.sources.append((store, esub))
            elif index >= 0x20:
                self.sinks.append((store, esub, offset, offset + nbytes))
            offset += nbytes
        self.length = offset
        self.valid = (cob is not None and not cob & PDO_INVALID and layout_ok
                      and 0 < offset <= 8 and self.trans_type not in range(241, 254))
        self.sync_count, self.last_data, self.last_sent, self.pending = 0, None, 0.0, None

    def pack(self) -> bytes:
        """TPDO data: the mapped objects' little-endian bytes, in mapping order."""
        return b"".join([store[sub] for store, sub in self.sources])

    def unpack(self, data: bytes) -> None:
        """RPDO data into the mapped objects (the caller checked the length)."""
        for store, sub, start, end in self.sinks:
            store[sub] = data[start:end]
