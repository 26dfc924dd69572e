"""``[observer]``: the passive tuning in physical terms, checked for the vessel before anything runs.

The tuning rule is Fossen & Strand (1999) eq. (48) and the passivity (SPR) condition their
Proposition 1; both are computed by `observers.passive_tuning.check_gains`. A tuning that fails them
is refused unless ``allow_unchecked`` (experiments).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from gateway.config.defaults import DEFAULTS
from gateway.config.model import ObserverConfig
from gateway.config.problems import Problems, show
from gateway.config.schema import TUNING_KEYS, ObserverTable, read_table
from observers.factory import ObserverSpecError, check_params, tuning_keys
from observers.froude import froude_scale
from observers.passive_tuning import (
    PassiveTuning,
    TuningError,
    check_gains,
    froude_scaled_fields,
    passive_gains,
)
from observers.vessel import VesselModel, load_vessel

__all__ = ["read_observer"]

_TUNING_NAMES = ("wave_period_s", "omega0", *TUNING_KEYS)
"""The keys of the common tuning (the wave period or ω0, and the passive tuning's)."""

_EXCLUSIVE = (
    ("omega_c", "cutoff_ratio"),
    ("bias_corner", "bias_corner_ratio"),
    ("velocity_injection", "velocity_injection_ratio"),
)


def read_observer(p: Problems, t: Mapping[str, Any], vessel: VesselModel | None) -> ObserverConfig | None:
    n0 = len(p)
    d = DEFAULTS["observer"]
    v = read_table(ObserverTable, t, "observer", p)
    n_tuning = len(p)
    values: dict[str, Any] = {}
    if "wave_period_s" in t and "omega0" in t:
        p.add("observer", "both wave_period_s and omega0 given (expected one: the wave period or ω0 = 2π/Tp)")
    elif "omega0" in t:
        values["omega0"] = v["omega0"]
    else:
        period = v["wave_period_s"] if "wave_period_s" in t else d["wave_period_s"]
        if period is not None:
            values["omega0"] = (
                2 * math.pi / period if isinstance(period, float) else tuple(2 * math.pi / x for x in period)
            )
    for explicit, ratio in _EXCLUSIVE:
        if explicit in t and ratio in t:
            p.add(
                "observer", f"both {explicit} and {ratio} given (expected one: {explicit} overrides {ratio})"
            )
    for key in TUNING_KEYS:
        if key in t:
            values[key] = v[key]
        elif key in d and not any(key == ratio and explicit in t for explicit, ratio in _EXCLUSIVE):
            values[key] = d[key]
    # The defaults are a ship's: on a model (or small craft) those not given are Froude-scaled to it,
    # frequencies × √λ, times ÷ √λ (`PassiveTuning.for_vessel`); given values are the user's, kept.
    # Without a usable vessel nothing runs; the checks' stand-in is full scale (they depend on ratios).
    defaulted = {
        k: x for k, x in values.items() if k not in t and not (k == "omega0" and "wave_period_s" in t)
    }
    values.update(froude_scaled_fields(defaulted, froude_scale(vessel) if vessel is not None else 1.0))
    # a problem in a key of the tuning itself (not rate_hz, type, ...) leaves nothing to check
    tuning_problems = [line for line in p.lines[n0:] if _key_of(line, p.where) in _TUNING_NAMES]
    if tuning_problems or len(p.lines) > n_tuning or any(x is None for x in values.values()):
        return None
    # The tuning is complete: check it for this vessel even if other observer keys have problems.
    tuning = PassiveTuning(**values)
    # The checks depend on gain ratios only (the vessel's M scales K3 and K4 alike), so a tuning is still
    # checked, with a stand-in vessel, when the configured vessel has problems of its own.
    try:
        checks = tuple(check_gains(passive_gains(vessel or load_vessel("mss_supply"), tuning)))
    except TuningError as exc:
        p.add("observer", str(exc))
        return None
    for check in checks:
        if not check.ok and not v["allow_unchecked"]:
            p.add(
                "observer",
                f"tuning fails {check.inequality}: {check.detail} (expected a tuning that passes, or "
                "observer.allow_unchecked = true to run such gains for experiments)",
            )
    params: dict[str, Any] = {}
    ptab, kind = v["params"], v["type"]
    if kind is not None:
        _refuse_unused_tuning(p, t, kind)
    if ptab is not None and kind is not None:
        try:
            check_params(kind, ptab)
        except ObserverSpecError as exc:
            p.add("observer.params", str(exc))
        for key, value in ptab.items():
            items = value if isinstance(value, list) else [value]
            if not all((isinstance(x, int | float)) for x in items):
                p.add(f"observer.params.{key}", f"wrong type (expected numbers, got {show(value)})")
            else:
                params[key] = tuple(value) if isinstance(value, list) else value
        if kind == "passive" and ptab:
            p.add("observer.params", 'the passive observer takes no params (expected none for "passive")')
    if len(p) != n0:
        return None
    assert kind is not None
    return ObserverConfig(
        type=kind,
        tuning=tuning,
        allow_unchecked=v["allow_unchecked"],
        rate_hz=v["rate_hz"],
        checks=checks,
        params=params,
    )


def _refuse_unused_tuning(p: Problems, t: Mapping[str, Any], kind: str) -> None:
    """A key of the common tuning the chosen observer does not use is a mistake, not a no-op: the SDRE and
    EKF observers take only ω0 (or the wave period) and ζ from it, the MMAE bank none (its settings,
    its own ζ too, go in ``[observer.params]``). Silently ignored, such a key looks like a tuning that
    took effect."""
    keys = tuning_keys(kind)
    what = ", ".join(sorted(keys)) if keys else "none of it"
    for key in _TUNING_NAMES:
        if key in t and key not in keys:
            p.add(
                f"observer.{key}",
                f'not used by the "{kind}" observer (of the common tuning it uses {what}; its own '
                "settings go in [observer.params])",
            )


def _key_of(line: str, where: str) -> str:
    """The last part of a problem's key path (``observer.zeta`` → ``zeta``)."""
    key = line[len(where) + 2 :].split(": ", 1)[0]
    return key.rsplit(".", 1)[-1]
