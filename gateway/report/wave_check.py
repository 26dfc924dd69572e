"""Does the observer's wave frequency fit the sea in the log? The mistuning check of every replay.

A wave filter tuned to ω0 removes the motion near ω0 from the LF estimate. When the sea in the log peaks
far from ω0 — a small craft in a short sea replayed with a ship's 7 s wave period, a swell replayed with a
wind-sea tuning — the wave motion passes into the LF estimate, the WF estimate drifts, and nothing in the
estimates themselves says so. So every replay measures the wave peak of the measured position and heading
and compares it with the ω0 each observer used.

**The measured peak** (per DOF: north, east, heading), with the report's own spectra (`spectra`): Welch
PSD over the whole record after a 4th-order high-pass at a third of the band's lower edge (the LF trend
removal), searched for its maximum in the vessel's wave band (`metrics.wave_band_for_length`: 0.2-2.0
rad/s at full scale, Froude-scaled for a model), clipped at 0.8 × Nyquist.

**Only clear peaks count.** The LF motion of a vessel that is moving (a USV on passage, a ship in a turn)
leaves a spectrum falling steeply through the band into the noise floor, whose maximum is then just its
low edge, or a wiggle of it. A wave peak is a bump *above* that fall. So a trend is fitted to the log-PSD
against log ω over the band — a quadratic, which follows a power-law fall bending into a flat noise
floor; least squares, refitted five times on the 70 % of bins lowest relative to the previous fit, so
that the peak itself does not lift it — and a DOF's maximum counts only if it is not on the band's edge
and its residual, averaged over three bins (a wave peak is broad; a lone bin of Welch's scatter is not),
stands at least `CLEAR_PEAK_DB` (8 dB) above the trend. Measured: simulated seas (Hs 5-6 m, DGPS 0.3 m,
15 min) stand 10.6-17.8 dB above it; the real USV log with a sea 9.4-13.9 dB; LF motion and white noise
alone (36 records of 15 min, tests/test_wave_check.py) at most 6.0 dB.

**Mistuned**, for an observer, when the median of the clear peaks and the median ω0 it used differ by
more than the factor `MISTUNE_RATIO` (1.4). The default passive tuning's gain from measured motion to the
LF estimate (`observers.passive_tuning.lf_response`, amplitude) is −22 dB at ω0, −20 dB at 1.1·ω0, −13 dB
at 1.4·ω0 and −10 dB at ω0/1.4, −6 dB at ω0/1.7, −4 dB at ω0/2: beyond a factor 1.4 the LF estimate
keeps three to four times more of the wave motion than the tuning promises, and it gets worse fast below
ω0. With no clear peak in any DOF there is no verdict (a calm sea, a vessel under way, too short a
record), but a note says that the check could not be made and why per DOF (`WaveCheck.notes`): silence
would read as a pass. A clear peak slower than any sea (`observers.froude.SEA_PERIOD_S`, 25 s ÷ √λ; the
band's low edge is 31 s) is warned as more likely the vessel's own slow motion, without retuning as the
fix.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gateway.report.data import DOF, Array
from gateway.report.spectra import nominal_dt, peak, resample, valid_samples, welch
from observers.factory import tuning_keys
from observers.froude import SEA_PERIOD_S

CLEAR_PEAK_DB = 8.0
MISTUNE_RATIO = 1.4
# Welch segments of this many periods of the band's low edge (as the report), at most half the record.
WELCH_PERIODS = 8
MAX_GAP_SAMPLES = 4.0
TREND_KEEP_PERCENTILE = 70.0
TREND_ITERATIONS = 5
TREND_DEGREE = 2
SMOOTH = 3


@dataclass(frozen=True)
class DofPeak:
    """The spectral maximum of one DOF in the band and how far it stands above the spectrum's trend."""

    omega: float  # rad/s (NaN: no spectrum)
    above_trend_db: float
    at_edge: bool

    @property
    def clear(self) -> bool:
        return math.isfinite(self.omega) and not self.at_edge and self.above_trend_db >= CLEAR_PEAK_DB

    def as_dict(self) -> dict[str, Any]:
        """For ``--json`` and metrics.json (None for a NaN: no spectrum)."""
        return {
            "peak_rad_s": self.omega if math.isfinite(self.omega) else None,
            "above_trend_db": self.above_trend_db if math.isfinite(self.above_trend_db) else None,
            "at_band_edge": self.at_edge,
            "clear": self.clear,
        }


@dataclass(frozen=True)
class ObserverTuning:
    """What one observer used: the median ω0 over the replay (rad/s) and whether it moved (adaptive)."""

    label: str
    kind: str  # the observer's name in `--observer NAME:...`
    omega0: float
    adaptive: bool
    ratio: float | None = None  # measured / ω0 (None: nothing measured)
    span: tuple[float, float] | None = None  # a multiple-model bank's lowest and highest candidate (rad/s)

    @property
    def mistuned(self) -> bool:
        return self.ratio is not None and max(self.ratio, 1.0 / self.ratio) > MISTUNE_RATIO


@dataclass(frozen=True)
class WaveCheck:
    band: tuple[float, float]
    peaks: dict[str, DofPeak]
    measured: float | None  # median of the clear peaks (rad/s)
    observers: list[ObserverTuning] = field(default_factory=list)
    froude_scale: float = 1.0  # the vessel's λ (`observers.froude`): the periods a sea has for it

    @property
    def longest_sea_s(self) -> float:
        """The longest period a sea has at the vessel's scale (s): `SEA_PERIOD_S` ÷ √λ."""
        return SEA_PERIOD_S[1] / math.sqrt(self.froude_scale)

    def warnings(self) -> list[str]:
        """One message per mistuned observer: what was measured, what was used, what to do."""
        out: list[str] = []
        if self.measured is None:
            return out
        w = self.measured
        where = ", ".join(d for d, p in self.peaks.items() if p.clear)
        for o in self.observers:
            if not o.mistuned:
                continue
            what = (
                f"the measured wave peak is {w:.2f} rad/s (period {_period(w)} s, in {where}) but "
                f"observer '{o.label}' filtered waves at ω0 = {o.omega0:.2f} rad/s "
                f"(period {_period(o.omega0)} s): its wave-frequency estimate is not the waves, and "
                "wave motion leaks into the LF estimate."
            )
            period = _period(w)
            if 2 * math.pi / w > self.longest_sea_s:
                # The band reaches past the longest swell (its edge is a clear peak's limit, not a sea's):
                # a peak there is more often the vessel's own slow motion (a DP oscillation, a slow yaw,
                # a manoeuvre) than waves, and a wave filter tuned to it would filter the motion DP must
                # act on. So no retuning is advised as the fix.
                scale = f" for this 1:{self.froude_scale:g} scale" if self.froude_scale != 1.0 else ""
                out.append(
                    f"{what} But a period of {period} s is longer than any sea's ({self.longest_sea_s:.3g} s "
                    f"at most{scale}): it is more likely the vessel's own slow motion (a DP oscillation, a "
                    "slow yaw, a manoeuvre) than waves. Look at the position and heading in the log (and "
                    "the controller's tuning) before retuning; only for a swell known to be that long, "
                    f"--observer {retune_spec(o.kind, w)}."
                )
                continue
            spec = self._advised_spec(o, w)
            if _bank_spans(o, w) and o.span is not None:  # (`_bank_spans` says so; mypy reads this)
                # A bank around the sea is what it had: advising it again sends the user round in a circle.
                # Its weights followed the other DOFs (motion without a clear wave peak), not the waves.
                others = [d for d, p in self.peaks.items() if not p.clear]
                todo = (
                    f"Its bank ({_fmt(o.span[0])}-{_fmt(o.span[1])} rad/s) spans the sea's, yet its weights "
                    "settled elsewhere"
                    + (f", led by the motion without a clear wave peak ({_and(others)})" if others else "")
                    + f": for this log, a fixed ω0 at the measured peak, --observer {spec}."
                )
            elif o.kind == "mmae":  # a bank of fixed candidates, no range: a bank around the sea
                todo = f"Its bank does not reach the sea's: re-run with --observer {spec}"
            elif o.adaptive:
                todo = f"Its ω0 range does not reach the sea's: re-run with --observer {spec}"
            else:
                todo = (
                    f"Re-run with --observer {spec}, or with --observer gain_scheduled:"
                    f"{_scheduled(w)} to follow the sea."
                )
            out.append(f"{what} {todo}")
        return out

    def advised(self) -> dict[str, str]:
        """The ``--observer`` spec the warnings advise each mistuned observer (by label), where they advise
        one (not for a peak longer than any sea's, which is more likely the vessel's own motion)."""
        w = self.measured
        if w is None or 2 * math.pi / w > self.longest_sea_s:
            return {}
        return {o.label: self._advised_spec(o, w) for o in self.observers if o.mistuned}

    @staticmethod
    def _advised_spec(o: ObserverTuning, w: float) -> str:
        """The spec that tunes ``o`` to a sea at ``w`` (rad/s): its own keys at the peak; a range around it
        for an observer that schedules ω0; for an MMAE whose bank already spans the sea (its weights led
        elsewhere), a fixed ω0 at the peak instead of the same bank again."""
        if _bank_spans(o, w):
            return retune_spec("passive", w)
        if o.adaptive and o.kind != "mmae":  # (an SDRE takes a range only when adaptive: said again)
            return f"{o.kind}:{'adaptive=true,' if o.kind == 'sdre' else ''}{_scheduled(w)}"
        return retune_spec(o.kind, w)

    def notes(self) -> list[str]:
        """With no clear peak in any DOF: that the observers' ω0 could not be checked, and why per DOF.
        Not a verdict (a calm sea, a short record, a vessel under way), but the engineer is told that the
        check was not made rather than left to read silence as a pass."""
        if self.measured is not None or not self.observers:
            return []
        by_reason: dict[str, list[str]] = {}  # (north, east and heading alike: said once)
        for d, p in self.peaks.items():
            by_reason.setdefault(_why_not_clear(p), []).append(d)
        why = "; ".join(f"{_and(dofs)}: {reason}" for reason, dofs in by_reason.items())
        used = ", ".join(f"'{o.label}' {o.omega0:.2f} rad/s" for o in self.observers)
        return [
            f"no clear wave peak in the log ({why}; band {self.band[0]:.3g}-{self.band[1]:.3g} rad/s): the "
            f"wave frequency the observers used ({used}) could not be checked against the sea"
        ]

    def as_dict(self) -> dict[str, Any]:
        return {
            "band_rad_s": list(self.band),
            "measured_peak_rad_s": self.measured,
            "per_dof": {d: p.as_dict() for d, p in self.peaks.items()},
            "observers": {
                o.label: {
                    "observer": o.kind,
                    "omega0_rad_s": o.omega0,
                    "adaptive": o.adaptive,
                    "ratio": o.ratio,
                    "mistuned": o.mistuned,
                }
                for o in self.observers
            },
            "warnings": self.warnings(),
            "notes": self.notes(),
        }


def _and(words: list[str]) -> str:
    """``north``, ``north and east``, ``north, east and heading``."""
    return words[0] if len(words) == 1 else f"{', '.join(words[:-1])} and {words[-1]}"


def _why_not_clear(p: DofPeak) -> str:
    """``1.68 rad/s at the band's edge``, ``3.9 rad/s only 5.2 dB above the trend``, or ``no spectrum``."""
    if not math.isfinite(p.omega):
        return "no spectrum (too few samples)"
    if p.at_edge:
        return f"maximum {p.omega:.2f} rad/s at the band's edge"
    above = f"{p.above_trend_db:.1f} dB above the trend ({CLEAR_PEAK_DB:g} needed)"
    return f"maximum {p.omega:.2f} rad/s only {above}"


def _bank_spans(o: ObserverTuning, omega: float) -> bool:
    """``o`` is an MMAE whose bank already spans a sea at ``omega`` (rad/s): its weights settled elsewhere,
    so the same bank again is no advice."""
    return o.kind == "mmae" and o.span is not None and o.span[0] <= omega <= o.span[1]


def retune_spec(kind: str, omega: float) -> str:
    """The ``--observer`` spec that tunes observer ``kind`` to a sea at ``omega`` (rad/s), in the keys it
    takes: ``KIND:wave_period_s=P`` where it uses ω0, a bank of 8 candidates from ω/2 to 2ω for the MMAE
    (which takes no ω0 of the common tuning: a spec with one is refused)."""
    if "wave_period_s" in tuning_keys(kind):
        return f"{kind}:wave_period_s={_period(omega)}"
    bank = "/".join(_fmt(x) for x in np.linspace(omega / 2.0, 2.0 * omega, 8))
    return f"{kind}:candidates={bank}"


def _scheduled(omega: float) -> str:
    """The keys of an observer that schedules ω0 for a sea at ``omega``: its period, and a range from half
    to twice it."""
    return f"wave_period_s={_period(omega)},omega_min={_fmt(omega / 2.0)},omega_max={_fmt(2.0 * omega)}"


def _fmt(x: float) -> str:
    return f"{x:.2g}"


def _period(omega: float) -> str:
    """2π/ω in s, to 0.1 s, or 0.01 s below 1 s: a model's basin sea (0.84 s, 7 s Froude-scaled at 1:70)
    rounded to 0.1 s would be advised 5 % off."""
    p = 2 * math.pi / omega
    return f"{p:.1f}" if p >= 1.0 else f"{p:.2f}"


def dof_peak(t: Array, x: Array, band: tuple[float, float], angle: bool = False) -> DofPeak:
    """The wave peak of one measured DOF (times in s, gaps as NaN) in `band` (rad/s)."""
    none = DofPeak(float("nan"), float("nan"), False)
    ok = valid_samples(t, x)
    tv, xv = t[ok], x[ok]
    if len(tv) < 16:
        return none
    dt = nominal_dt(tv)
    if not math.isfinite(dt) or dt <= 0:
        return none
    if angle:
        xv = np.unwrap(xv)
    lo, hi = band[0], min(band[1], 0.8 * math.pi / dt)
    if hi <= lo:
        return none
    pieces = [p[:, 0] for p in resample(tv, xv[:, None], dt, MAX_GAP_SAMPLES * dt)]
    seg_s = min(WELCH_PERIODS * 2.0 * math.pi / lo, 0.5 * (tv[-1] - tv[0]))
    psd = welch(pieces, dt, seg_s, lo / 3.0)
    if psd is None:
        return none
    w_peak, at_edge = peak(psd, (lo, hi))
    sel = (psd.omega >= lo) & (psd.omega <= hi) & (psd.psd > 0)
    if np.count_nonzero(sel) < 5 or not math.isfinite(w_peak):
        return none
    return DofPeak(w_peak, _above_trend_db(psd.omega[sel], psd.psd[sel], w_peak), at_edge)


def _above_trend_db(omega: Array, psd: Array, w_peak: float) -> float:
    """dB by which the PSD at w_peak stands above a power law fitted to the rest of the band (see module)."""
    lw, lp = np.log10(omega), np.log10(psd)
    keep = np.ones(len(lw), dtype=bool)
    coef = np.zeros(TREND_DEGREE + 1)
    for _ in range(TREND_ITERATIONS):
        coef = np.polyfit(lw[keep], lp[keep], TREND_DEGREE)
        resid = lp - np.polyval(coef, lw)
        keep = resid <= np.percentile(resid, TREND_KEEP_PERCENTILE)
        if np.count_nonzero(keep) <= TREND_DEGREE + 1:
            break
    k = int(np.argmin(np.abs(omega - w_peak)))
    resid = lp - np.polyval(coef, lw)
    h = SMOOTH // 2
    return float(10.0 * np.mean(resid[max(k - h, 0) : k + h + 1]))


def check_wave_tuning(
    t: Array,
    y: Array,
    band: tuple[float, float],
    omega0: dict[str, Array],
    kinds: dict[str, tuple[str, bool]] | None = None,
    *,
    spans: dict[str, tuple[float, float]] | None = None,
    froude_scale: float = 1.0,
) -> WaveCheck:
    """Measured wave peak of y (N×3: north, east, heading; NaN where not measured) against the ω0 each
    observer used (`omega0`: label → its ω0 samples, N×3 or N, rad/s). `kinds`: label → (observer name,
    whether it schedules ω0 itself); an observer whose ω0 moved counts as scheduling it anyway. `spans`:
    label → the lowest and highest ω0 of a multiple-model observer's bank. `froude_scale`: the vessel's λ
    (the band's own scale), for the periods a sea has."""
    kinds = kinds or {}
    spans = spans or {}
    peaks = {DOF[k]: dof_peak(t, y[:, k], band, angle=(k == 2)) for k in range(3)}
    clear = [p.omega for p in peaks.values() if p.clear]
    measured = float(np.median(clear)) if clear else None
    tunings = []
    for label, w in omega0.items():
        w = np.asarray(w, dtype=float)
        w = w[np.isfinite(w) & (w > 0)]
        if w.size == 0:
            continue
        w0 = float(np.median(w))
        kind, schedules = kinds.get(label, (label, False))
        adaptive = schedules or bool(np.ptp(w) > 1e-6 * w0)
        ratio = measured / w0 if measured is not None else None
        tunings.append(ObserverTuning(label, kind, w0, adaptive, ratio, spans.get(label)))
    return WaveCheck(band=band, peaks=peaks, measured=measured, observers=tunings, froude_scale=froude_scale)
