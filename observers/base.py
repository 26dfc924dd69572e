"""What every dpgw observer shares: the estimate, the batch run, and the `Observer` protocol.

The gateway, replay and the benchmarks talk to observers only through these, so any observer registered
in `observers.factory` can stand in for any other. ``tests/test_observer_conformance.py`` checks every
registered observer against the protocol's promises, written out below.

Units everywhere: y = η = [N, E, ψ] (m, m, rad; local NED, ψ in [-π, π)), ν = [u, v, r] (m/s, m/s, rad/s,
body frame), τ and b = [X, Y, N] (N, N, N·m), t in seconds on the caller's clock.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from observers.settling import UNKNOWN_SETTLE_S

Array = NDArray[np.float64]

# Status of one sample, as kernels return it (small ints: numba code stores them in int8 arrays).
STATUS_INITIALIZING = 0
STATUS_OK = 1
STATUS_DEAD_RECKONING = 2
STATUS_NAMES = {
    STATUS_INITIALIZING: "initializing",
    STATUS_OK: "ok",
    STATUS_DEAD_RECKONING: "dead_reckoning",
}
"""Code → the ``status`` word of the estimate message (docs/interfaces.md)."""

# Shared constants handed to kernels and estimates; never written to (kept writeable: numba compiles a
# separate, slower-to-load signature for read-only arrays).
NAN3 = np.full(3, np.nan)
ZERO3 = np.zeros(3)


@dataclass(frozen=True)
class Estimate:
    """One estimate at time t: LF position/heading η̂, velocity ν̂, bias b̂ (earth-fixed), wave motion η̂_w,
    and the status word (`STATUS_NAMES`). All NaN while initialising."""

    t: float
    eta: Array
    nu: Array
    bias: Array
    eta_wf: Array
    status: str

    @property
    def initialized(self) -> bool:
        return self.status != STATUS_NAMES[STATUS_INITIALIZING]

    @classmethod
    def initializing(cls, t: float) -> Estimate:
        """The estimate before the first usable measurement: no numbers yet."""
        return cls(t, NAN3, NAN3, NAN3, NAN3, STATUS_NAMES[STATUS_INITIALIZING])


@dataclass(frozen=True)
class Run:
    """Result of `Observer.run` over n samples: what `step` gave after each sample, as arrays.

    t (n,); eta, nu, bias, eta_wf (n, 3), NaN while initialising; status (n,) codes (`STATUS_NAMES`);
    omega0 (n, 3): the wave frequency in use per DOF after each sample (rad/s). ``extras`` holds what one
    observer has beyond that, by name (each observer's docstring lists its keys), e.g. the MMAE's weights
    ``"weights"`` (n, N) or the gain-scheduled observer's ω0 estimates ``"updates"``.
    """

    t: Array
    eta: Array
    nu: Array
    bias: Array
    eta_wf: Array
    status: NDArray[np.int8]
    omega0: Array
    extras: Mapping[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @property
    def initialized(self) -> NDArray[np.bool_]:
        return np.asarray(self.status != STATUS_INITIALIZING)

    def estimate(self, k: int) -> Estimate:
        """Sample k as the `Estimate` that `step` returned for it."""
        return Estimate(
            float(self.t[k]),
            self.eta[k],
            self.nu[k],
            self.bias[k],
            self.eta_wf[k],
            STATUS_NAMES[int(self.status[k])],
        )


@runtime_checkable
class Observer(Protocol):
    """The face of every observer (in the manner of filterpy: the model stated up front in the class
    docstring; prediction and update kept apart as `predict` and `step`).

    Before the first complete measurement (or `initialize`) an observer is uninitialised: `step` returns
    `Estimate.initializing` and nothing advances. A sample at a time not after `t` (repeated or backward)
    is not used: the estimate is returned unchanged. `run` over samples gives exactly — bit for bit — what
    `step` gives sample by sample, and leaves the observer in the same state, so a record may be run in
    pieces. `omega0` and `extra` describe the observer after the last sample.
    """

    @property
    def initialized(self) -> bool:
        """Whether the observer has a state (from a measurement or `initialize`)."""
        ...

    @property
    def t(self) -> float:
        """Time (s) of the last sample used; 0 before initialisation."""
        ...

    @property
    def omega0(self) -> Array:
        """Wave frequency in use per DOF (3,), rad/s."""
        ...

    @property
    def settle_time_s(self) -> float:
        """Seconds after the observer's start (its first estimate, or the first after a `reset` or a
        restart) after which its estimate is taken as settled: `observers.settling.ENGAGE_TIME_CONSTANTS`
        time constants of its slowest error mode, each observer's figure from its own model and tuning
        (its docstring says how); `observers.settling.UNKNOWN_SETTLE_S` where nothing can be derived."""
        ...

    @property
    def max_gap_s(self) -> float:
        """The longest gap between two steps the observer integrates across (dead-reckoning through it);
        after a longer one it starts again from its next complete measurement, as at its first. ``inf``
        (the usual answer) for an observer that bridges any gap."""
        ...

    def initialize(
        self,
        t: float,
        eta: ArrayLike,
        nu: ArrayLike | None = None,
        bias: ArrayLike | None = None,
        eta_wf: ArrayLike | None = None,
    ) -> None:
        """Start at time t from an explicit state (a restart, or a test's wrong guess); omitted parts zero.
        Without it, the first complete measurement initialises the observer."""
        ...

    def predict(self, t: float, tau: ArrayLike | None = None) -> Estimate:
        """Advance to time t with no measurement (dead reckoning), τ held since the last sample."""
        ...

    def step(self, t: float, y: ArrayLike, tau: ArrayLike | None = None) -> Estimate:
        """Advance to time t with measurement y (NaN = missing DOF) and τ held since the last sample."""
        ...

    def run(self, t: ArrayLike, y: ArrayLike, tau: ArrayLike | None = None) -> Run:
        """`step` over every sample: t (n,), y (n, 3), τ (n, 3) or None for zero."""
        ...

    def reset(self) -> None:
        """Back to uninitialised, as constructed."""
        ...

    def extra(self) -> dict[str, Any]:
        """Observer-specific fields for the estimate message (JSON-able: numbers, lists, None)."""
        ...


# --- shared plumbing (not part of the protocol) -----------------------------------------------------------

CLOCK_T = 0  # every kernel's clock array starts with: the time of the last sample used ...
CLOCK_STARTED = 1  # ... and 1.0 once initialised


@dataclass(frozen=True)
class InitialState:
    """An explicit start (`Observer.initialize`): η (ψ not yet wrapped), and ν, b, η_w or None for zero."""

    eta: Array
    nu: Array | None = None
    bias: Array | None = None
    eta_wf: Array | None = None


def batch_inputs(t: ArrayLike, y: ArrayLike, tau: ArrayLike | None) -> tuple[Array, Array, Array]:
    """`Observer.run`'s arguments as contiguous floats: t (n,), y (n, 3), τ (n, 3) (zeros for None)."""
    t_arr = np.ascontiguousarray(t, dtype=float).ravel()
    n = t_arr.shape[0]
    Y = np.ascontiguousarray(y, dtype=float).reshape(n, 3)
    TAU = np.zeros((n, 3)) if tau is None else np.ascontiguousarray(tau, dtype=float).reshape(n, 3)
    return t_arr, Y, TAU


def step_inputs(y: ArrayLike, tau: ArrayLike | None) -> tuple[Array, Array]:
    """`Observer.step`'s y and τ as float arrays (τ zero for None)."""
    return np.asarray(y, dtype=float), ZERO3 if tau is None else np.asarray(tau, dtype=float)


class ObserverBase:
    """What dpgw's observers share beyond the protocol's promises: the clock their kernels keep (an array
    starting [t, started], `CLOCK_T`, `CLOCK_STARTED`), `t` and `initialized` read from it, `initialize`
    handing an `InitialState` to the observer's `_begin`, `predict` as a step without a measurement, no
    extras, and `from_params` for observers whose parameters are keyword arguments of the constructor.

    Only the plumbing lives here; the model, the kernels and what `_begin` does stay with each observer.
    """

    _clock: Array

    max_gap_s: float = math.inf
    """`Observer.max_gap_s`: any gap is bridged, unless the observer says otherwise."""

    new_samples_only: bool = False
    """Whether the observer wants each measurement once, when it is new (``True``), rather than the latest
    measurement of every DOF held and given again at every step (``False``, the default: continuous-time
    observers, whose injection would otherwise shrink with the step rate). A discrete-time Kalman-type
    observer counts every sample it is given as new information: a held fix given again at the step rate
    is the same measurement counted several times. For an observer that says ``True`` the gateway gives a
    DOF as NaN while its measurement is one already given (until the observer is initialised: then the
    held values, so that it can start from a complete sample)."""

    @classmethod
    def from_params(
        cls, vessel: Any, tuning: Any, params: dict[str, Any], *, allow_unchecked: bool = False
    ) -> Any:
        """The observer `observers.factory` builds by name (its params: constructor keywords)."""
        return cls(vessel, tuning, allow_unchecked=allow_unchecked, **params)  # type: ignore[call-arg]

    @property
    def initialized(self) -> bool:
        return bool(self._clock[CLOCK_STARTED])

    @property
    def t(self) -> float:
        return float(self._clock[CLOCK_T])

    def initialize(
        self, t: float, eta: ArrayLike, nu: ArrayLike | None = None, bias: ArrayLike | None = None,
        eta_wf: ArrayLike | None = None,
    ) -> None:  # fmt: skip
        """`Observer.initialize`: start at time t from an explicit state; omitted parts zero."""
        parts = [None if v is None else np.asarray(v, dtype=float) for v in (nu, bias, eta_wf)]
        self._begin(float(t), InitialState(np.asarray(eta, dtype=float), *parts))

    def _begin(self, t: float, start: InitialState) -> None:
        raise NotImplementedError

    def step(self, t: float, y: ArrayLike, tau: ArrayLike | None = None) -> Estimate:
        raise NotImplementedError

    def predict(self, t: float, tau: ArrayLike | None = None) -> Estimate:
        """Advance to time t with no measurement (dead reckoning), τ held since the last sample."""
        return self.step(t, NAN3, tau)

    def extra(self) -> dict[str, Any]:
        """Observer-specific fields for the estimate message (none unless the observer says)."""
        return {}

    @property
    def settle_time_s(self) -> float:
        """`Observer.settle_time_s`: here the conservative `UNKNOWN_SETTLE_S`, for an observer that derives
        no figure of its own (each of dpgw's observers does)."""
        return UNKNOWN_SETTLE_S

    def _set_clock(self, t: float) -> None:
        self._clock[CLOCK_T] = t
        self._clock[CLOCK_STARTED] = 1.0
