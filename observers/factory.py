"""Observers by name — what the gateway's ``[observer] type`` and replay's ``--observer`` specs choose.

Every observer implements `observers.base.Observer` (``tests/test_observer_conformance.py`` checks each
one registered here). To add one, write its class with a ``from_params`` classmethod (see
`ObserverBuilder`) and add one line to `_REGISTERED` below: its name, the paper, the class as
``"module:Class"`` (imported only when built, so that reading a config does not load every observer's
numerics) and the parameter names its ``from_params`` accepts (checked before anything is built, so a
misspelt key in a config stops start-up with a message naming it).

MMAE note (docs/mmae.md): Hassani's (A.2) noise settings do not identify real seas. By default the MMAE
measures the sensors' σ and the wave motion's σ from the data and designs its bank from them (ζ 0.25);
``measurement_sigma`` and ``wave_std`` fix either instead (e.g. from data sheets and a forecast).
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol

from observers.base import Observer
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
    # adaptive = true: ω0 from the wave-frequency estimator, re-solved on each estimate (sdre_adaptive)
    "adaptive",
    "window_s",
    "update_period_s",
    "omega_min",
    "omega_max",
    "per_dof",
)


class ObserverBuilder(Protocol):
    """What the registry calls: an observer class's ``from_params`` classmethod."""

    def __call__(
        self,
        vessel: VesselModel,
        tuning: PassiveTuning | None,
        params: dict[str, Any],
        *,
        allow_unchecked: bool = False,
    ) -> Observer: ...


@dataclass(frozen=True)
class ObserverEntry:
    """One registered observer: its name, the paper it implements, where its class lives, its parameters."""

    name: str
    paper: str
    target: str  # "module:Class", the class having ``from_params`` (an `ObserverBuilder`)
    params: tuple[str, ...] = ()
    tuning: tuple[str, ...] | None = None
    """The fields of the common passive tuning (`PassiveTuning`) its ``from_params`` uses; None: all of
    them. A replay or study spec that sets another is refused, not ignored."""

    def builder(self) -> ObserverBuilder:
        module, _, cls = self.target.partition(":")
        builder: ObserverBuilder = getattr(importlib.import_module(module), cls).from_params
        return builder


# EKF: the SDRE observer's physical tuning (the same Q; R from the sensors' per-sample noise).
EKF_PARAMS = (
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
)

_GS_PARAMS = ("omega0_initial", "window_s", "update_period_s", "omega_min", "omega_max", "per_dof")
_MMAE_PARAMS = (
    "candidates",
    "weight_floor",
    "dt",
    "zeta",
    "wave_std",
    "measurement_sigma",
    "warmup_s",
    "max_gap_s",
    "lf_output",
)

# The registry: one entry per observer. New observers (ekf, …) are added here.
_REGISTERED = (
    ObserverEntry("passive", "Fossen & Strand (1999)", "observers.passive:PassiveObserver"),
    ObserverEntry(
        "gain_scheduled",
        "Torsetnes, Jouffroy & Fossen (2004)",
        "observers.gain_scheduled:GainScheduledObserver",
        _GS_PARAMS,
    ),
    # the bank is designed from its own settings: no passive tuning (its `zeta` is its own parameter)
    ObserverEntry(
        "mmae", "Hassani, Pascoal, Aguiar & Athans", "observers.mmae:MMAEObserver", _MMAE_PARAMS, tuning=()
    ),
    # ω0 and ζ from the common tuning, the rest from the SDRE tuning's own fields
    ObserverEntry(
        "sdre",
        "Snijders, van der Woude & Westhuis (2005)",
        "observers.sdre:SdreObserver",
        SDRE_PARAMS,
        tuning=("omega0", "zeta"),
    ),
    ObserverEntry(
        "ekf",
        "Balchen et al. (1980); Fossen (2021) Sec. 13.4",
        "observers.ekf:EkfObserver",
        EKF_PARAMS,
        tuning=("omega0", "zeta"),
    ),
    # memory: the passive tuning plus a radiation model; froude_scale sets the length scale of the built-in
    # (supply-vessel) model, which otherwise follows the vessel's mass (docs/memory-observer.md)
    ObserverEntry(
        "memory", "Hajivand & Mousavizadegan (2010)", "observers.memory:MemoryObserver", ("froude_scale",)
    ),
)

OBSERVERS: dict[str, ObserverEntry] = {e.name: e for e in _REGISTERED}
"""Every registered observer by name, in registration order."""

OBSERVER_TYPES = tuple(OBSERVERS)
OBSERVER_PARAMS: dict[str, tuple[str, ...]] = {name: e.params for name, e in OBSERVERS.items()}
OBSERVER_TUNING: dict[str, tuple[str, ...] | None] = {name: e.tuning for name, e in OBSERVERS.items()}
TUNING_KEYS = (frozenset(PassiveTuning.__dataclass_fields__) - {"loop_bandwidth"}) | {"wave_period_s"}
"""The keys that set the common tuning: the `PassiveTuning` fields, and ``wave_period_s`` (ω0 = 2π/Tp).
Not ``loop_bandwidth``: that is the DP controller's bandwidth, which a gateway config gives the observer
from its ``[control]`` (`gateway.config`), not a key of its own."""


def tuning_keys(name: str) -> frozenset[str]:
    """The keys of the common tuning observer ``name`` uses (its entry's ``tuning``; all when None), with
    ``wave_period_s`` wherever ω0 is used. A config or spec that sets another is refused, not ignored."""
    used = OBSERVER_TUNING[name]
    if used is None:
        return TUNING_KEYS
    return frozenset(used) | ({"wave_period_s"} if "omega0" in used else set())


_ESTIMATOR_PARAMS = ("window_s", "update_period_s", "omega_min", "omega_max", "per_dof")
"""The wave-frequency estimator's settings (`observers.wave_frequency.ESTIMATOR_KEYS`): an SDRE takes them
only with ``adaptive = true``."""


def with_defaults(kind: str, defaults: Mapping[str, Any] | None, params: Mapping[str, Any]) -> dict[str, Any]:
    """Observer ``kind``'s ``params`` (the user's: a config's, a replay or study spec's) over ``defaults``
    (a scenario's, `simulator.scenarios.Scenario.observer_params`): the one merge every place that builds a
    scenario's observer uses — the study, the replay, the in-process closed loop and ``dpgw demo``.

    A default is left out where the observer, with the user's params, has no use for it and would refuse
    it: the estimator's settings go to an ``sdre`` only when it is adaptive (a fixed SDRE has no
    estimator). Given by the user, they are passed on as given (and refused there, with the reason)."""
    merged = {**(defaults or {}), **params}
    if kind == "sdre" and not merged.get("adaptive"):
        for key in _ESTIMATOR_PARAMS:
            if key not in params:
                merged.pop(key, None)
    return merged


class ObserverSpecError(ValueError):
    """An unknown observer or parameter; the message names it and lists the known ones."""


def check_params(kind: str, params: Mapping[str, Any]) -> None:
    if kind not in OBSERVERS:
        raise ObserverSpecError(f"observer '{kind}': unknown (known: {', '.join(OBSERVER_TYPES)})")
    unknown = sorted(set(params) - set(OBSERVERS[kind].params))
    if unknown:
        known = ", ".join(OBSERVERS[kind].params) or "none"
        raise ObserverSpecError(f"observer '{kind}': unknown parameter(s) {unknown} (known: {known})")


def make_observer(
    kind: str,
    vessel: VesselModel,
    tuning: PassiveTuning | None = None,
    *,
    params: Mapping[str, Any] | None = None,
    allow_unchecked: bool = False,
) -> Observer:
    """The observer called ``kind`` for ``vessel``: the passive ``tuning`` (where it applies) and its own
    ``params`` (`OBSERVER_PARAMS`)."""
    params = dict(params or {})
    check_params(kind, params)
    return OBSERVERS[kind].builder()(vessel, tuning, params, allow_unchecked=allow_unchecked)
