"""`Sensor`: what the simulator runner drives (`simulator.sensors` has the sensors).

A module of its own because the sensors are compiled by mypyc (setup.py), which makes a Protocol a plain
class: ``isinstance(x, Sensor)`` needs it as Python defines it. The sensors match it by shape (they do not
name it as a base class, which a compiled class could not have).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol, runtime_checkable

if TYPE_CHECKING:
    from simulator.sensors import Emission, ShipState


@runtime_checkable
class Sensor(Protocol):
    """What the simulator runner drives: ask `next_time`, build the ship state at that time, call `sample`."""

    source: str

    def next_time(self) -> float:
        """Sim time of the next sample."""
        ...

    def sample(self, state: ShipState) -> list[Emission]:
        """Sample ``state`` (taken at `next_time`), advance `next_time` past ``state.t`` and return the
        emissions in wire order (sort stably by ``t_emit`` to merge streams), with the sample-side faults
        applied; the wire-side ones are `FaultSchedule.apply_to_emissions`'s. A state more than 1 µs before
        `next_time` is not a sample time: nothing is returned and nothing advances."""
        ...
