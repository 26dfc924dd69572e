"""The MMAE's low-frequency output stage: the LF process noise identified from the data (dpgw's addition).

Opt-in: ``MMAEObserver(vessel, lf_output=True)`` (``mmae:lf_output=true`` on the command line). It is off by
default because it costs about 5× the MMAE's batch throughput (seven trial filters and their designs beside
the bank of eight); the bank and its weights are the same either way.

Hassani et al. fix the whole Q at (A.2). dpgw identifies R and the wave part Q1 from the measured sea
(`observers.mmae`), and this module does the same for the LF part, Q2 (force noise of (9)) and Q3 (bias
random walk of (10)), but only for the estimate that is given out, never for the bank that identifies ω0.

Why not in the bank. On a calm, identified sea (A.2)'s Q2, Q3 are so large beside Q1 that the LF model
explains the wave-band motion as well as the wave model does: the steady-state filter barely notches, and
its LF estimate carries the wave motion (yaw gain 1.06 at the peak on Hassani's own sea). A stiffer LF model
in the bank fixes that, yet on a slow sea (Tp 12 s, near the slowest candidate) with every DOF stiff the
bank no longer re-adapts: the faster candidate explains the slow sea better. So the bank keeps (A.2), and
the estimate comes from a separate single filter — the winning wave model with the LF noise scaled.

The choice of the scale, per DOF (in the bank's vessel-parallel axes). At every identification of the bank
(one slowest period) and once a filter holds more than half the weight, `LF_NOISE_SCALES` trial filters —
the winner's wave model and the bank's R, Q1, with Q2, Q3 = s × (A.2) — are run over the samples since the
last identification, from the winner's state at its first win (a later winner changes their wave model,
not their states). Their posterior residual rₖ = yₖ − (η̂ₖ + η̂_w,ₖ) is averaged over blocks of
T_b = 2π/ω_c (ω_c = the slowest candidate / 1.5: a box filter that passes the LF band only); white
measurement noise of variance R gives E[r̄²] = R/n for a block of n samples, so

    ρ(s) = mean over the last `LF_BLOCKS` whole blocks of r̄² n / R

is the residual's power below the wave band in units of the noise's: about 1 for a model that follows the
LF motion, ≫ 1 for one that lags it. The stiffest s with ρ(s) − ρ(1) ≤ `LF_KAPPA` is chosen — the
difference to the loosest model, because on a vessel that turns the loosest model's ρ is itself above 1.
A looser scale is taken at once (a lagging model loses the LF motion now), a stiffer one when two
identifications in a row chose it. When a DOF's scale changes, the output filter's LF states of that DOF
(η, b, ν) are set from the trial filter that ran with the new scale: a stiffer model keeps what it has for a
long time, so it starts from an estimate made with its own model.

When it is used. The output filter runs on every sample from the first win on; its estimate replaces the
blended one (16) in each DOF whose scale is below 1 (`mix_outputs`; a DOF kept loose, where the vessel
moves, keeps the blend), while the winner holds at least `LF_OUTPUT_WEIGHT` of the weight (both judged at
each identification). While the bank re-adapts the weights spread, and the blended
estimate of the paper is given as before.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from observers import _mmae_kernel as kernel
from observers.state import I_BIAS, I_ETA, I_NU, N_STATE
from observers.vessel import VesselModel

if TYPE_CHECKING:
    from observers.mmae import MMAEBank

Array = NDArray[np.float64]
Matrices = tuple[Array, Array, Array, Array, Array, Array, Array]
"""One filter's (Phi, Gam, A, B, K, Sinv, logdet), as the kernel takes them."""

LF_NOISE_SCALES = (1.0, 1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6)
"""Candidate scales of (A.2)'s LF process noise Q2, Q3."""
LF_BLOCKS = 3
"""Blocks of 2π/ω_c the LF residual statistic averages."""
LF_KAPPA = 0.5
"""A scale is stiff enough to use while its ρ exceeds the loosest model's by at most this."""
LF_OUTPUT_WEIGHT = 0.9
"""The output filter gives the estimate only while the winning filter holds at least this weight."""


def scaled_lf_noise(Q: Array, base: Array, scale: Sequence[float]) -> Array:
    """Q (9×9) with its Q2, Q3 blocks (force noise, bias random walk) replaced by ``base``'s times
    ``scale[d]`` per DOF d (the cross terms by the geometric mean)."""
    out = np.array(Q, dtype=float, copy=True)
    f = np.tile(np.asarray(scale, dtype=float), 2)
    out[3:, 3:] = base[3:, 3:] * np.sqrt(np.outer(f, f))
    return out


class _Filter:
    """One steady-state filter of the kernel's bank layout (a bank of one): state, time, matrices."""

    def __init__(self, x: Array, clock: Array) -> None:
        self.X = x.reshape(1, N_STATE).copy()
        self.p = np.ones(1)
        self.xb = x.copy()
        self.clock = clock.copy()
        self.matrices: Matrices | None = None

    def run(self, T: Array, Y: Array, TAU: Array, params: Array, OUT: Array) -> None:
        m = T.shape[0]
        assert self.matrices is not None
        kernel.run(
            self.X, self.p, self.xb, self.clock, T, Y, TAU, *self.matrices, params,
            OUT, np.empty((m, 1)), np.empty(m, dtype=np.int8),
        )  # fmt: skip

    def step(self, t: float, y: Array, tau: Array, params: Array) -> None:
        assert self.matrices is not None
        kernel.step(self.X, self.p, self.xb, self.clock, t, y, tau, *self.matrices, params)


class LFOutputStage:
    """The LF process-noise choice and the output filter (module docstring). ``design`` makes a bank
    (`observers.mmae.design_bank` with its arguments (vessel, candidates, zeta, Q, R, dt)); ``base_Q`` is
    the (A.2) Q whose Q2, Q3 the scales multiply."""

    def __init__(self, vessel: VesselModel, base_Q: Array, design: Callable[..., MMAEBank]) -> None:
        self.vessel = vessel
        self.base_Q = np.asarray(base_Q, dtype=float)
        self._design = design
        self.reset()

    def reset(self) -> None:
        self.scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
        self.active = False
        self.rho: Array = np.full((3, len(LF_NOISE_SCALES)), np.nan)
        self._choice: tuple[float, ...] | None = None
        self._win = -1
        self._trials: list[_Filter] = []
        self._output: _Filter | None = None
        self._recent: list[tuple[Array, Array, Array]] = []
        self._residuals: list[tuple[Array, Array]] = []
        self._cache: dict[tuple[int, tuple[float, ...]], Matrices] = {}
        self._cache_bank: MMAEBank | None = None

    @property
    def running(self) -> bool:
        """Whether the output filter exists (from the first identification with a winner on)."""
        return self._output is not None

    def _matrices(self, bank: MMAEBank, win: int, scale: Sequence[float]) -> Matrices:
        if bank is not self._cache_bank:  # a redesigned bank: the trial filters are designed anew
            self._cache, self._cache_bank = {}, bank
        key = (win, tuple(float(s) for s in scale))
        got = self._cache.get(key)
        if got is None:
            b = bank
            Q = scaled_lf_noise(b.Q, self.base_Q, scale)
            kb = self._design(self.vessel, (float(b.candidates[win]),), b.zeta, Q, b.R, b.dt)
            got = (kb.Phi, kb.Gam, kb.A, kb.B, kb.K, kb.Sinv, kb.logdet)
            if len(self._cache) > 64:
                self._cache.clear()
            self._cache[key] = got
        return got

    def record(self, T: Array, Y: Array, TAU: Array) -> None:
        """Samples the bank took since the last identification (the trial filters run on them next)."""
        if self._output is not None and T.shape[0]:
            self._recent.append((T, Y, TAU))

    def identify(
        self, t: float, bank: MMAEBank, X: Array, p: Array, clock: Array, R: Array, params: Array
    ) -> None:
        """At an identification of the bank at time t (the samples before t recorded): choose the scales,
        design the output filter for the winner, decide whether it gives the estimate."""
        chunks, self._recent = self._recent, []
        top = float(p.max())
        win = int(np.argmax(p))
        if top < 0.5 or clock[kernel.CLOCK_STARTED] == 0.0:
            self.active = False
            if self._output is not None:
                self._output.matrices = self._matrices(bank, self._win, self.scale)  # the bank may be new
            return
        if self._output is None:  # the first winner: every filter starts from its state, no blocks yet
            self._win = win
            self._trials = [_Filter(X[win], clock) for _ in LF_NOISE_SCALES]
            self._output = _Filter(X[win], clock)
            self._output.matrices = self._matrices(bank, win, self.scale)
            return
        self._win = win
        for s, f in zip(LF_NOISE_SCALES, self._trials, strict=True):
            f.matrices = self._matrices(bank, win, (s, s, s))
        if chunks:
            self._update_residuals(t, chunks, bank, R, params)
        scale = self._choose()
        if scale != self.scale:
            self._hand_over(scale)
            self.scale = scale
        self._output.matrices = self._matrices(bank, win, self.scale)
        self.active = min(self.scale) < 1.0 and top >= LF_OUTPUT_WEIGHT

    def _update_residuals(
        self, t: float, chunks: list[tuple[Array, Array, Array]], bank: MMAEBank, R: Array, params: Array
    ) -> None:
        T = np.ascontiguousarray(np.concatenate([c[0] for c in chunks]))
        Y = np.ascontiguousarray(np.concatenate([c[1] for c in chunks]))
        TAU = np.ascontiguousarray(np.concatenate([c[2] for c in chunks]))
        m = T.shape[0]
        trial_params = params.copy()
        trial_params[kernel.PARAM_WARMUP_S] = 0.0
        res = np.empty((len(LF_NOISE_SCALES), m, 3))
        OUT = np.empty((m, kernel.N_OUT, 3))
        for i, f in enumerate(self._trials):
            f.run(T, Y, TAU, trial_params, OUT)
            r = Y - OUT[:, kernel.OUT_ETA, :] - OUT[:, kernel.OUT_ETA_WF, :]
            r[:, 2] = (r[:, 2] + math.pi) % (2.0 * math.pi) - math.pi
            res[i] = r
        self._residuals.append((T, res))
        tb = 2.0 * math.pi / (float(min(bank.candidates)) / 1.5)
        self._residuals = [c for c in self._residuals if c[0][-1] >= t - (LF_BLOCKS + 1) * tb]
        TT = np.concatenate([c[0] for c in self._residuals])
        RR = np.concatenate([c[1] for c in self._residuals], axis=1)  # (scales, samples, 3)
        blk = np.floor(TT / tb).astype(np.int64)
        last_full = math.floor(t / tb) - 1
        use = (blk <= last_full) & (blk > last_full - LF_BLOCKS)
        # per scale, DOF and block: Σ r and the count of finite r; r̄² n / R = (Σ r)² / (n R)
        k = len(LF_NOISE_SCALES)
        sums = np.zeros((k, 3, LF_BLOCKS))
        counts = np.zeros((k, 3, LF_BLOCKS))
        first = last_full - LF_BLOCKS + 1
        for j in range(LF_BLOCKS):
            part = RR[:, use & (blk == first + j), :]
            finite = np.isfinite(part)
            sums[:, :, j] = np.where(finite, part, 0.0).sum(axis=1)
            counts[:, :, j] = finite.sum(axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            z = sums**2 / (counts * np.asarray(R, dtype=float)[None, :, None])
        z[counts < 10] = np.nan  # a block with fewer than 10 samples does not count; the DOF waits
        self.rho = z.mean(axis=2).T  # (3, scales): NaN unless every block counts

    def _choose(self) -> tuple[float, float, float]:
        choice = [1.0, 1.0, 1.0]
        for d in range(3):
            rho = self.rho[d]
            if not np.isfinite(rho[0]):
                continue
            ok = [i for i in range(len(LF_NOISE_SCALES)) if rho[i] - rho[0] <= LF_KAPPA]
            choice[d] = float(LF_NOISE_SCALES[max(ok)]) if ok else 1.0
        prev, self._choice = self._choice, tuple(choice)
        out = list(self.scale)
        for d in range(3):
            # looser at once (a lagging model loses the LF motion now); stiffer when chosen twice in a row
            if choice[d] > out[d] or (prev is not None and prev[d] == choice[d]):
                out[d] = choice[d]
        return (out[0], out[1], out[2])

    def _hand_over(self, scale: Sequence[float]) -> None:
        """The output filter's LF states of each DOF whose scale changes, from the trial with that scale."""
        out = self._output
        assert out is not None
        psi_o = float(out.clock[kernel.CLOCK_PSI_F])
        for d in range(3):
            if scale[d] == self.scale[d]:
                continue
            trial = self._trials[LF_NOISE_SCALES.index(scale[d])]
            x = trial.X[0]
            a = float(trial.clock[kernel.CLOCK_PSI_F]) - psi_o  # the trial's frame → the output's frame
            c, s = math.cos(a), math.sin(a)
            for off in (I_ETA, I_BIAS):
                if d == 2:
                    out.X[0, off + 2] = x[off + 2]
                else:
                    v = (c * x[off] - s * x[off + 1], s * x[off] + c * x[off + 1])
                    out.X[0, off + d] = v[d]
            out.X[0, I_NU + d] = x[I_NU + d]
        out.xb[:] = out.X[0]

    def step(self, t: float, y: Array, tau: Array, params: Array) -> None:
        if self._output is not None:
            self._output.step(t, y, tau, params)

    def run(self, T: Array, Y: Array, TAU: Array, params: Array, OUT: Array) -> None:
        """The output filter over samples; OUT (m, 4, 3) its outputs (unchanged if it is not running)."""
        if self._output is not None and T.shape[0]:
            self._output.run(T, Y, TAU, params, OUT)

    def outputs(self, out: Array) -> None:
        """The output filter's NED outputs [η̂, ν̂, b̂, η̂_w] into out (4, 3)."""
        f = self._output
        assert f is not None
        kernel.outputs(f.xb, f.clock[kernel.CLOCK_PSI_F], out)


def mix_outputs(blend: Array, lf: Array, scale: Sequence[float]) -> None:
    """Per DOF, the output filter's estimate where its scale is below 1, the blend's elsewhere; in place
    into ``blend`` (m, 4, 3) [η̂, ν̂, b̂, η̂_w] from ``lf`` (m, 4, 3). The DOFs are the vessel-parallel axes
    of the blend's heading estimate: η̂, b̂, η̂_w are turned there, chosen, and turned back; ν̂ is in the
    body frame already. Only the DOFs whose scale is below 1 take the stiff model: a DOF the choice kept
    loose (the vessel moves in it) keeps the paper's blend."""
    stiff = np.asarray(scale, dtype=float) < 1.0
    if not stiff.any():
        return
    if stiff.all():
        blend[...] = lf
        return
    psi = blend[:, kernel.OUT_ETA, 2]
    c, s = np.cos(psi)[:, None], np.sin(psi)[:, None]
    for row in (kernel.OUT_ETA, kernel.OUT_BIAS, kernel.OUT_ETA_WF):
        # to the vessel-parallel axes (x along the heading, y across)
        bx = c[:, 0] * blend[:, row, 0] + s[:, 0] * blend[:, row, 1]
        by = -s[:, 0] * blend[:, row, 0] + c[:, 0] * blend[:, row, 1]
        lx = c[:, 0] * lf[:, row, 0] + s[:, 0] * lf[:, row, 1]
        ly = -s[:, 0] * lf[:, row, 0] + c[:, 0] * lf[:, row, 1]
        x = lx if stiff[0] else bx
        y = ly if stiff[1] else by
        blend[:, row, 0] = c[:, 0] * x - s[:, 0] * y
        blend[:, row, 1] = s[:, 0] * x + c[:, 0] * y
        if stiff[2]:
            blend[:, row, 2] = lf[:, row, 2]
    for d in range(3):
        if stiff[d]:
            blend[:, kernel.OUT_NU, d] = lf[:, kernel.OUT_NU, d]
