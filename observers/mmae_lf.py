"""The MMAE's low-frequency output stage: the LF process noise identified from the data (dpgw's addition).

On by default whenever the MMAE identifies the noise and Q is not given; ``MMAEObserver(vessel,
lf_output=False)`` (``mmae:lf_output=false`` on the command line) gives the paper's blend (16). The bank and
its weights are the same either way. With it the MMAE's batch throughput is about 40 % of the blend's
alone (seven trial filters and one output filter beside the bank of eight, and their designs: `_Designer`).

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
each identification). While the bank re-adapts the weights spread, and the blended estimate of the paper
is given as before.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from observers import _mmae_kernel as kernel
from observers.doubling_dare import solve_dare_doubling
from observers.mmae_model import continuous_model, discretize, filter_tables
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
LF_REDESIGN_RATIO = 2.0
"""The trial and output filters are designed again when the bank's R or Q1 (identified) has moved outside
[1/2, 2] × what they were designed with, not at every redesign of the bank (30 %): they measure the LF
residual and smooth the LF estimate, which a factor of two in the wave model barely moves, and each design
is a Riccati equation."""


def scaled_lf_noise(Q: Array, base: Array, scale: Sequence[float]) -> Array:
    """Q (9×9) with its Q2, Q3 blocks (force noise, bias random walk) replaced by ``base``'s times
    ``scale[d]`` per DOF d (the cross terms by the geometric mean)."""
    out = np.array(Q, dtype=float, copy=True)
    f = np.tile(np.asarray(scale, dtype=float), 2)
    out[3:, 3:] = base[3:, 3:] * np.sqrt(np.outer(f, f))
    return out


class _Designer:
    """Steady-state filters of one candidate for the stage, made fast: Φ, Γ and the Q_d of each unit
    intensity are computed once per candidate (Q_d is linear in Q and the stage's Q is diagonal: Q_d =
    Σⱼ Qⱼⱼ Q_d(eⱼeⱼᵀ)), and the DARE is solved by doubling (`observers.doubling_dare`). The same tables as
    `observers.mmae.design_bank` for one candidate (tests/test_mmae.py compares them)."""

    def __init__(self, vessel: VesselModel) -> None:
        self.vessel = vessel
        self._per_candidate: dict[tuple[float, float, float], tuple[Array, ...]] = {}

    def _candidate(self, w0: float, zeta: float, dt: float) -> tuple[Array, ...]:
        key = (w0, zeta, dt)
        got = self._per_candidate.get(key)
        if got is None:
            A, B, G, C = continuous_model(self.vessel, w0, zeta)
            units = []
            for j in range(9):
                unit = np.zeros((9, 9))
                unit[j, j] = 1.0
                Phi, Gam, Qd = discretize(A, B, G, unit, dt)
                units.append(Qd)
            Phi[:6, 6:] = 0.0  # block-diagonal, as design_bank makes it
            Phi[6:, :6] = 0.0
            got = (A, B, C, Phi, Gam, np.array(units))
            self._per_candidate[key] = got
        return got

    def design(self, w0: float, zeta: float, dt: float, Q: Array, R: Array) -> Matrices:
        """The filter for candidate w0 with Q (9×9, diagonal) and R."""
        if np.count_nonzero(Q - np.diag(np.diag(Q))):
            raise ValueError("the LF stage's Q must be diagonal (the bank's own, Q not given)")
        A, B, C, Phi, Gam, units = self._candidate(w0, zeta, dt)
        Qd = np.tensordot(np.diag(Q), units, axes=1)
        Qd = 0.5 * (Qd + Qd.T)
        P = solve_dare_doubling(Phi.T, C.T, Qd, R)
        K = np.zeros((1, 4, N_STATE, 3))
        Sinv = np.zeros((1, 4, 3, 3))
        logdet = np.zeros((1, 4))
        filter_tables(P, C, R, K[0], Sinv[0], logdet[0])
        return (Phi[None].copy(), Gam, A[None].copy(), B, K, Sinv, logdet)


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


class _Trials:
    """The trial filters: one per scale, each a bank of one with its own state, frame and clock, run
    together by one compiled call (`_mmae_kernel.run_single`)."""

    def __init__(self, x: Array, clock: Array, k: int) -> None:
        self.X = np.tile(x, (k, 1))
        self.xb = self.X.copy()
        self.clock = np.tile(clock, (k, 1))
        self.matrices: Matrices | None = None

    def set(self, each: list[Matrices]) -> None:
        """The trials' matrices, one design per trial (Gam and B are the same for all: the model is)."""
        self.matrices = (
            np.concatenate([m[0] for m in each]),
            each[0][1],
            np.concatenate([m[2] for m in each]),
            each[0][3],
            np.concatenate([m[4] for m in each]),
            np.concatenate([m[5] for m in each]),
            np.concatenate([m[6] for m in each]),
        )

    def residuals(self, T: Array, Y: Array, TAU: Array, params: Array) -> Array:
        """(k, m, 3) posterior residuals y − (η̂ + η̂_w) of every trial over the samples."""
        assert self.matrices is not None
        res = np.empty((self.X.shape[0], T.shape[0], 3))
        kernel.run_single(self.X, self.xb, self.clock, T, Y, TAU, *self.matrices, params, res)
        return res


class LFOutputStage:
    """The LF process-noise choice and the output filter (module docstring). ``base_Q`` is the (A.2) Q
    whose Q2, Q3 the scales multiply. It runs only where the bank's Q is diagonal (identified, Q not
    given), which its designs rely on."""

    def __init__(self, vessel: VesselModel, base_Q: Array) -> None:
        self.vessel = vessel
        self.base_Q = np.asarray(base_Q, dtype=float)
        self._designer = _Designer(vessel)
        self.reset()

    def reset(self) -> None:
        self.scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
        self._rows: list[tuple[float, ...]] = []
        self._params = np.zeros(kernel.N_PARAMS)  # the bank's, weights never updated (set at identify)
        self.active = False
        self.rho: Array = np.full((3, len(LF_NOISE_SCALES)), np.nan)
        self._choice: tuple[float, ...] | None = None
        self._win = -1
        self._trials: _Trials | None = None
        self._output: _Filter | None = None
        self._recent: list[tuple[Array, Array, Array]] = []
        self._blocks: dict[int, tuple[Array, Array]] = {}  # LF residual block → (Σ r, count) (scales, 3)
        self._cache: dict[tuple[float, tuple[float, ...]], Matrices] = {}
        self._cache_sig: Array | None = None  # the bank's diag R, diag Q1 the cached designs were made with

    @property
    def running(self) -> bool:
        """Whether the output filter exists (from the first identification with a winner on)."""
        return self._output is not None

    def _matrices(self, bank: MMAEBank, win: int, scale: Sequence[float]) -> Matrices:
        sig = np.r_[np.diag(bank.R), np.diag(bank.Q)[:3]]
        if self._cache_sig is None or np.any(
            (sig > LF_REDESIGN_RATIO * self._cache_sig) | (sig < self._cache_sig / LF_REDESIGN_RATIO)
        ):  # the bank's noise has moved far: the trial and output filters are designed anew
            self._cache, self._cache_sig = {}, sig
        key = (float(bank.candidates[win]), tuple(float(s) for s in scale))
        got = self._cache.get(key)
        if got is None:
            Q = scaled_lf_noise(bank.Q, self.base_Q, scale)
            got = self._designer.design(key[0], bank.zeta, bank.dt, Q, bank.R)
            if len(self._cache) > 64:
                self._cache.clear()
            self._cache[key] = got
        return got

    def record(self, T: Array, Y: Array, TAU: Array) -> None:
        """Samples the bank took since the last identification (the trial filters run on them next)."""
        if self._output is not None and T.shape[0]:
            self._flush_rows()
            # copies: the caller's arrays may be reused before the next identification reads them
            self._recent.append((T.copy(), Y.copy(), TAU.copy()))

    def record_one(self, t: float, y: Array, tau: Array) -> None:
        """One sample (live `step`), kept as a row until the next chunk or identification."""
        if self._output is not None:
            self._rows.append((t, y[0], y[1], y[2], tau[0], tau[1], tau[2]))

    def _flush_rows(self) -> None:
        if self._rows:
            rows = np.array(self._rows)
            self._rows = []
            self._recent.append((rows[:, 0].copy(), rows[:, 1:4].copy(), rows[:, 4:7].copy()))

    def identify(self, t: float, bank: MMAEBank, X: Array, p: Array, clock: Array, params: Array) -> None:
        """At an identification of the bank at time t (the samples before t recorded): choose the scales,
        design the output filter for the winner, decide whether it gives the estimate. ``X``, ``p``,
        ``clock``, ``params``: the bank's filter states, weights, clock and kernel parameters."""
        self._flush_rows()
        chunks, self._recent = self._recent, []
        self._params = _no_weights(params)
        top = float(p.max())
        win = int(np.argmax(p))
        if top < 0.5 or clock[kernel.CLOCK_STARTED] == 0.0:
            self.active = False
            if self._output is not None:
                self._output.matrices = self._matrices(bank, self._win, self.scale)  # the bank may be new
            return
        if self._output is None:  # the first winner: every filter starts from its state, no blocks yet
            self._win = win
            self._trials = _Trials(X[win], clock, len(LF_NOISE_SCALES))
            self._output = _Filter(X[win], clock)
            self._output.matrices = self._matrices(bank, win, self.scale)
            return
        self._win = win
        assert self._trials is not None
        self._trials.set([self._matrices(bank, win, (s, s, s)) for s in LF_NOISE_SCALES])
        if chunks:
            self._update_residuals(t, chunks, bank)
        scale = self._choose()
        if scale != self.scale:
            self._hand_over(scale)
            self.scale = scale
        self._output.matrices = self._matrices(bank, win, self.scale)
        self.active = min(self.scale) < 1.0 and top >= LF_OUTPUT_WEIGHT

    def _update_residuals(self, t: float, chunks: list[tuple[Array, Array, Array]], bank: MMAEBank) -> None:
        T = np.ascontiguousarray(np.concatenate([c[0] for c in chunks]))
        Y = np.ascontiguousarray(np.concatenate([c[1] for c in chunks]))
        TAU = np.ascontiguousarray(np.concatenate([c[2] for c in chunks]))
        assert self._trials is not None
        res = self._trials.residuals(T, Y, TAU, self._params)  # (scales, samples, 3)
        # per block of T_b: Σ r and the count of finite r, per scale and DOF, added up as samples come
        tb = 2.0 * math.pi / (float(min(bank.candidates)) / 1.5)
        blk = np.floor(T / tb).astype(np.int64)
        finite = np.isfinite(res)
        values = np.where(finite, res, 0.0)
        for b in range(int(blk[0]), int(blk[-1]) + 1):
            sel = blk == b
            if not sel.any():
                continue
            add = (values[:, sel, :].sum(axis=1), finite[:, sel, :].sum(axis=1).astype(float))
            old = self._blocks.get(b)
            self._blocks[b] = add if old is None else (old[0] + add[0], old[1] + add[1])
        last_full = math.floor(t / tb) - 1
        first = last_full - LF_BLOCKS + 1
        self._blocks = {b: v for b, v in self._blocks.items() if b >= first}
        self.rho = np.full((3, len(LF_NOISE_SCALES)), np.nan)
        if not all(b in self._blocks for b in range(first, last_full + 1)):
            return
        sums = np.stack([self._blocks[b][0] for b in range(first, last_full + 1)], axis=2)  # (k, 3, blocks)
        counts = np.stack([self._blocks[b][1] for b in range(first, last_full + 1)], axis=2)
        # r̄² n / R = (Σ r)² / (n R); a block with fewer than 10 samples does not count and the DOF waits
        with np.errstate(divide="ignore", invalid="ignore"):
            z = sums**2 / (counts * np.diag(bank.R)[None, :, None])
        z[counts < 10] = np.nan
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
            assert self._trials is not None
            i = LF_NOISE_SCALES.index(scale[d])
            x = self._trials.X[i]
            a = float(self._trials.clock[i, kernel.CLOCK_PSI_F]) - psi_o  # the trial's frame → the output's
            c, s = math.cos(a), math.sin(a)
            for off in (I_ETA, I_BIAS):
                if d == 2:
                    out.X[0, off + 2] = x[off + 2]
                else:
                    v = (c * x[off] - s * x[off + 1], s * x[off] + c * x[off + 1])
                    out.X[0, off + d] = v[d]
            out.X[0, I_NU + d] = x[I_NU + d]
        out.xb[:] = out.X[0]

    def step(self, t: float, y: Array, tau: Array) -> None:
        """The output filter over one sample (live)."""
        if self._output is not None:
            self._output.step(t, y, tau, self._params)

    def run(self, T: Array, Y: Array, TAU: Array, OUT: Array) -> None:
        """The output filter over samples; OUT (m, 4, 3) its outputs (unchanged if it is not running)."""
        if self._output is not None and T.shape[0]:
            self._output.run(T, Y, TAU, self._params, OUT)

    def outputs(self, out: Array) -> None:
        """The output filter's NED outputs [η̂, ν̂, b̂, η̂_w] into out (4, 3)."""
        f = self._output
        assert f is not None
        kernel.outputs(f.xb, f.clock[kernel.CLOCK_PSI_F], out)


def _no_weights(params: Array) -> Array:
    """The bank's parameters with the weights never updated: a bank of one keeps its weight 1 either way,
    and the update (a likelihood, an exponential, a projection) would cost as much as the filter."""
    out = params.copy()
    out[kernel.PARAM_WARMUP_S] = math.inf
    return out


def mix_outputs(blend: Array, lf: Array, scale: Sequence[float]) -> None:
    """Per DOF, the output filter's estimate where its scale is below 1, the blend's elsewhere; in place
    into ``blend`` (m, 4, 3) [η̂, ν̂, b̂, η̂_w] from ``lf`` (m, 4, 3). The DOFs are the vessel-parallel axes
    of the blend's heading estimate: η̂, b̂, η̂_w are turned there, chosen, and turned back; ν̂ is in the
    body frame already. Only the DOFs whose scale is below 1 take the stiff model: a DOF the choice kept
    loose (the vessel moves in it) keeps the paper's blend."""
    stiff = np.asarray(scale, dtype=float) < 1.0
    if stiff.any():
        kernel.mix_outputs(blend, lf, stiff)
