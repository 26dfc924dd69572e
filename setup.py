"""Build step: compile the per-event hot path to C with mypyc; everything else is in pyproject.toml.

Why: replay and the in-process closed loop spend their time in many small Python steps (decoding, the
reference checks, fusion, the pipeline's bookkeeping, the outputs) rather than in any one kernel, so no
numba kernel can take them; mypyc compiles these same type-annotated modules as they are, with no second
implementation to keep in step (docs/performance.md, "The hot path compiled"). The source stays the
readable reference: ``DPGW_PURE_PYTHON=1`` runs it interpreted, and tests/test_compiled.py checks that
both give byte-identical logs.

The build is optional. Without a C compiler, or with ``DPGW_PURE_PYTHON=1`` set at install, the same
modules install as plain Python (about 2x slower on replay, otherwise the same). Either way
``wire/_compiled.json`` records what was built and from which sources; at import, `wire.compiled` runs
the whole set interpreted if any source has changed since (an edit in a checkout takes effect at once,
slower, until ``pip install -e .`` compiles it again).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import sys
from pathlib import Path

from setuptools import setup
from setuptools.command.build_ext import build_ext

ROOT = Path(__file__).resolve().parent

# The modules compiled together (one shared library: calls between them are direct C calls). Chosen by
# profile: every module a replay cycle or a closed-loop tick passes through — the gateway's, and on the
# simulator's side of the loop its time loop, sensors, thruster model, faults, bias and clock — except
# those holding numba kernels (numba compiles Python bytecode, which a compiled module no longer has: such
# kernels live in `_..._kernel.py` modules beside them) and those defining runtime-checkable protocols
# (mypyc makes a Protocol a plain class: hence `simulator.sensor_protocol`). The in-process loop's glue
# (`dpgw.closed_loop`) stays interpreted: compiled, it gained nothing measurable (docs/performance.md).
COMPILED = [
    "gateway/pipeline.py",
    "gateway/fusion.py",
    "gateway/references/monitor.py",
    "gateway/references/track.py",
    "gateway/references/state.py",
    "gateway/references/voting.py",
    "gateway/references/attitude.py",
    "gateway/references/feedback.py",
    "gateway/foxglove_channels.py",
    "gateway/logreaders.py",
    "gateway/replay.py",
    "gateway/commands.py",
    "gateway/esc_direction.py",
    "gateway/control/controller.py",
    "gateway/control/allocation.py",
    "gateway/control/reference.py",
    "gateway/control/wind_feedforward.py",
    "wire/codecs/nmea.py",
    "wire/codecs/nmea_time.py",
    "wire/codecs/nmea_framing.py",
    "wire/codecs/nmea_encode.py",
    "wire/codecs/mavlink.py",
    "wire/geodesy.py",
    "wire/foxglove.py",
    "wire/gst_covariance.py",
    "wire/json_payload.py",
    "wire/mcap/writer.py",
    "simulator/runner.py",
    "simulator/sensors.py",
    "simulator/thrusters.py",
    "simulator/faults.py",
    "simulator/environment.py",
    "simulator/clock.py",
]
MANIFEST = "wire/_compiled.json"


def module_name(path: str) -> str:
    return path.removesuffix(".py").replace("/", ".")


def source_hash(path: str) -> str:
    return hashlib.sha256((ROOT / path).read_bytes()).hexdigest()


# mypyc's runtime (lib-rt/bytes_ops.c, mypy 2.4) slices bytes without clamping the end to the start: a
# slice that is empty because it ends before it begins (b"abc"[2:1], or line[7:-1] on a short line, which
# Python gives as b"") raises SystemError ("Negative size passed to PyBytes_FromStringAndSize"). The build
# compiles a copy of the runtime with the clamp added (tests/test_compiled.py checks the semantics). If a
# newer runtime no longer has that line, the copy is left as it is and the test says whether it is fixed.
_SLICE_BUG = "        Py_ssize_t slice_len = endn - startn;\n"
_SLICE_FIX = "        Py_ssize_t slice_len = endn > startn ? endn - startn : 0;\n"


def patched_runtime(extensions: list) -> None:
    """Point ``extensions`` at a copy of mypyc's lib-rt with the empty-bytes-slice fix (above)."""
    from mypyc.build import include_dir

    original = include_dir()
    copy = ROOT / "build" / "mypyc-lib-rt"
    if copy.exists():
        shutil.rmtree(copy)
    shutil.copytree(original, copy)
    ops = copy / "bytes_ops.c"
    ops.write_text(ops.read_text().replace(_SLICE_BUG, _SLICE_FIX))
    for ext in extensions:
        ext.include_dirs = [
            str(copy) + d[len(original) :] if d.startswith(original) else d for d in ext.include_dirs
        ]


def extensions() -> tuple[list, str]:
    """The mypyc extensions, or none and why."""
    if os.environ.get("DPGW_PURE_PYTHON", "") not in ("", "0"):
        return [], "DPGW_PURE_PYTHON set at install"
    try:
        from mypyc.build import mypycify
    except ImportError as exc:  # (a build without the build-system requirements)
        return [], f"mypyc not available ({exc})"
    try:
        # (the build's environment has the build requirements only: a `type: ignore` that the full install
        # needs may be unused there, which is no reason to stop; CI's mypy run checks them)
        built = mypycify(["--no-warn-unused-ignores", *COMPILED], opt_level="3", group_name="wire._native")
        patched_runtime(built)
        return built, ""
    except BaseException as exc:  # mypyc reports a type error by SystemExit
        return [], f"mypyc failed ({exc!r}; `pip install -v` shows its errors)"


def write_manifest(base: Path, built: bool, reason: str) -> None:
    """What was compiled, from which sources (their hashes); or that nothing was, and why. The modules are
    listed either way: an install that compiled nothing must still not import extensions an earlier build
    left beside the sources (`wire.compiled` imports the listed modules from source then)."""
    manifest = {
        "compiled": built,
        "reason": "" if built else reason,
        "modules": {module_name(p): source_hash(p) if built else "" for p in COMPILED},
    }
    target = base / MANIFEST
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(json.dumps(manifest, indent=1) + "\n")


def remove_stale_extensions() -> list[Path]:
    """In a checkout built in place (``pip install -e .``): delete the compiled file of any module that is
    no longer in `COMPILED`. Python imports an extension before the ``.py`` beside it, and the stale one,
    built as part of a shared library that no longer has it, fails to import (``no attribute
    'init_…'``). Only files beside a source of the same name are touched. Returns what was deleted."""
    keep = {str(ROOT / path) for path in COMPILED}
    removed = []
    for package in ("dpgw", "gateway", "observers", "simulator", "wire"):
        for ext in (ROOT / package).rglob("*.cpython-*.so"):
            source = ext.with_name(ext.name.split(".", 1)[0] + ".py")
            if source.is_file() and str(source) not in keep:
                ext.unlink()
                removed.append(ext)
    return removed


class BuildExt(build_ext):
    """Compile the hot path if it can, install it as Python if not; write the manifest either way."""

    reason = ""

    def run(self) -> None:
        if self._base() == ROOT:
            remove_stale_extensions()
        built = bool(self.extensions)
        if built:
            try:
                super().run()
            except Exception as exc:  # no compiler, no Python headers: install as Python
                self.warn(f"dpgw: the hot path is not compiled ({exc}); it installs as Python (slower)")
                BuildExt.reason = f"C build failed ({exc})"
                built = False
                self._remove_partial_outputs()
        write_manifest(self._base(), built, BuildExt.reason)

    def _remove_partial_outputs(self) -> None:
        for ext in self.extensions:
            path = Path(self.get_ext_fullpath(ext.name))
            path.unlink(missing_ok=True)

    def _base(self) -> Path:
        """Where the built package lands: the sources themselves (editable, in place) or the build folder."""
        return ROOT if self.inplace or self.editable_mode else Path(self.build_lib)

    def get_outputs(self) -> list[str]:
        return [*super().get_outputs(), str(self._base() / MANIFEST)]


ext_modules, BuildExt.reason = extensions()
if BuildExt.reason:
    print(f"dpgw: the hot path installs as Python: {BuildExt.reason}", file=sys.stderr)
    # (no extension, so no build_ext to write the manifest: written here, where an install from this folder
    # reads it, so that `dpgw --version` can say why; pip shows the message above only with -v)
    write_manifest(ROOT, False, BuildExt.reason)
setup(ext_modules=ext_modules, cmdclass={"build_ext": BuildExt})
