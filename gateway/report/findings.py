"""What the report finds that must not stay in report.md: an observer whose LF estimate amplifies the
measured motion at the measurement's spectral peak.

A wave filter is there to keep wave motion out of the LF estimate, so its attenuation at the measured peak
(`metrics`, docs/report.md: 10·log10 of the LF estimate's PSD over the measurement's, from the same
samples) is negative: −20 dB and less at a sea it is tuned to. Above 0 dB the LF estimate holds *more* of
that motion than was measured: the filter lifts it. The passive observer does so below its notch (its LF
response rises above 1 there: +1.8 dB at 1.68 rad/s for CyberShip II's default ω0 7.51 rad/s,
`observers.passive_tuning.lf_response`), which is where a sea far below ω0 lies. The DP controller acts
on that estimate, so `dpgw replay --report` says it on the console as well as in report.md (both from
`amplification_warnings`). At a maximum on the band's edge (no clear wave peak) it is still the motion
there that is lifted; the warning says that no wave peak was found there, so that the figure is not read
as the sea's.
"""

from __future__ import annotations

import math
from typing import Any

from gateway.report.data import DOF, DOF_SYMBOL
from gateway.report.wave_check import retune_spec
from observers.factory import OBSERVER_TYPES

# Attenuation above this (dB) is amplification: the LF estimate holds more of the motion than was measured.
AMPLIFYING_DB = 0.0


def amplification_warnings(metrics: dict[str, Any]) -> list[str]:
    """One warning per observer whose attenuation at the measurement's peak is above `AMPLIFYING_DB` in
    some DOF, from `compute_metrics`' dict: where, by how much, and what to do."""
    out: list[str] = []
    measured = metrics["measurement"]
    for label, od in metrics["observers"].items():
        lifted = [
            (k, float(od[d]["attenuation_db"]))
            for k, d in enumerate(DOF)
            if od[d]["attenuation_db"] is not None and od[d]["attenuation_db"] > AMPLIFYING_DB
        ]
        if not lifted:
            continue
        peaks = {measured[DOF[k]]["dominant_frequency_rad_s"] for k, _ in lifted}
        if len(peaks) == 1:  # one peak for all (a common case): its frequency once
            parts = [
                ", ".join(f"{att:+.2f} dB in {DOF_SYMBOL[k]}" for k, att in lifted)
                + f" at {_rad_s(next(iter(peaks)))}"
            ]
        else:
            parts = [
                f"{att:+.2f} dB in {DOF_SYMBOL[k]} at {_rad_s(measured[DOF[k]]['dominant_frequency_rad_s'])}"
                for k, att in lifted
            ]
        omega0 = sorted(
            {round(od[DOF[k]]["omega0_median_rad_s"], 2) for k, _ in lifted if _has_omega0(od, k)}
        )
        used = f" (ω0 in use {', '.join(f'{w:.2f}' for w in omega0)} rad/s)" if omega0 else ""
        edge = [DOF_SYMBOL[k] for k, _ in lifted if measured[DOF[k]]["peak_at_band_edge"]]
        where = (
            f"; {'that' if len(edge) == len(lifted) else 'in ' + ', '.join(edge)} is the band's edge, no "
            "clear wave peak: what is lifted is the motion there (LF motion, noise, or the edge of a sea "
            "outside the band), not a sea the filter was tuned for"
            if edge
            else ""
        )
        w_peak = next(
            (
                measured[DOF[k]]["dominant_frequency_rad_s"]
                for k, _ in lifted
                if measured[DOF[k]]["dominant_frequency_rad_s"]
            ),
            None,
        )
        kind = od.get("observer")
        spec = retune_spec(kind, w_peak) if kind in OBSERVER_TYPES and w_peak else f"{kind or 'NAME'}:..."
        out.append(
            f"observer '{label}' amplifies the measured motion at the measurement's spectral peak instead "
            f"of attenuating it: {', '.join(parts)}{used}, so its LF estimate, which DP acts on, holds more "
            f"of that motion than was measured{where}. If there is sea at that frequency, tune ω0 to it "
            f"(--observer {spec}); see psd.png for where the "
            "LF estimate rises above the measurement"
        )
    return out


def _rad_s(w: float | None) -> str:
    return "–" if w is None else f"{w:.2f} rad/s"


def _has_omega0(od: dict[str, Any], k: int) -> bool:
    w = od[DOF[k]]["omega0_median_rad_s"]
    return w is not None and math.isfinite(w)
