"""``dpgw tune``: observer gains, error-dynamics poles, tuning-rule and SPR checks, notch depth."""

from __future__ import annotations

import argparse
import math
import sys
from typing import TYPE_CHECKING, Any

from dpgw import cli_json
from observers.vessel_files import builtin_vessels

if TYPE_CHECKING:
    import numpy as np

# Only the parser is built at import; the tuning numerics (numpy, scipy) are imported by `run`, so
# `dpgw tune --help` answers at once.


NAME = "tune"
HELP = "passive-observer gains and checks for a vessel and sea state"
DESCRIPTION = (
    "Compute the gains of the Fossen & Strand (1999) passive observer for a vessel and a dominating "
    "wave period, in physical terms, and check them: the tuning rule (48), the SPR condition of "
    "Proposition 1, the eigenvalues of the linearised estimation-error dynamics, and the notch "
    "depth (how much wave-frequency motion at ω0 reaches the low-frequency estimate)."
)
EPILOG = (
    "examples:\n"
    "  dpgw tune --vessel mss_supply --wave-period 9\n"
    "  dpgw tune --vessel my_ship.toml --wave-period 7 --velocity-injection 0.1 --json\n"
    "  dpgw tune --vessel cybership2 --wave-period 0.8367        # the model's default sea, 7/sqrt(70) s\n"
    f"built-in vessels: {', '.join(builtin_vessels())}"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--vessel", required=True, help="built-in vessel name or a vessel TOML file")
    p.add_argument(
        "--wave-period",
        type=float,
        required=True,
        metavar="S",
        help="dominating wave period Tp (s), in the vessel's own scale: a model's basin period (the config's "
        "default is a ship's 7 s, Froude-scaled on a model: 7/sqrt(70) = 0.8367 s on cybership2, the gains "
        "dpgw run uses there; 0.84 would be 0.4 %% off)",
    )
    p.add_argument("--zeta", type=float, default=0.1, help="wave-model damping ζ (default 0.1)")
    p.add_argument("--zeta-n", type=float, default=1.0, help="notch damping ζn > ζ (default 1.0)")
    p.add_argument(
        "--cutoff-ratio",
        type=float,
        default=None,
        metavar="RATIO",
        help="ωc/ω0 (default the paper's 1.1/0.8976 = 1.2255)",
    )
    p.add_argument(
        "--bias-time",
        type=float,
        default=math.inf,
        metavar="S",
        help="bias time constant T (s); inf (default): random-walk bias; the paper's (58) is 1000",
    )
    p.add_argument(
        "--velocity-injection-ratio",
        type=float,
        default=0.12,
        metavar="RATIO",
        help="velocity-error decay rate a from the injection 𝒦, as a fraction of ω0 (default 0.12)",
    )
    p.add_argument("--velocity-injection", type=float, metavar="PER_S", help="a in 1/s (overrides the ratio)")
    p.add_argument(
        "--injection-damping-ratio",
        type=float,
        default=0.4,
        metavar="RATIO",
        help="least a set by the ratio, as a fraction of the vessel's own damping rate D/M per DOF "
        "(default 0.4; keeps the bias mode fast on a heavily damped DOF; 0: off)",
    )
    p.add_argument(
        "--bias-corner-ratio",
        type=float,
        default=0.04,
        metavar="RATIO",
        help="bias corner λ/κ as a fraction of ω0 (default 0.04)",
    )
    p.add_argument(
        "--loop-bandwidth",
        type=_loop_bandwidth,
        default="default",
        metavar="RAD_S",
        help="natural frequency ωn of the DP loop the estimate feeds: a ratio-set velocity injection is held "
        "at ≥ ωn − D/M per DOF, as the gateway does (docs/passive-observer.md). default: the DP "
        "controller's own default for the vessel (Froude-scaled; what 'dpgw run' uses without [control] "
        "bandwidth_rad_s); a number, or three (surge,sway,yaw), for a config that sets it; none: no loop "
        "(a controller fed the raw measurements, or no controller)",
    )
    p.add_argument(
        "--json",
        action="store_true",
        help="print one JSON object (for programs; null where a value is infinite: T of a random-walk bias)",
    )
    p.set_defaults(func=run)


def _loop_bandwidth(text: str) -> str | tuple[float, ...] | None:
    """``--loop-bandwidth``: "default", "none", or one or three positive rad/s."""
    word = text.strip().lower()
    if word in ("default", "none"):
        return None if word == "none" else "default"
    try:
        values = tuple(float(v) for v in word.split(","))
    except ValueError:
        values = ()
    if len(values) not in (1, 3) or not all(0 < v < math.inf for v in values):
        raise argparse.ArgumentTypeError(
            f"must be 'default', 'none', or one or three positive rad/s separated by commas (got {text})"
        )
    return values


def _matrix(a: np.ndarray) -> list[list[float]]:
    import numpy as np

    return [[float(v) for v in row] for row in np.atleast_2d(a)]


def run(args: argparse.Namespace) -> int:
    from observers.passive_tuning import (
        PassiveTuning,
        check_gains,
        check_stability,
        error_eigenvalues,
        notch_depth_db,
        passive_gains,
        tuning_advice,
        velocity_injection_rate,
    )
    from observers.vessel import VesselError, load_vessel

    try:
        vessel = load_vessel(args.vessel)
    except VesselError as exc:
        print(f"dpgw tune: {exc}", file=sys.stderr)
        return 2
    if not 0 < args.wave_period < math.inf:
        print("dpgw tune: --wave-period must be a positive, finite number of seconds", file=sys.stderr)
        return 2
    kwargs: dict[str, Any] = {
        "zeta": args.zeta,
        "zeta_n": args.zeta_n,
        "bias_time_constant_s": args.bias_time,
        "velocity_injection_ratio": args.velocity_injection_ratio,
        "velocity_injection": args.velocity_injection,
        "injection_damping_ratio": args.injection_damping_ratio,
        "bias_corner_ratio": args.bias_corner_ratio,
    }
    if args.cutoff_ratio is not None:
        kwargs["cutoff_ratio"] = args.cutoff_ratio
    loop = args.loop_bandwidth
    if loop == "default":  # as `dpgw run` feeds its default controller (gateway.config)
        from gateway.control.controller import ControllerTuning

        loop = ControllerTuning().resolved(vessel).bandwidth_rad_s
    kwargs["loop_bandwidth"] = None if loop is None else (loop[0] if len(loop) == 1 else loop)
    try:
        gains = passive_gains(vessel, PassiveTuning.from_wave_period(args.wave_period, **kwargs))
    except ValueError as exc:
        print(f"dpgw tune: {exc}", file=sys.stderr)
        return 2
    stability = check_stability(vessel, gains)
    checks = [*check_gains(gains), stability]
    eig = error_eigenvalues(vessel, gains, 0.0)
    slowest = stability.values["max_real_part_per_s"][0]  # (the slowest mode over all headings)
    notch = notch_depth_db(vessel, gains)
    result = {
        "vessel": vessel.name,
        "wave_period_s": args.wave_period,
        # the settings the gains came from, as resolved (a program reading only the JSON knew the gains
        # but not what made them)
        "settings": {
            "zeta": gains.zeta.tolist(),
            "zeta_n": gains.zeta_n.tolist(),
            "cutoff_ratio": (gains.omega_c / gains.omega0).tolist(),
            "bias_time_constant_s": args.bias_time,
            "velocity_injection_ratio": args.velocity_injection_ratio,
            "velocity_injection": args.velocity_injection,
            "injection_damping_ratio": args.injection_damping_ratio,
            "bias_corner_ratio": args.bias_corner_ratio,
        },
        "loop_bandwidth": None if loop is None else list(loop),
        # a of 𝒦 = diag(M) ωc a (`passive_gains`): the velocity error's decay rate from the injection
        "velocity_injection_per_s": velocity_injection_rate(vessel, gains).tolist(),
        "omega0": gains.omega0.tolist(),
        "omega_c": gains.omega_c.tolist(),
        "K1": _matrix(gains.K1),
        "K2": _matrix(gains.K2),
        "K3": _matrix(gains.K3),
        "K4": _matrix(gains.K4),
        "T": _matrix(gains.T),
        "eigenvalues": [[float(e.real), float(e.imag)] for e in eig],
        "slowest_rate_any_heading": slowest,
        "checks": [c.as_dict() for c in checks],
        "notch_db": notch.tolist(),
        # the same notes in the text and the JSON: what to change, found by trying it (`tuning_advice`); for
        # a period no sea has, the period is what to change, and advice on the rest would only distract
        "notes": (
            [note]
            if (note := sea_period_note(args.wave_period, vessel.model_scale))
            else tuning_advice(vessel, gains)
        ),
    }
    if args.json:
        print(cli_json.dumps(result, indent=2))
    else:
        print(_text(result, vessel.source))
    return 0 if all(c.ok for c in checks) else 1


def _fmt_matrix(name: str, m: list[list[float]], unit: str) -> str:
    rows = ["  [" + "  ".join(f"{v:12.5g}" for v in row) + " ]" for row in m]
    return f"{name} ({unit}):\n" + "\n".join(rows)


def _text(r: dict[str, Any], source: str) -> str:
    w0 = r["omega0"][0]
    lines = [
        f"vessel {r['vessel']}  ({source})",
        f"wave period {r['wave_period_s']:g} s -> ω0 = {w0:.4f} rad/s, ωc = {r['omega_c'][0]:.4f} rad/s",
        "velocity injection a = "
        + " / ".join(f"{v:.4g}" for v in r["velocity_injection_per_s"])
        + " 1/s (surge / sway / yaw)"
        + (
            ", at least ωn − D/M of the DP loop, ωn = "
            + " / ".join(f"{v:.4g}" for v in r["loop_bandwidth"])
            + " rad/s"
            if r["loop_bandwidth"] is not None
            else ", no DP loop given"
        ),
        "",
        _fmt_matrix("K1 = [diag(k1); diag(k2)], eqs (45)-(46)", r["K1"], "-, rad/s"),
        _fmt_matrix("K2 = diag(k3), eq (47)", r["K2"], "rad/s"),
        _fmt_matrix("K3 = Λ, bias injection (24)", r["K3"], "N/(m·s), N·m/(rad·s)"),
        _fmt_matrix("K4 = 𝒦, velocity injection (25)", r["K4"], "N/m, N·m/rad"),
        _fmt_matrix("T, bias time constants", r["T"], "s"),
        "",
        "eigenvalues of the linearised error dynamics (ψ = 0), 1/s:",
    ]
    for re, im in r["eigenvalues"]:
        tc = f"  (time constant {-1 / re:8.1f} s)" if re < 0 else "  (grows: unstable)" if re > 0 else ""
        lines.append(f"  {re:10.5f} {'+' if im >= 0 else '-'} {abs(im):.5f}j{tc}")
    slow = r["slowest_rate_any_heading"]
    lines.append(
        f"slowest over all headings: {slow:.5f} 1/s (time constant {-1 / slow:.1f} s)"
        if slow < 0
        else f"slowest over all headings: {slow:+.5f} 1/s: UNSTABLE, an error mode grows"
    )
    lines.append("")
    for c in r["checks"]:
        lines.append(f"{'PASS' if c['ok'] else 'FAIL'}  {c['name']}: {c['inequality']}")
        lines.append(f"      {c['detail']}")
    lines.append("")
    notch = ", ".join(f"{d:.1f}" for d in r["notch_db"])
    lines.append(f"notch depth at ω0 (LF estimate / WF motion): {notch} dB (surge, sway, yaw)")
    lines += [f"note: {n}" for n in r["notes"]]
    return "\n".join(lines)


# A tuning outside SEA_PERIOD_S is still made (a test of the observer may want one), with a note: the
# usual cause is a frequency in rad/s given as the period, or a model's period given for the ship or the
# other way round.


def sea_period_note(period_s: float, model_scale: float | None) -> str | None:
    """The note for a wave period no sea has at the vessel's scale (Froude: periods scale as √λ), or
    None."""
    from observers.froude import SEA_PERIOD_S  # (not at import: `dpgw --help` loads no numpy)

    root = math.sqrt(model_scale) if model_scale else 1.0
    lo, hi = SEA_PERIOD_S[0] / root, SEA_PERIOD_S[1] / root
    if lo <= period_s <= hi:
        return None
    scale = f" for this 1:{model_scale:g} model, Froude-scaled" if model_scale else " at full scale"
    if model_scale and SEA_PERIOD_S[0] <= period_s <= SEA_PERIOD_S[1]:
        hint = f"a full-scale period? At 1:{model_scale:g} it is {period_s / root:.3g} s"
    else:
        w0 = 2 * math.pi / period_s
        hint = f"check that it is the period in seconds, not ω0 in rad/s (ω0 = 2π/T: {w0:.3g} rad/s here)"
    return f"a wave period of {period_s:g} s is no sea's ({lo:.2g}-{hi:.2g} s{scale}): {hint}"
