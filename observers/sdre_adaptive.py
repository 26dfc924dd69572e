"""The SDRE observer with its wave frequency scheduled from the measurements: an adaptive ``sdre``.

Snijders, van der Woude & Westhuis (2005) design the observer for a known peak frequency ω0 of the waves;
the sea changes during an operation. Here ω0 follows the estimate of the wave-frequency estimator of
Torsetnes, Jouffroy & Fossen (2004) (`observers.wave_frequency`: the spectral peak of the measured motion
over a sliding window, a new estimate every ``update_period_s``, clipped to [ω_min, ω_max], assumption
A6). Each new estimate re-solves the Riccati equation for the new ω0 (`SdreObserver.set_omega0`: one
solution, turned with the heading; the state is kept, so the estimate does not jump).

What the papers do not give: Torsetnes et al.'s contraction budget bounds how fast the *passive*
observer's gains may move; the SDRE has no such result. Each frozen ω0 gives a Hurwitz A − KC at every
heading (tested), and the updates are rare (minutes apart) and small once the estimate has settled, so
the switching is slow next to the error dynamics (poles ~0.1-1 s⁻¹); a proof is not claimed.

``step`` and ``run`` give the same numbers: ``run`` lets the estimator stop at each sample where an
update falls due (`WaveFrequencyEstimator.add_until_updates`) and runs the compiled loop between them.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from observers.base import Estimate, Run, batch_inputs
from observers.sdre import SdreObserver
from observers.sdre_tuning import SdreTuning, SdreWeights
from observers.vessel import VesselModel
from observers.wave_frequency import WaveFrequencyConfig, WaveFrequencyEstimator


class AdaptiveSdreObserver(SdreObserver):
    """`SdreObserver` whose ω0 follows the wave-frequency estimator (module docstring).

    `Run.extras["updates"]`: the ω0 estimates taken during the run, ``(t, (ω0 per DOF))``; `Run.omega0` is
    the ω0 in use after each sample.
    """

    def __init__(
        self,
        vessel: VesselModel,
        tuning: SdreTuning | None = None,
        *,
        estimator: WaveFrequencyConfig | None = None,
        weights: SdreWeights | None = None,
        **kwargs: Any,
    ) -> None:
        self.estimator = WaveFrequencyEstimator(estimator or WaveFrequencyConfig.for_vessel(vessel))
        super().__init__(vessel, tuning, weights=weights, **kwargs)
        self._initial_tuning = self.tuning
        self._updates: list[tuple[float, tuple[float, float, float]]] = []

    def reset(self) -> None:
        """Uninitialised, ω0 back where it started, the estimator emptied."""
        super().reset()
        self.estimator.reset()
        initial = getattr(self, "_initial_tuning", None)
        if initial is not None and initial is not self.tuning:
            self.tuning = initial
            self.set_omega0(initial.omega0)
        self._updates = []

    def _schedule(self, t: float, estimate: np.ndarray) -> None:
        c = self.estimator.config
        target = np.clip(estimate, c.omega_min, c.omega_max)
        self._updates.append((t, (float(target[0]), float(target[1]), float(target[2]))))
        self.set_omega0(target)

    def step(self, t: float, y: ArrayLike, tau: ArrayLike | None = None) -> Estimate:
        """`SdreObserver.step`, after handing the sample to the estimator and re-solving if ω0 is due."""
        tf = float(t)
        y_arr = np.asarray(y, dtype=float)
        self.estimator.add(tf, y_arr)
        update = self.estimator.estimate(tf)
        if update is not None:
            self._schedule(tf, update)
        return super().step(tf, y_arr, tau)

    def run(self, t: ArrayLike, y: ArrayLike, tau: ArrayLike | None = None) -> Run:
        """`step` over every sample, with the same numbers (module docstring)."""
        t_arr, Y, TAU = batch_inputs(t, y, tau)
        first = len(self._updates)
        pieces: list[Run] = []
        start = 0
        for j in self.estimator.add_until_updates(t_arr, Y):
            update = self.estimator.estimate(float(t_arr[j]))
            if update is None:
                continue
            pieces.append(super().run(t_arr[start:j], Y[start:j], TAU[start:j]))
            start = j
            self._schedule(float(t_arr[j]), update)
        pieces.append(super().run(t_arr[start:], Y[start:], TAU[start:]))
        return Run(
            t_arr,
            np.concatenate([p.eta for p in pieces]),
            np.concatenate([p.nu for p in pieces]),
            np.concatenate([p.bias for p in pieces]),
            np.concatenate([p.eta_wf for p in pieces]),
            np.concatenate([p.status for p in pieces]),
            np.concatenate([p.omega0 for p in pieces]),
            {"updates": tuple(self._updates[first:])},
        )

    def extra(self) -> dict[str, Any]:
        e = self.estimator
        return {
            "omega0_estimate": None if e.latest is None else [float(v) for v in e.latest],
            "omega0_updates": e.updates,
            "omega0_skipped": e.skipped,
        }
