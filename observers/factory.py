"""Observers by name — what the gateway's ``[observer] type`` and replay's ``--observer`` specs choose.

MMAE note (docs/mmae.md): Hassani's (A.2) noise settings do not identify real seas. By default the MMAE
measures the sensors' σ and the wave motion's σ from the data and designs its bank from them (ζ 0.25);
``measurement_sigma`` and ``wave_std`` fix either instead (e.g. from data sheets and a forecast).

| name | paper | module |
|---|---|---|
| ``passive`` | Fossen & Strand (1999) | `observers.passive` |
| ``gain_scheduled`` | Torsetnes, Jouffroy & Fossen (2004) | `observers.gain_scheduled` |
| ``mmae`` | Hassani, Pascoal, Aguiar & Athans | `observers.mmae` |
| ``sdre`` | Snijders, van der Woude & Westhuis (2005) | `observers.sdre` |

Every observer has the same face: ``step(t, y, tau) -> PassiveEstimate``, ``run(t, y, tau)``,
``initialized``, ``omega0`` (the wave frequency in use per DOF) and ``extra()`` (fields for the estimate
message, e.g. the MMAE weights). ``params`` are the observer's own settings beyond the passive tuning.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol

from numpy.typing import ArrayLike, NDArray

from observers.passive import PassiveEstimate, PassiveObserver, PassiveRun
from observers.passive_tuning import PassiveTuning
from observers.vessel import VesselModel

# SDRE: the observer's own physical tuning (observers.sdre_tuning.SdreTuning); ω0 and ζ come from the
# common tuning like every observer's. paper_weights = true runs the paper's Q, R literally (comparison).
SDRE_PARAMS = (
    "position_sigma_m",
    "heading_sigma_rad",
    "sample_period_s",
    "wave_sigma_m",
    "wave_sigma_rad",
    "lf_bandwidth_ratio",
    "lf_bandwidth",
    "velocity_weight",
    "position_weight",
    "yaw_lever_m",
    "paper_weights",
)

OBSERVER_TYPES = ("passive", "gain_scheduled", "mmae", "sdre")

OBSERVER_PARAMS: dict[str, tuple[str, ...]] = {
    "passive": (),
    "gain_scheduled": ("omega0_initial", "window_s", "update_period_s", "omega_min", "omega_max", "per_dof"),
    "mmae": (
        "candidates",
        "weight_floor",
        "dt",
        "zeta",
        "wave_std",
        "measurement_sigma",
        "warmup_s",
        "max_gap_s",
    ),
    "sdre": SDRE_PARAMS,
}


class Observer(Protocol):
    @property
    def initialized(self) -> bool: ...

    @property
    def omega0(self) -> NDArray[Any]: ...

    def step(self, t: float, y: ArrayLike, tau: ArrayLike | None = None) -> PassiveEstimate: ...

    def run(self, t: ArrayLike, y: ArrayLike, tau: ArrayLike | None = None) -> PassiveRun: ...

    def extra(self) -> dict[str, Any]: ...


class ObserverSpecError(ValueError):
    """An unknown observer or parameter; the message names it and lists the known ones."""


def check_params(kind: str, params: Mapping[str, Any]) -> None:
    if kind not in OBSERVER_TYPES:
        raise ObserverSpecError(f"observer '{kind}': unknown (known: {', '.join(OBSERVER_TYPES)})")
    unknown = sorted(set(params) - set(OBSERVER_PARAMS[kind]))
    if unknown:
        known = ", ".join(OBSERVER_PARAMS[kind]) or "none"
        raise ObserverSpecError(f"observer '{kind}': unknown parameter(s) {unknown} (known: {known})")


def make_observer(
    kind: str,
    vessel: VesselModel,
    tuning: PassiveTuning | None = None,
    *,
    params: Mapping[str, Any] | None = None,
    allow_unchecked: bool = False,
) -> Observer:
    params = dict(params or {})
    check_params(kind, params)
    if kind == "passive":
        return PassiveObserver(vessel, tuning, allow_unchecked=allow_unchecked)
    if kind == "gain_scheduled":
        from observers.gain_scheduled import GainScheduledObserver
        from observers.wave_frequency import WaveFrequencyConfig

        est_keys = ("window_s", "update_period_s", "omega_min", "omega_max", "per_dof")
        est = {k: params.pop(k) for k in est_keys if k in params}
        if "per_dof" in est:
            est["per_dof"] = bool(est["per_dof"])
        return GainScheduledObserver(
            vessel,
            tuning,
            estimator=WaveFrequencyConfig(**est),
            allow_unchecked=allow_unchecked,
            **params,
        )
    if kind == "sdre":
        from observers.sdre import SdreObserver

        return SdreObserver.from_params(vessel, tuning, params, allow_unchecked=allow_unchecked)
    import numpy as np

    from observers.mmae import MMAEObserver

    if "candidates" in params:
        params["candidates"] = tuple(float(c) for c in params["candidates"])
    if "measurement_sigma" in params:
        # R from the sensors' noise (m, m, rad per sample): Hassani's (A.2) R is far from real gyros
        sigma = np.broadcast_to(np.asarray(params.pop("measurement_sigma"), dtype=float), (3,))
        params["R"] = np.diag(sigma**2)
    return MMAEObserver(vessel, **params)
