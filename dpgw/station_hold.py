"""The station a simulated run keeps, and the joystick operator who holds it before DP is engaged.

Shared by `dpgw demo`, `dpgw sim` and the in-process closed loop of the studies, so that all three hold the
same station the same way.
"""

from __future__ import annotations

import math
from typing import Any

HOLD_PERIOD_S = 120.0
"""Natural period of the joystick operator's slow correction of the drift off station while DP is not yet
engaged (`Simulation.held_tau`), for a 76.2 m vessel, Froude-scaled with the vessel's length
(× √(L/76.2)): slow beside the waves (the correction works on the true LF motion) and within the hold."""


def froude_scale(scenario: Any) -> float:
    """Times set for the controller's reference vessel (76.2 m: its defaults are set for it) are this many
    times longer on the scenario's: √(L/76.2), as the controller scales its own."""
    from gateway.control.controller import REFERENCE_LENGTH_M

    return math.sqrt(scenario.vessel.length_m / REFERENCE_LENGTH_M)


def hold_setpoint(scenario: Any) -> dict[str, float]:
    """The station kept in dp: the scenario's start position and heading (``eta0``)."""
    north, east, psi = scenario.eta0
    return {"north_m": float(north), "east_m": float(east), "heading_deg": math.degrees(psi)}
