"""One simulated CiA 402 wire drive: a python-canopen ``LocalNode`` with the NMT slave, SDO
checks, PDO rules, heartbeat consumer, power state machine and motor model on top.

All entry points are called with the peer's lock held (see :mod:`cia402_peer`); values live
in the node's ``data_store``, so what SDO reads is what PDOs carry.
"""

from __future__ import annotations

import struct
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from canopen import LocalNode
from canopen import objectdictionary as cod
from canopen.sdo import SdoAbortedError, SdoServer
from canopen.sdo.constants import EXPEDITED, SDO_STRUCT

from drive_model import MODE_CST, POWERED, PowerMachine, PowerState, WireMotor, WireParams
from pdo_channels import PdoChannel, check_write, classify, find_variable

INITIALISING, STOPPED, OPERATIONAL, PRE_OPERATIONAL = 0x00, 0x04, 0x05, 0x7F
NMT_NAMES = {INITIALISING: "initialising", STOPPED: "stopped", OPERATIONAL: "operational",
             PRE_OPERATIONAL: "pre-operational"}
ABORT_READ_ONLY = 0x06010002
ABORT_NO_SUBINDEX = 0x06090011
ABORT_BAD_LENGTH = 0x06070010
ABORT_INCOMPATIBLE = 0x06040043
ABORT_INVALID_VALUE = 0x06090030
ABORT_TOO_HIGH = 0x06090031
ABORT_TOO_LOW = 0x06090032
EMCY_HEARTBEAT = 0x8130
INTEGER_TYPES = cod.INTEGER_TYPES

#: (store dict of an index, subindex, struct) of one numeric object.
Ref = tuple[dict[int, bytes], int, struct.Struct]


class PeerLink(Protocol):
    """What a node needs of the peer that hosts it."""

    lock: threading.RLock
    params: WireParams
    boot_delay_s: float

    def send(self, cob_id: int, data: bytes) -> None:
        """Send one frame."""

    def event(self, fmt: str, *args: object) -> None:
        """Queue a log line (written by the housekeeping thread)."""

    def watch_host(self, host_id: int) -> None:
        """Deliver the heartbeats of `host_id` to the nodes."""

    def routes_changed(self) -> None:
        """Re-subscribe the RPDO COB-IDs after a PDO (re)configuration."""


@dataclass
class HeartbeatConsumer:
    """One 0x1016 entry: a monitored node and how long it may stay silent."""

    host: int
    timeout_s: float
    last_heard: float | None = None


def _int_bytes(value: int, bits: int) -> bytes:
    return (int(value) & ((1 << bits) - 1)).to_bytes(bits // 8, "little")


def _encoder(var: cod.ODVariable, wrap: bool) -> Callable[[int], bytes]:
    """int -> the object's little-endian bytes, wrapped (encoder counts) or saturated."""
    bits = len(var)
    mask, n = (1 << bits) - 1, bits // 8
    if wrap:
        return lambda v: (v & mask).to_bytes(n, "little")
    signed = var.data_type in cod.SIGNED_TYPES
    lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, mask)
    return lambda v: ((lo if v < lo else hi if v > hi else v) & mask).to_bytes(n, "little")


class _SdoServer(SdoServer):
    """python-canopen's SDO server, logging the aborts it sends and checking a segmented
    download's object when the transfer starts (not only after the last segment)."""

    def abort(self, abort_code: int = 0x08000000) -> None:
        self._node.peer.event("node %d: SDO abort 0x%04X:%02X code 0x%08X", self._node.id,
                              self._index or 0, self._subindex or 0, abort_code)
        super().abort(abort_code)

    def init_download(self, request: bytes) -> None:
        command, index, subindex = SDO_STRUCT.unpack_from(request)
        if not command & EXPEDITED:
            self._index, self._subindex = index, subindex
            if not self._node._find_object(index, subindex).writable:
                raise SdoAbortedError(ABORT_READ_ONLY)
        super().init_download(request)


class DriveNode(LocalNode):
    """A simulated CiA 402 wire drive on the bus."""

    def __init__(self, node_id: int, od: cod.ObjectDictionary, peer: PeerLink,
                 initial_position: int = 0) -> None:
        super().__init__(node_id, od)
        self.sdo = _SdoServer(0x600 + node_id, 0x580 + node_id, self)
        self.peer = peer
        self._heartbeat_cob = 0x700 + node_id
        self.nmt_state = INITIALISING
        self.booted = False
        self.boot_due: float | None = None
        self.power = PowerMachine()
        self.motor = WireMotor(peer.params, initial_position)
        self.rpdos = [PdoChannel(False, n) for n in range(512) if 0x1400 + n in od]
        self.tpdos = [PdoChannel(True, n) for n in range(512) if 0x1800 + n in od]
        self.consumers: list[HeartbeatConsumer] = []
        self._live_tpdos: list[PdoChannel] = []
        self._sync_rpdos: list[PdoChannel] = []
        self._outputs: list[tuple[dict[int, bytes], int, Callable[[int], bytes],
                                  Callable[[], int]]] = []
        self._cw: Ref | None = None
        self._target: Ref | None = None
        self._mode: Ref | None = None
        self._last_sync: float | None = None
        self._seed_store()
        self._bind()

    # ----- wiring -------------------------------------------------------------------------

    def attach(self) -> None:
        """Take over SDO requests from python-canopen's subscription (NMT is the peer's)."""
        self.network.unsubscribe(self.sdo.rx_cobid, self.sdo.on_request)
        self.network.unsubscribe(0, self.nmt.on_command)
        self.network.subscribe(self.sdo.rx_cobid, self._on_sdo_request)

    def schedule_boot(self, at: float) -> None:
        """Send the boot-up message at monotonic time `at` (the housekeeping does)."""
        self.boot_due = at

    def _seed_store(self) -> None:
        """Give every numeric object a stored value: ParameterValue, else DefaultValue, else 0."""
        for obj in self.object_dictionary.values():
            members = [obj] if isinstance(obj, cod.ODVariable) else obj.subindices.values()
            for var in members:
                store = self.data_store.setdefault(var.index, {})
                if var.subindex in store or var.data_type not in cod.NUMBER_TYPES:
                    continue
                value = var.value if var.value is not None else var.default
                try:
                    if var.data_type in INTEGER_TYPES:
                        store[var.subindex] = _int_bytes(int(value or 0), len(var))
                    else:
                        store[var.subindex] = var.encode_raw(float(value or 0.0))
                except (TypeError, ValueError, struct.error):
                    store[var.subindex] = bytes(len(var) // 8)

    def _ref(self, index: int, sub: int) -> Ref | None:
        var = find_variable(self.object_dictionary, index, sub)
        if var is None or var.data_type not in var.STRUCT_TYPES:
            return None
        return self.data_store.setdefault(index, {}), sub, var.STRUCT_TYPES[var.data_type]

    def _bind(self) -> None:
        """Rebuild everything derived from the OD values: refs, PDO layouts, consumers."""
        self._cw, self._target = self._ref(0x6040, 0), self._ref(0x6071, 0)
        self._mode = self._ref(0x6060, 0)
        m = self.motor
        wanted = [(0x6064, 0, True, m.position_counts),
                  (0x606C, 0, False, m.velocity_counts_per_s),
                  (0x6077, 0, False, m.torque_permille),
                  (0x6041, 0, False, lambda: self.power.state.statusword),
                  (0x603F, 0, False, lambda: self.power.error_code),
                  (0x6401, 1, False, m.tension_mn), (0x3160, 1, False, m.tension_mn)]
        self._outputs = []
        for index, sub, wrap, getter in wanted:
            var = find_variable(self.object_dictionary, index, sub)
            if var is not None and var.data_type in INTEGER_TYPES:
                store = self.data_store.setdefault(index, {})
                self._outputs.append((store, sub, _encoder(var, wrap), getter))
        for ch in self.rpdos + self.tpdos:
            ch.load(self)
        self._refresh_channels()
        self._load_consumers()
        self._publish()

    def _refresh_channels(self) -> None:
        self._live_tpdos = [ch for ch in self.tpdos if ch.valid]
        self._sync_rpdos = [ch for ch in self.rpdos if ch.valid and ch.synchronous]

    # ----- object access ------------------------------------------------------------------

    def read_int(self, index: int, subindex: int) -> int | None:
        """Current value of a numeric object, None when the OD lacks it."""
        var = find_variable(self.object_dictionary, index, subindex)
        if var is None:
            return None
        raw = self.data_store.get(index, {}).get(subindex)
        if raw is None:
            raw = self.get_data(index, subindex)
        return int(var.decode_raw(raw))

    def _write_int(self, index: int, subindex: int, value: int) -> None:
        var = find_variable(self.object_dictionary, index, subindex)
        if var is not None and var.data_type in INTEGER_TYPES:
            self.data_store.setdefault(index, {})[subindex] = _int_bytes(value, len(var))

    @staticmethod
    def _get(ref: Ref | None) -> int:
        if ref is None:
            return 0
        store, sub, st = ref
        return st.unpack(store[sub])[0]

    def _find_object(self, index: int, subindex: int) -> cod.ODVariable:
        # python-canopen lets a plain VAR answer on any sub-index, and an ARRAY on every
        # sub-index 1..255 (made up from sub 1): only the declared ones exist.
        if find_variable(self.object_dictionary, index, subindex) is None \
                and index in self.object_dictionary:
            raise SdoAbortedError(ABORT_NO_SUBINDEX)
        return super()._find_object(index, subindex)

    def set_data(self, index: int, subindex: int, data: bytes,
                 check_writable: bool = False) -> None:
        """Store a written value, refusing what CiA 301/402 refuse, then react to it."""
        obj = self._find_object(index, subindex)
        if check_writable:
            if not obj.writable:
                raise SdoAbortedError(ABORT_READ_ONLY)
            if obj.data_type in cod.NUMBER_TYPES and 8 * len(data) != len(obj):
                raise SdoAbortedError(ABORT_BAD_LENGTH)
            self._validate(index, subindex, obj, bytes(data))
        super().set_data(index, subindex, data, check_writable)
        self._after_write(index, subindex)

    def _validate(self, index: int, subindex: int, var: cod.ODVariable, data: bytes) -> None:
        if var.data_type not in INTEGER_TYPES:
            return
        value = int(var.decode_raw(data))
        check_write(self, index, subindex, value)
        if index == 0x6060:
            self._check_mode(value)
        elif index == 0x1016 and subindex > 0:
            self._check_consumer(subindex, value)
        if var.max is not None and value > var.max:
            raise SdoAbortedError(ABORT_TOO_HIGH)
        if var.min is not None and value < var.min:
            raise SdoAbortedError(ABORT_TOO_LOW)

    def _check_mode(self, mode: int) -> None:
        supported = self.read_int(0x6502, 0)
        if supported is not None and mode > 0 and (mode > 16 or not supported >> (mode - 1) & 1):
            raise SdoAbortedError(ABORT_INVALID_VALUE)

    def _check_consumer(self, subindex: int, value: int) -> None:
        host = (value >> 16) & 0x7F
        if not host or not value & 0xFFFF:
            return
        for sub in getattr(self.object_dictionary.get(0x1016), "subindices", {}):
            other = self.read_int(0x1016, sub) if sub not in (0, subindex) else None
            if other and (other >> 16) & 0x7F == host and other & 0xFFFF:
                raise SdoAbortedError(ABORT_INCOMPATIBLE)

    def _after_write(self, index: int, subindex: int) -> None:
        if index == 0x6040:
            self._eval_controlword()
        elif index == 0x6060:
            self._write_int(0x6061, 0, self.read_int(0x6060, 0) or 0)
        elif index == 0x1016:
            self._load_consumers()
        kind = classify(index)
        if kind is not None:
            tpdo, mapping, number = kind
            for ch in self.tpdos if tpdo else self.rpdos:
                if ch.number == number:
                    ch.load(self)
            self._refresh_channels()
            if not tpdo:
                self.peer.routes_changed()

    # ----- NMT ----------------------------------------------------------------------------

    def _on_sdo_request(self, can_id: int, data: bytearray, timestamp: float) -> None:
        if self.nmt_state not in (PRE_OPERATIONAL, OPERATIONAL):
            return  # no SDO while initialising or stopped
        with self.peer.lock:
            self.sdo.on_request(can_id, data, timestamp)
            if self.nmt_state == OPERATIONAL:
                self._poll_event_tpdos(time.monotonic())

    def _set_nmt(self, state: int) -> None:
        if state != self.nmt_state:
            self.peer.event("node %d: NMT %s -> %s", self.id, NMT_NAMES[self.nmt_state],
                            NMT_NAMES[state])
        self.nmt_state = state
        self.nmt._state = state  # the heartbeat producer's payload
        self.nmt.update_heartbeat()

    def on_nmt(self, command: int, now: float) -> None:
        """Act on an NMT command addressed to this node."""
        self.peer.event("node %d: NMT command 0x%02X", self.id, command)
        if command in (0x81, 0x82):
            self._reset(application=command == 0x81, now=now)
        elif self.nmt_state == INITIALISING:
            return
        elif command == 0x01:
            if self.nmt_state != OPERATIONAL:
                self._last_sync = None
                for ch in self._live_tpdos:
                    ch.last_data = None  # event-driven TPDOs go out on entry
            self._set_nmt(OPERATIONAL)
        elif command in (0x02, 0x80):
            for ch in self.rpdos:
                ch.pending = None
            self._set_nmt(STOPPED if command == 0x02 else PRE_OPERATIONAL)

    def _reset(self, application: bool, now: float) -> None:
        """NMT reset node/communication: stored parameters back to the EDS/DCF values."""
        self.nmt.stop_heartbeat()
        self._set_nmt(INITIALISING)
        top = 0xA000 if application else 0x2000
        for index in [i for i in self.data_store if 0x1000 <= i < top]:
            del self.data_store[index]
        self._seed_store()
        self.power.reset()
        self._bind()
        if application:
            self._write_int(0x6061, 0, self.read_int(0x6060, 0) or 0)
        self.peer.routes_changed()
        self.boot_due = now + (self.peer.boot_delay_s if application else 0.0)
        if not application:
            self._boot()

    def _boot(self) -> None:
        self.boot_due = None
        self.peer.send(self._heartbeat_cob, b"\x00")
        self.booted = True
        self.peer.event("node %d: boot-up", self.id)
        self._set_nmt(PRE_OPERATIONAL)
        producer_ms = self.read_int(0x1017, 0) or 0
        if producer_ms:
            self.nmt.start_heartbeat(producer_ms)

    # ----- heartbeat consumer -------------------------------------------------------------

    def _load_consumers(self) -> None:
        self.consumers = []
        obj = self.object_dictionary.get(0x1016)
        if obj is None or isinstance(obj, cod.ODVariable):
            return
        for sub in sorted(obj.subindices):
            value = self.read_int(0x1016, sub) if sub else 0
            host, ms = ((value or 0) >> 16) & 0x7F, (value or 0) & 0xFFFF
            if host and ms:
                self.consumers.append(HeartbeatConsumer(host, ms / 1000.0))
                self.peer.watch_host(host)

    def on_host_heartbeat(self, host: int, now: float) -> None:
        """A heartbeat of `host` arrived: arm or re-arm its consumers."""
        for c in self.consumers:
            if c.host == host:
                c.last_heard = now

    def _check_consumers(self, now: float) -> None:
        for c in self.consumers:
            if c.last_heard is not None and now - c.last_heard > c.timeout_s:
                c.last_heard = None  # re-armed by the next heartbeat
                self._comm_loss(c.host)

    def _comm_loss(self, host: int) -> None:
        """Apply the communication-loss reaction (0x6007; 2 when the OD lacks it)."""
        option = self.read_int(0x6007, 0)
        option = 2 if option is None else option
        self.peer.event("node %d: heartbeat of node %d lost, reaction %d", self.id, host,
                        option)
        self._write_int(0x6071, 0, 0)
        for ch in self.rpdos:
            ch.pending = None
        prev = self.power.state
        changed = (self.power.fault(EMCY_HEARTBEAT) if option == 1
                   else self.power.quick_stop() if option == 3
                   else False if option == 0 else self.power.disable_voltage())
        if changed:
            self._power_changed(prev)

    # ----- CiA 402 ------------------------------------------------------------------------

    def _eval_controlword(self) -> None:
        prev = self.power.state
        if self.power.command(self._get(self._cw)):
            self._power_changed(prev)

    def _power_changed(self, prev: PowerState) -> None:
        state = self.power.state
        self.peer.event("node %d: %s -> %s", self.id, prev.label, state.label)
        code = self.power.error_code
        register = (0x11 if code & 0xFF00 == 0x8100 else 0x01) if state is PowerState.FAULT else 0
        self._write_int(0x1001, 0, register)
        if self.nmt_state in (PRE_OPERATIONAL, OPERATIONAL):
            if state is PowerState.FAULT:
                self.emcy.send(code, register)
            elif prev is PowerState.FAULT:
                self.emcy.reset()
        self._publish()

    def _torque_nm(self) -> float:
        if (self.power.state is not PowerState.OPERATION_ENABLED or self._target is None
                or self._get(self._mode) != MODE_CST):
            return 0.0
        return self._get(self._target) * self.peer.params.rated_torque_nm / 1000.0

    def _publish(self) -> None:
        for store, sub, encode, getter in self._outputs:
            store[sub] = encode(getter())

    # ----- SYNC and PDOs ------------------------------------------------------------------

    def on_sync(self, now: float) -> None:
        """SYNC: apply RPDOs, step the power state machine and the motor, send TPDOs."""
        dt = 0.0 if self._last_sync is None else now - self._last_sync
        self._last_sync = now
        for ch in self._sync_rpdos:
            if ch.pending is not None:
                ch.unpack(ch.pending)
                ch.pending = None
        self._eval_controlword()
        self.motor.step(self._torque_nm(), dt, self.power.state in POWERED)
        self._publish()
        send = self.peer.send
        for ch in self._live_tpdos:
            tt = ch.trans_type
            if 1 <= tt <= 240:
                ch.sync_count += 1
                if ch.sync_count >= tt:
                    ch.sync_count = 0
                    data = ch.pack()
                    send(ch.cob_id, data)
                    ch.last_data, ch.last_sent = data, now
            elif tt == 0:
                data = ch.pack()
                if data != ch.last_data:
                    send(ch.cob_id, data)
                    ch.last_data, ch.last_sent = data, now
            else:
                self._event_tpdo(ch, now)

    def _event_tpdo(self, ch: PdoChannel, now: float) -> None:
        data = ch.pack()
        due = data != ch.last_data or (ch.event_s > 0 and now - ch.last_sent >= ch.event_s)
        if due and now - ch.last_sent >= ch.inhibit_s:
            self.peer.send(ch.cob_id, data)
            ch.last_data, ch.last_sent = data, now

    def on_rpdo(self, ch: PdoChannel, data: bytes | bytearray, now: float) -> None:
        """An RPDO frame: kept for the next SYNC, or applied now when event-driven."""
        if self.nmt_state != OPERATIONAL or len(data) < ch.length:
            return
        if ch.synchronous:
            ch.pending = bytes(data)
            return
        ch.unpack(bytes(data))
        self._eval_controlword()
        self._publish()

    # ----- housekeeping -------------------------------------------------------------------

    def poll(self, now: float) -> None:
        """Timers: the boot-up, the heartbeat consumers, event-driven TPDOs."""
        if self.boot_due is not None and now >= self.boot_due:
            self._boot()
        if self.nmt_state == INITIALISING:
            return
        self._check_consumers(now)
        if self.nmt_state == OPERATIONAL:
            self._poll_event_tpdos(now)

    def _poll_event_tpdos(self, now: float) -> None:
        for ch in self._live_tpdos:
            if ch.trans_type >= 254:
                self._event_tpdo(ch, now)

    def next_deadline(self) -> float:
        """When :meth:`poll` next has something to do (monotonic s; inf: nothing)."""
        times = [self.boot_due] if self.boot_due is not None else []
        times += [c.last_heard + c.timeout_s for c in self.consumers if c.last_heard is not None]
        if self.nmt_state == OPERATIONAL:
            for ch in self._live_tpdos:
                if ch.trans_type >= 254 and ch.event_s > 0:
                    times.append(ch.last_sent + ch.event_s)
        return min(times, default=float("inf"))
