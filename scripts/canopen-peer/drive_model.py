"""The physics and the CiA 402 power state machine of one simulated wire drive.

Pure Python, no CANopen: :mod:`drive_node` feeds these from the object dictionary and
publishes their results back into it.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

#: Modes of operation (0x6060) value of cyclic synchronous torque mode.
MODE_CST = 10


class PowerState(enum.Enum):
    """CiA 402 power states, each with the statusword the drive reports in it."""

    SWITCH_ON_DISABLED = 0x0250
    READY_TO_SWITCH_ON = 0x0231
    SWITCHED_ON = 0x0233
    OPERATION_ENABLED = 0x0237
    QUICK_STOP_ACTIVE = 0x0217
    FAULT = 0x0218

    @property
    def statusword(self) -> int:
        """The statusword (0x6041) of this state."""
        return self.value

    @property
    def label(self) -> str:
        """Lower-case name for log lines."""
        return self.name.lower().replace("_", " ")


_S = PowerState
#: States in which the power stage is on (the shaft is free to turn).
POWERED = frozenset({_S.OPERATION_ENABLED, _S.QUICK_STOP_ACTIVE})


def _command_target(state: PowerState, cw: int) -> PowerState | None:
    """Where `cw` (a controlword without the fault-reset bit) takes `state`; None: stay."""
    if state is _S.FAULT:
        return None
    if cw & 0x02 == 0:  # disable voltage (transitions 7, 9, 10, 12)
        return _S.SWITCH_ON_DISABLED
    if cw & 0x06 == 0x02:  # quick stop (7, 10, 11)
        return _S.QUICK_STOP_ACTIVE if state is _S.OPERATION_ENABLED else (
            None if state is _S.QUICK_STOP_ACTIVE else _S.SWITCH_ON_DISABLED)
    if cw & 0x07 == 0x06:  # shutdown, bit 3 ignored (2, 6, 8)
        return None if state is _S.QUICK_STOP_ACTIVE else _S.READY_TO_SWITCH_ON
    if cw & 0x0F == 0x07:  # switch on / disable operation (3, 5)
        return _S.SWITCHED_ON if state in (_S.READY_TO_SWITCH_ON, _S.OPERATION_ENABLED) else None
    if cw & 0x0F == 0x0F:  # enable operation (4, 16; 3+4 from ready to switch on)
        return _S.OPERATION_ENABLED if state is not _S.SWITCH_ON_DISABLED else None
    return None


class PowerMachine:
    """The CiA 402 power state machine, driven by controlwords and faults."""

    def __init__(self) -> None:
        self.state = _S.SWITCH_ON_DISABLED
        self.error_code = 0
        self._fault_reset_bit = False

    def command(self, cw: int) -> bool:
        """Evaluate a controlword (0x6040); True when the state changed.

        Fault reset acts on a rising edge of bit 7; while bit 7 is set no other command is
        evaluated.
        """
        rising = bool(cw & 0x80) and not self._fault_reset_bit
        self._fault_reset_bit = bool(cw & 0x80)
        if cw & 0x80:
            if rising and self.state is _S.FAULT:
                self.state = _S.SWITCH_ON_DISABLED
                self.error_code = 0
                return True
            return False
        target = _command_target(self.state, cw)
        if target is None or target is self.state:
            return False
        self.state = target
        return True

    def fault(self, error_code: int) -> bool:
        """Latch a fault with `error_code`; True when the drive was not in fault already."""
        if self.state is _S.FAULT:
            return False
        self.state = _S.FAULT
        self.error_code = error_code
        return True

    def disable_voltage(self) -> bool:
        """Communication-loss reaction "disable voltage"; True when the state changed."""
        if self.state in (_S.FAULT, _S.SWITCH_ON_DISABLED):
            return False
        self.state = _S.SWITCH_ON_DISABLED
        return True

    def quick_stop(self) -> bool:
        """Communication-loss reaction "quick stop"; True when the state changed."""
        if self.state is _S.OPERATION_ENABLED:
            self.state = _S.QUICK_STOP_ACTIVE
            return True
        if self.state in (_S.READY_TO_SWITCH_ON, _S.SWITCHED_ON):
            self.state = _S.SWITCH_ON_DISABLED
            return True
        return False

    def reset(self) -> None:
        """After an NMT reset: switch on disabled, unless a fault is latched."""
        if self.state is not _S.FAULT:
            self.state = _S.SWITCH_ON_DISABLED


@dataclass(frozen=True)
class WireParams:
    """A motor winding a wire that ends in a spring to a fixed point, through a gear."""

    pulley_radius_m: float = 0.01
    gear_ratio: float = 25.0
    spring_n_per_m: float = 2000.0
    #: Wound-in length at which the spring is relaxed (negative: pre-tension at theta = 0).
    x0_m: float = -0.002
    tension_offset_n: float = 0.0
    inertia_kg_m2: float = 2e-6
    damping_nm_s_per_rad: float = 1e-5
    counts_per_rev: int = 2000
    rated_torque_nm: float = 0.1
    #: Integration substep. The wire's dynamics are slow (a natural frequency of ~2 Hz with the
    #: defaults): semi-implicit Euler is stable far beyond this, and a longer substep keeps a
    #: SYNC that arrives late (an emulated CPU) from costing more time than it had.
    max_substep_s: float = 2e-3
    #: Longest interval integrated at once (a SYNC after a long pause).
    max_step_s: float = 0.05


class WireMotor:
    """Motor-side dynamics J dw/dt = tau - T r / g - b w, T = max(0, k (x - x0)) + offset."""

    def __init__(self, p: WireParams, position_offset_counts: int = 0) -> None:
        self.p = p
        #: Encoder reading at theta = 0 (where the drive's position starts).
        self.position_offset_counts = position_offset_counts
        self.theta = 0.0
        self.omega = 0.0
        self.torque_nm = 0.0
        self._arm = p.pulley_radius_m / p.gear_ratio
        self._counts_per_rad = p.counts_per_rev / (2.0 * math.pi)

    def tension_n(self) -> float:
        """Wire tension, N."""
        stretch = self.theta * self._arm - self.p.x0_m
        return max(0.0, self.p.spring_n_per_m * stretch) + self.p.tension_offset_n

    def step(self, torque_nm: float, dt: float, powered: bool) -> None:
        """Integrate `dt` seconds with the motor torque `torque_nm`.

        Unpowered, a holding brake keeps the shaft still (so the wire keeps its pre-tension).
        """
        self.torque_nm = torque_nm if powered else 0.0
        if not powered:
            self.omega = 0.0
            return
        dt = min(max(dt, 0.0), self.p.max_step_s)
        n = max(1, math.ceil(dt / self.p.max_substep_s))
        h = dt / n
        p = self.p
        arm, k, x0, off = self._arm, p.spring_n_per_m, p.x0_m, p.tension_offset_n
        inv_j, b = 1.0 / p.inertia_kg_m2, p.damping_nm_s_per_rad
        theta, omega = self.theta, self.omega
        for _ in range(n):
            tension = k * (theta * arm - x0)
            tension = (tension if tension > 0.0 else 0.0) + off
            omega += (torque_nm - tension * arm - b * omega) * inv_j * h
            theta += omega * h
        self.theta, self.omega = theta, omega

    def position_counts(self) -> int:
        """Encoder position (0x6064), counts."""
        return self.position_offset_counts + round(self.theta * self._counts_per_rad)

    def velocity_counts_per_s(self) -> int:
        """Encoder velocity (0x606C), counts/s."""
        return round(self.omega * self._counts_per_rad)

    def torque_permille(self) -> int:
        """Applied torque (0x6077), per mille of the rated torque."""
        return round(self.torque_nm / self.p.rated_torque_nm * 1000.0)

    def tension_mn(self) -> int:
        """Wire tension as the analog input reports it, mN."""
        return round(self.tension_n() * 1000.0)
