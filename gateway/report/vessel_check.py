"""Does the vessel fit the log? The vessel-scale check of every replay: motion faster than the vessel makes.

A replay runs the observer on the vessel it is given, and nothing in the estimates says when that vessel
is not the one that made the log: a small USV replayed as a 6,000 t supply vessel gives estimates,
only wrong ones (a wave filter and dynamics seconds too slow). One thing in the log does say it, cheaply:
the periods of the motion.

**The rule (Froude scaling).** A vessel's wave-frequency motion lies in its wave band
(`metrics.wave_band_for_length`: 0.2-2.0 rad/s, periods 3-31 s, at full scale; × √λ for a 1:λ model).
Waves shorter than that (at 2 rad/s a wave is 2πg/ω² = 15 m long) hardly move a ship in the horizontal
plane: its hull spans several of them and their forces cancel along it. A small craft or a model rides
such waves, and its motion peaks there. So a *clear* spectral peak of the measured position or heading
above the top of the vessel's wave band (up to 0.8 × Nyquist; clear as in the wave-tuning check,
`wave_check.dof_peak`: not on the band's edge and `CLEAR_PEAK_DB` above the spectrum's trend) is motion
the given vessel does not make: the log is of a smaller, faster vessel. The advice names the built-in
vessels whose wave band reaches the peak.

Only this direction is judged. A small vessel rides a long swell as well as a short sea, so a peak below
a small vessel's band says nothing about its size (a real USV's log has one at 8 s and one at 1.6 s);
and a log without a clear peak above the band (a calm sea, a 1 Hz receiver whose Nyquist frequency is
inside the band) gets no verdict: silence is not a verdict. Measured (`dpgw replay --json`,
`vessel_check`): the USV log 202412061745 replayed as mss_supply has clear peaks at 3.9 rad/s north
(13.4 dB) and 4.1 rad/s east (9.6 dB) and is advised cybership2; its two other logs (a calm sea, and a
short run) give no verdict. Simulated logs (300 s) replayed with their own vessel (torsetnes_2004, the
demo's; hassani, CyberShip II; mss_supply_storm, mss_osv, hajivand_2010, snijders_2005,
fossen_strand_1999) stand at most 1.8 dB above the trend above their band, nothing clear. The simulated
CyberShip II replayed as mss_supply gives no verdict either: its waves move the 1:70 model by
millimetres, under its DGPS's noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from gateway.report.data import DOF, Array
from gateway.report.metrics import wave_band_for_length
from gateway.report.wave_check import DofPeak, dof_peak


@dataclass(frozen=True)
class VesselCheck:
    vessel: str
    band: tuple[float, float]  # the vessel's wave band (rad/s)
    peaks: dict[str, DofPeak]  # per DOF, the spectral maximum above the band
    suitable: tuple[str, ...]  # built-in vessels whose wave band reaches the fastest clear peak

    @property
    def fastest(self) -> float | None:
        """The highest clear peak above the vessel's band (rad/s); None: no clear peak there."""
        clear = [p.omega for p in self.peaks.values() if p.clear]
        return max(clear) if clear else None

    def advice(self) -> str:
        """One line naming the mismatch and what to change; "" when the log gives no sign of one."""
        w = self.fastest
        if w is None:
            return ""
        where = ", ".join(f"{d} {p.omega:.1f} rad/s" for d, p in self.peaks.items() if p.clear)
        lo, hi = self.band
        todo = (
            f"re-run with --vessel {' or --vessel '.join(self.suitable)} (built-in, wave band reaching "
            f"{w:.1f} rad/s), or --vessel FILE.toml of the real vessel (docs/vessels.md)"
            if self.suitable
            else "re-run with --vessel FILE.toml of the real vessel (docs/vessels.md)"
        )
        return (
            f"vessel '{self.vessel}' does not fit this log: it moves at periods down to {_period(w)} s "
            f"({where}), faster than '{self.vessel}' moves (its waves {_period(hi)}-{_period(lo)} s, "
            f"{lo:.2g}-{hi:.2g} rad/s): the log is of a smaller vessel; {todo}"
        )

    def as_dict(self) -> dict[str, Any]:
        return {
            "vessel": self.vessel,
            "band_rad_s": list(self.band),
            "above_band": {d: p.as_dict() for d, p in self.peaks.items()},
            "suitable": list(self.suitable),
            "advice": self.advice() or None,
        }


def builtin_scales() -> dict[str, tuple[float | None, float | None]]:
    """The built-in vessels' (length, model scale), the candidates `check_vessel_scale` may advise."""
    from gateway.report.metrics import vessel_scale
    from observers.vessel_files import builtin_vessels

    return {name: vessel_scale(name) for name in builtin_vessels()}


def _period(omega: float) -> str:
    p = 2 * math.pi / omega
    return f"{p:.1f}" if p >= 1.0 else f"{p:.2f}"


def check_vessel_scale(
    t: Array,
    y: Array,
    vessel: str,
    length_m: float | None,
    model_scale: float | None,
    candidates: dict[str, tuple[float | None, float | None]] | None = None,
) -> VesselCheck:
    """The clear peaks of y (N×3: north, east, heading; NaN where not measured; times t in s) above the
    wave band of a vessel of ``length_m`` (a 1:``model_scale`` model), and the ``candidates`` (name →
    (length, model scale), the built-in vessels) whose wave band reaches the fastest of them."""
    band = wave_band_for_length(length_m, model_scale)
    peaks = {DOF[k]: dof_peak(t, y[:, k], (band[1], math.inf), angle=(k == 2)) for k in range(3)}
    check = VesselCheck(vessel, band, peaks, ())
    w = check.fastest
    if w is None or not candidates:
        return check
    suitable = tuple(
        name
        for name, (length, scale) in sorted(candidates.items())
        if name != vessel and wave_band_for_length(length, scale)[1] >= w
    )
    return VesselCheck(vessel, band, peaks, suitable)
