"""Online consequence analysis: would the vessel stay in position if its worst-case failure happened now?

IMO's guidelines for DP vessels ask this of a DP class 2 or 3 control system (MSC/Circ.645 §3.4.2.4,
carried into MSC.1/Circ.1580): a function that continuously verifies that the thrusters left in operation
after the worst-case failure can still give the resultant force and moment needed before it, with an
alarm when that failure would lose the position for want of thrust in the prevailing conditions.

Pure numerics (DESIGN.md rule 2): the thrust demanded, in; the verdict, out; time only through
``t``.

**The load.** What the thrusters must hold is what is required of them now, without its fast part: τ̄,
the controller's demanded τ = [X, Y, N] (body frame; the allocated τ falls short of it while the
allocation saturates, and the guidelines ask for the force *required*) through a first-order low-pass of
time constant T (``filter_s``), in earth-fixed axes (the force turned by the heading ψ, so that a
heading change turns the load with the vessel at once) and tested in body axes,
exactly discretised for each step::

    τ̄ ← τ̄ + (1 − e^(−dt/T)) (τ − τ̄)

A DP vessel's mean environmental load moves over minutes; gusts and the controller's answer to the
slow drift move τ over tens of seconds. T of 30 s keeps the verdict on the mean load, as the guidelines'
"prevailing environmental conditions" ask, rather than on every gust.

**The test.** For each failure case g (a set of thrusters lost together: by default each thruster alone;
``failure_groups`` for a switchboard, an engine room or a fuel system that takes several with it, and then
each thruster in no group alone, `failure_cases`) and the
thrusters in service now, k_g = the largest k with k τ̄ within what the rest can give
(`gateway.control.capability.attainable_scale`). k_g ≥ 1: the load is held after that failure; the
utilisation 1/k_g is the share of the remaining capacity it takes (over 100 %: position lost). The worst
case is the g of least k_g. An alarm is raised when the worst case's utilisation passes 100 %, and
cleared when it falls below ``clear_utilisation`` (95 %): a load at the limit does not make the alarm
flap.

**When.** Each evaluation solves one small linear programme per failure case; the load changes slowly,
so it is redone when τ̄ has moved by more than ``retest_fraction`` (2 %) of the thrusters' capacity in
any degree of freedom since the last one, when a thruster has left or rejoined the allocation, and at
least every ``max_period_s`` (60 s) — never more often than every ``min_period_s`` (1 s).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gateway.control.capability import CapabilityLP
from observers.vessel import Thruster

Array = NDArray[np.float64]

Attainable = Callable[[Sequence[Thruster], Array, Collection[int]], float]
"""(thrusters, τ, failed ids) → the largest k with k τ attainable (`capability.attainable_scale`)."""


def failure_cases(ids: Sequence[int], groups: Sequence[Sequence[int]] = ()) -> list[tuple[int, ...]]:
    """The failure cases of a layout of thrusters ``ids``: each group of ``groups`` (thrusters lost
    together), then each thruster in no group alone; no groups: each thruster alone. A thruster's own
    failure (its drive trips) is a single failure whatever it is fed from: one in a group is covered by the
    group's loss, which takes it and more (the thrusters left can give no more for it), but one in no
    group would otherwise never be tested. Groups keep their order; ids in layout order."""
    cases = [tuple(g) for g in groups]
    grouped = {i for g in cases for i in g}
    return cases + [(i,) for i in ids if i not in grouped]


class CachedCapability:
    """`capability.attainable_scale` with one `CapabilityLP` kept per set of failed thrusters: the failure
    cases come back at every evaluation, and building an LP's constraints costs as much as solving it."""

    def __init__(self) -> None:
        self._lps: dict[frozenset[int], CapabilityLP] = {}

    def __call__(self, thrusters: Sequence[Thruster], tau: Array, failed: Collection[int]) -> float:
        key = frozenset(failed)
        lp = self._lps.get(key)
        if lp is None:
            lp = self._lps[key] = CapabilityLP(thrusters, failed=key)
        return lp.scale(tau)


@dataclass(frozen=True)
class FailureCase:
    """The verdict for one failure case: the thrusters lost, and the utilisation of the rest by the
    present load (1/k; inf when the rest cannot push that way at all)."""

    lost: tuple[int, ...]
    utilisation: float

    @property
    def holds(self) -> bool:
        return self.utilisation <= 1.0


@dataclass(frozen=True)
class Verdict:
    """One evaluation: the load τ̄ (body frame [X, Y, N]), the utilisation with every thruster in service
    now (``intact``), each failure case, and the worst of them (None: no case to test, every thruster of
    every case already out)."""

    t: float
    load: tuple[float, float, float]
    intact: float
    cases: tuple[FailureCase, ...]

    @property
    def worst(self) -> FailureCase | None:
        return max(self.cases, key=lambda c: c.utilisation) if self.cases else None


MIN_SCALE = 1e-6
"""A k* below this is none: the LP's round-off, not a load the rest could hold a millionth of."""


def _utilisation(k: float) -> float:
    return 0.0 if math.isinf(k) else (math.inf if k < MIN_SCALE else 1.0 / k)


class ConsequenceAnalysis:
    """The online consequence analysis of a thruster layout (module docstring)."""

    def __init__(
        self,
        thrusters: Sequence[Thruster],
        attainable: Attainable | None = None,
        *,
        failure_groups: Sequence[Sequence[int]] = (),
        filter_s: float = 30.0,
        clear_utilisation: float = 0.95,
        retest_fraction: float = 0.02,
        min_period_s: float = 1.0,
        max_period_s: float = 60.0,
    ) -> None:
        if not (math.isfinite(filter_s) and filter_s > 0):
            raise ValueError(f"consequence analysis: filter_s must be > 0 s, got {filter_s!r}")
        if not 0.0 < clear_utilisation < 1.0:
            raise ValueError(
                f"consequence analysis: clear_utilisation must be in (0, 1), got {clear_utilisation!r}"
            )
        self.thrusters = tuple(thrusters)
        ids = self._ids = frozenset(t.id for t in self.thrusters)
        groups = failure_cases([t.id for t in self.thrusters], failure_groups)
        unknown = sorted({i for g in groups for i in g} - ids)
        if unknown:
            raise ValueError(
                f"consequence analysis: failure groups name thrusters {unknown}, not in the layout"
            )
        self.groups = tuple(groups)
        self.attainable: Attainable = CachedCapability() if attainable is None else attainable
        self.filter_s = float(filter_s)
        self.clear_utilisation = float(clear_utilisation)
        self.min_period_s = float(min_period_s)
        self.max_period_s = float(max_period_s)
        # what "2 % of capacity" is per DOF: the sum of the thrusters' largest thrusts (X, Y) and that
        # times the largest lever arm (N)
        cap = sum(t.max_thrust_n for t in self.thrusters)
        arm = max((math.hypot(t.x_m, t.y_m) for t in self.thrusters), default=1.0)
        self._retest = (retest_fraction * cap, retest_fraction * cap, retest_fraction * cap * arm)
        self._mean = [0.0, 0.0, 0.0]  # τ̄ in earth-fixed axes [X_n, Y_e, N]
        self._psi, self._cos, self._sin = 0.0, 1.0, 0.0
        self._t: float | None = None
        self._dt = math.nan
        self._alpha = 0.0
        self._tested_at: float | None = None
        self._attempted_at: float | None = None  # (= _tested_at unless the last evaluation raised)
        self.failed = False
        """Whether the last evaluation raised (a solver's failure): retried every ``min_period_s``, not at
        every control step; `alarm_text` says "not evaluated" meanwhile (`record_failure`)."""
        self._failure_text: str | None = None
        self._tested_load = [0.0, 0.0, 0.0]
        self._tested_out: frozenset[int] = frozenset()
        self.verdict: Verdict | None = None
        self.alarm = False
        """Whether the alarm is up: the worst case's utilisation passed 100 % and has not yet fallen below
        ``clear_utilisation``."""
        self._alarm_text: str | None = None  # (worded once per evaluation, asked at every control step)

    def reset(self) -> None:
        """Forget the load (a restart, or the thrusters handed to someone else)."""
        self._mean = [0.0, 0.0, 0.0]
        self._t = self._tested_at = self._attempted_at = None
        self.failed = False
        self.verdict = None
        self.alarm = False
        self._alarm_text = None

    def update(self, t: float, tau: ArrayLike, out: Collection[int] = (), psi: float = 0.0) -> Verdict | None:
        """One control step at time t (s) with the demanded τ (body frame) at heading ψ (rad); ``out``: the
        ids of thrusters not in service now (out of DP). Returns a new verdict when one was evaluated, else
        None. The mean is kept in earth-fixed axes (X, Y turned by ψ; N as it is), so through a heading
        change the load turns with the vessel at once instead of lagging by the filter's time."""
        # (on plain floats: this runs at every control step, the evaluation only now and then)
        x, y, n = np.asarray(tau, dtype=float).tolist()
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(n) and math.isfinite(t)):
            return None
        if math.isfinite(psi) and psi != self._psi:
            self._psi, self._cos, self._sin = psi, math.cos(psi), math.sin(psi)
        c, s = self._cos, self._sin
        xe, ye = c * x - s * y, s * x + c * y
        mean = self._mean
        if self._t is not None and t < self._t:
            # time went back (a restarted simulation clock): the mean starts again from τ and is tested
            # at once, not after the clock has caught up with the last test
            self._t = self._tested_at = self._attempted_at = None
        if self._t is None:
            mean[:] = (xe, ye, n)
        else:
            dt = t - self._t
            if dt > 0:
                if dt != self._dt:
                    self._dt, self._alpha = dt, 1.0 - math.exp(-dt / self.filter_s)
                a = self._alpha
                mean[0] += a * (xe - mean[0])
                mean[1] += a * (ye - mean[1])
                mean[2] += a * (n - mean[2])
        self._t = t
        if self._attempted_at is not None and t - self._attempted_at < self.min_period_s:
            return None
        out = frozenset(out)
        if not self._due(t, out):
            return None
        return self.evaluate(t, out)

    @property
    def load(self) -> list[float]:
        """τ̄ in body axes at the last heading, [X, Y, N] (N, N, N·m)."""
        c, s = self._cos, self._sin
        xe, ye, n = self._mean
        return [c * xe + s * ye, -s * xe + c * ye, n]

    def _due(self, t: float, out: frozenset[int]) -> bool:
        if self._tested_at is None or self.failed:
            return True
        if t - self._tested_at >= self.max_period_s or out != self._tested_out:
            return True
        load, was, step = self.load, self._tested_load, self._retest  # (body axes: what the LP sees)
        return any(abs(load[j] - was[j]) > step[j] for j in range(3))

    def evaluate(self, t: float, out: frozenset[int] = frozenset()) -> Verdict:
        """Test every failure case against the present load now (`update` decides when on its own)."""
        self._attempted_at, self.failed = t, True  # (until it returns: a raise is retried a period on)
        load = np.array(self.load)
        intact = _utilisation(self.attainable(self.thrusters, load, out))
        cases = []
        for g in self.groups:
            lost = frozenset(g) - out  # (a thruster already out cannot be lost again)
            if not lost:
                continue  # nothing left to lose: no case
            # (a case that takes every thruster left, the last one in service or a group that feeds them
            # all, is the worst of all: k = 0 for any load but none)
            k = self.attainable(self.thrusters, load, out | lost)
            cases.append(FailureCase(tuple(sorted(lost)), _utilisation(k)))
        verdict = Verdict(t, (float(load[0]), float(load[1]), float(load[2])), intact, tuple(cases))
        worst = verdict.worst
        if worst is None:
            self.alarm = False
        elif worst.utilisation > 1.0:
            self.alarm = True
        elif worst.utilisation < self.clear_utilisation:
            self.alarm = False
        self.verdict = verdict
        self._tested_at, self._tested_load, self._tested_out = t, self.load, out
        self._alarm_text = self._word(worst, out) if self.alarm and worst is not None else None
        self.failed = False
        return verdict

    def alarm_text(self) -> str | None:
        """The alarm's words while it is up, else None; while the last evaluation had raised, that it was
        not evaluated and why (`record_failure`)."""
        return self._failure_text if self.failed else self._alarm_text

    def record_failure(self, exc: BaseException) -> None:
        """An evaluation (`update`) raised ``exc``: the caller, who must go on commanding the thrusters,
        hands it here; `alarm_text` says so until an evaluation succeeds, retried every ``min_period_s``."""
        self.failed = True
        self._failure_text = f"consequence analysis: not evaluated ({type(exc).__name__}: {exc})"

    def _word(self, worst: FailureCase, out: frozenset[int]) -> str:
        """The alarm's words for the worst case, the thrusters in ``out`` already out of service."""
        lost = ", ".join(str(i) for i in worst.lost)
        which = f"thruster {lost}" if len(worst.lost) == 1 else f"thrusters {lost}"
        if out | set(worst.lost) >= self._ids:
            return (
                f"consequence analysis: after losing {which} no thruster would be left to hold the position"
            )
        if math.isinf(worst.utilisation):
            return (
                f"consequence analysis: after losing {which} the rest could not push against the present load"
            )
        # One wording above and below 100 % (the alarm is held up down to clear_utilisation): the logs of
        # alarms raised and cleared know an alarm by its text with the numbers masked
        # (`gateway.foxglove_channels.alarm_key`), so a verdict that said "position would be lost" above
        # 100 % and something else below would be logged as one alarm cleared and another raised at every
        # crossing of 100 % — the chatter the hysteresis is there to prevent.
        return (
            f"consequence analysis: after losing {which} the rest would need {100 * worst.utilisation:.0f} % "
            f"of their thrust for the present load (over 100 %: position lost; the alarm clears below "
            f"{100 * self.clear_utilisation:.0f} %)"
        )
