"""A study's grid: scenarios × sea states × seeds, every case scored for every observer spec.

A *case* is one simulation (scenario, sea state, seed, duration); the observer specs are not part of the
grid's cases but of each case: every observer runs on the same measurements of one simulation, so the
comparison between observers is paired (same waves, same noise). The grid comes from CLI flags or a TOML
study file (docs/study.md); both end here, in `StudySpec`, checked before anything runs: a mistake stops
the study with one message naming the key.

Everything here is plain data (JSON-able): a case travels to a Dask worker as its dict and its hash is
the cache key.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from dpgw.scenario_names import SCENARIO_NAMES

DEFAULT_DURATION_S = 300.0
DEFAULT_SEEDS = (0, 1, 2, 3, 4, 5, 6, 7)
# The loop observer keeps the vessel on station (the gateway's DP controller acts on its estimate). It is
# the same in every case so that the vessel's motion does not depend on which observers are studied.
DEFAULT_LOOP_OBSERVER = "passive"


class StudySpecError(ValueError):
    """A study grid that cannot run; the message names the key."""


@dataclass(frozen=True)
class SeaSpec:
    """One sea state of the grid. None keeps the scenario's own value (its first sea state): ``hs_m``
    significant wave height, ``tp_s`` peak period, ``direction_deg`` the direction the waves travel
    towards (NED, from north), ``current_mps`` / ``current_dir_deg`` a constant current (flowing towards)."""

    hs_m: float | None = None
    tp_s: float | None = None
    direction_deg: float | None = None
    current_mps: float | None = None
    current_dir_deg: float | None = None

    @property
    def label(self) -> str:
        parts = [
            f"Hs{self.hs_m:g}" if self.hs_m is not None else "",
            f"Tp{self.tp_s:g}" if self.tp_s is not None else "",
            f"dir{self.direction_deg:g}" if self.direction_deg is not None else "",
            f"cur{self.current_mps:g}" if self.current_mps is not None else "",
            f"@{self.current_dir_deg:g}" if self.current_dir_deg is not None else "",
        ]
        return " ".join(p for p in parts if p) or "nominal"

    def check(self, where: str) -> None:
        # (key, ok, its range in words)
        checks = (
            ("hs_m", self.hs_m is None or (math.isfinite(self.hs_m) and self.hs_m >= 0), "≥ 0 m"),
            ("tp_s", self.tp_s is None or (math.isfinite(self.tp_s) and self.tp_s > 0), "> 0 s"),
            ("direction_deg", self.direction_deg is None or math.isfinite(self.direction_deg), "finite"),
            (
                "current_mps",
                self.current_mps is None or (math.isfinite(self.current_mps) and self.current_mps >= 0),
                "≥ 0 m/s",
            ),
            (
                "current_dir_deg",
                self.current_dir_deg is None or math.isfinite(self.current_dir_deg),
                "finite",
            ),
        )
        for key, ok, valid in checks:
            if not ok:
                raise StudySpecError(f"{where}: '{key}' must be {valid} (got {getattr(self, key)!r})")


@dataclass(frozen=True)
class CaseSpec:
    """One simulation of the grid and the observers scored on it."""

    scenario: str
    sea: SeaSpec
    seed: int
    duration_s: float
    settle_s: float
    observers: tuple[str, ...]  # observer specs as `dpgw replay --observer` takes them
    loop_observer: str = DEFAULT_LOOP_OBSERVER

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["observers"] = list(self.observers)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> CaseSpec:
        return cls(**{**d, "sea": SeaSpec(**d["sea"]), "observers": tuple(d["observers"])})

    def key(self, code_version: str) -> str:
        """The cache key: a hash of the case (canonical JSON) and the code that computes it."""
        text = json.dumps({"case": self.as_dict(), "code": code_version}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:24]

    @property
    def name(self) -> str:
        return f"{self.scenario} {self.sea.label} seed {self.seed}"


@dataclass(frozen=True)
class StudySpec:
    """The grid. ``observers`` empty: every registered observer with its defaults."""

    scenarios: tuple[str, ...]
    seas: tuple[SeaSpec, ...] = (SeaSpec(),)
    seeds: tuple[int, ...] = DEFAULT_SEEDS
    observers: tuple[str, ...] = ()
    duration_s: float = DEFAULT_DURATION_S
    settle_s: float | None = None  # None: a third of the duration
    loop_observer: str = DEFAULT_LOOP_OBSERVER
    extra: dict[str, Any] = field(default_factory=dict)

    def observer_specs(self) -> tuple[str, ...]:
        if self.observers:
            return self.observers
        from observers.factory import OBSERVER_TYPES

        return OBSERVER_TYPES

    def cases(self) -> list[CaseSpec]:
        settle = self.settle_s if self.settle_s is not None else self.duration_s / 3.0
        obs = self.observer_specs()
        return [
            CaseSpec(sc, sea, seed, self.duration_s, settle, obs, self.loop_observer)
            for sc, sea, seed in itertools.product(self.scenarios, self.seas, self.seeds)
        ]

    def check(self) -> None:
        """Every key of the grid, before anything runs (names the key that is wrong)."""
        from gateway.replay import ReplayError, parse_observer_spec

        if not self.scenarios:
            raise StudySpecError("study: 'scenarios' is empty")
        for name in self.scenarios:
            if name not in SCENARIO_NAMES:
                raise StudySpecError(
                    f"study: 'scenarios': unknown '{name}' (known: {', '.join(SCENARIO_NAMES)})"
                )
        if not self.seeds:
            raise StudySpecError("study: 'seeds' is empty")
        if any(s < 0 for s in self.seeds):
            raise StudySpecError(f"study: 'seeds' must be ≥ 0 ({list(self.seeds)})")
        if not (math.isfinite(self.duration_s) and self.duration_s > 0):
            raise StudySpecError(f"study: 'duration_s' must be > 0 ({self.duration_s!r})")
        if self.settle_s is not None and not (0 <= self.settle_s < self.duration_s):
            raise StudySpecError(f"study: 'settle_s' must be in [0, duration_s) ({self.settle_s!r})")
        for k, sea in enumerate(self.seas):
            sea.check(f"study: 'seas'[{k}]")
        if any(sea.current_mps for sea in self.seas):
            self._check_current()
        try:
            parse_observer_spec(self.loop_observer)
        except ReplayError as exc:
            raise StudySpecError(f"study: 'loop_observer': {exc}") from None
        labels: set[str] = set()
        for text in self.observer_specs():
            try:
                spec = parse_observer_spec(text)
            except ReplayError as exc:
                raise StudySpecError(f"study: 'observers': {exc}") from None
            if spec.label in labels:
                raise StudySpecError(
                    f"study: 'observers': label '{spec.label}' given twice (name it: SPEC@label)"
                )
            labels.add(spec.label)

    def _check_current(self) -> None:
        """A current runs the full plant (`dpgw.study.case.build_scenario`): every scenario's vessel must
        have what it needs, or the study would stop at its first case instead of now."""
        from simulator.plant_params import MissingHullError, PlantError, PlantParams
        from simulator.scenarios import SCENARIOS, get_scenario

        def full_plant_problem(name: str) -> PlantError | None:
            scenario = get_scenario(name)
            try:
                PlantParams.build(scenario.vessel, scenario.plant_options)
            except PlantError as exc:
                return exc
            return None

        for name in self.scenarios:
            if (problem := full_plant_problem(name)) is None:
                continue
            # The plant's own message offers switching its effects off, which a study has no option for: say
            # what a study can do instead (drop the current for this scenario, or take one that can run it).
            able = [other for other in SCENARIOS if full_plant_problem(other) is None]
            vessel = get_scenario(name).vessel.name
            why = (
                "it has no [hull] table (M_A, x_g, beam, draught, surge resistance; docs/vessels.md)"
                if isinstance(problem, MissingHullError)
                else str(problem)
            )
            raise StudySpecError(
                f"study: 'current_mps' > 0 runs scenario '{name}' on the full plant, and its vessel "
                f"'{vessel}' cannot run on it: {why}. Study "
                f"'{name}' without a current, or a current on a scenario that has the hull data: "
                + ", ".join(able)
            ) from None


_SEA_KEYS = {"hs_m", "tp_s", "direction_deg", "current_mps", "current_dir_deg"}
_STUDY_KEYS = {"scenarios", "seeds", "observers", "duration_s", "settle_s", "loop_observer", "sea", "grid"}


def _floats(value: Any, key: str) -> list[float | None]:
    values = value if isinstance(value, list) else [value]
    out: list[float | None] = []
    for v in values:
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise StudySpecError(f"study file: '{key}': numbers expected, got {v!r}")
        out.append(float(v))
    return out


def seas_product(grid: dict[str, list[float | None]]) -> tuple[SeaSpec, ...]:
    """Every combination of the listed values (a key not listed keeps the scenario's own value)."""
    keys = sorted(grid)
    return tuple(
        SeaSpec(**dict(zip(keys, combo, strict=True)))
        for combo in itertools.product(*(grid[k] for k in keys))
    )


# The study files shipped with dpgw (package data: they are there wherever dpgw is installed), by name.
SHIPPED_STUDIES = Path(__file__).resolve().parent / "studies"
# Where the shipped studies were in the source tree before they were package data: a command printed with
# it still runs.
_OLD_STUDIES_FOLDER = Path("examples", "studies")


def shipped_study_names() -> list[str]:
    return sorted(p.stem for p in SHIPPED_STUDIES.glob("*.toml"))


def study_file_path(text: str | Path) -> Path:
    """``--file``'s value as a file: a path that exists, else a shipped study by its name (``observers``,
    ``observers.toml``, or the ``examples/studies/observers.toml`` of older docs). Any other path is
    returned as given (`load_study_file` then says it is not there, with the shipped names)."""
    path = Path(text)
    if path.exists():
        return path
    bare = path.parent in (Path("."), _OLD_STUDIES_FOLDER) and path.suffix in ("", ".toml")
    shipped = SHIPPED_STUDIES / f"{path.stem}.toml"
    return shipped if bare and shipped.is_file() else path


def load_study_file(path: str | Path) -> StudySpec:
    """A TOML study file (docs/study.md): top-level keys of the grid; ``[grid]`` lists of sea values whose
    product is taken; ``[[sea]]`` tables list sea states one by one (both may be given)."""
    try:
        with open(path, "rb") as f:
            doc = tomllib.load(f)
    except FileNotFoundError:
        raise StudySpecError(
            f"study file {path}: no such file (a study shipped with dpgw is given by its name: "
            f"{', '.join(shipped_study_names())}; their files are in {SHIPPED_STUDIES})"
        ) from None
    except OSError as exc:
        raise StudySpecError(f"study file {path}: {exc.strerror}") from None
    except tomllib.TOMLDecodeError as exc:
        raise StudySpecError(f"study file {path}: {exc}") from None
    unknown = sorted(set(doc) - _STUDY_KEYS)
    if unknown:
        raise StudySpecError(f"study file {path}: unknown key(s) {unknown} (known: {sorted(_STUDY_KEYS)})")
    seas: list[SeaSpec] = []
    grid = doc.get("grid", {})
    for k in sorted(set(grid) - _SEA_KEYS):
        raise StudySpecError(f"study file {path}: [grid] unknown key '{k}' (known: {sorted(_SEA_KEYS)})")
    if grid:
        seas += seas_product({k: _floats(v, f"grid.{k}") for k, v in grid.items()})
    for i, table in enumerate(doc.get("sea", [])):
        for k in sorted(set(table) - _SEA_KEYS):
            raise StudySpecError(
                f"study file {path}: [[sea]] {i}: unknown key '{k}' (known: {sorted(_SEA_KEYS)})"
            )
        seas.append(SeaSpec(**{k: _floats(v, f"sea.{k}")[0] for k, v in table.items()}))
    scenarios = doc.get("scenarios", [])
    seeds = doc.get("seeds", list(DEFAULT_SEEDS))
    if isinstance(seeds, dict):  # seeds = {count = 8, start = 0}
        seeds = list(range(int(seeds.get("start", 0)), int(seeds.get("start", 0)) + int(seeds["count"])))
    if not all(isinstance(s, int) and not isinstance(s, bool) for s in seeds):
        raise StudySpecError(f"study file {path}: 'seeds': integers expected ({seeds!r})")
    if not isinstance(scenarios, list) or not all(isinstance(s, str) for s in scenarios):
        raise StudySpecError(f"study file {path}: 'scenarios': a list of names expected ({scenarios!r})")
    observers = doc.get("observers", [])
    if not isinstance(observers, list) or not all(isinstance(s, str) for s in observers):
        raise StudySpecError(
            f"study file {path}: 'observers': a list of observer specs expected ({observers!r})"
        )
    spec = StudySpec(
        scenarios=tuple(scenarios),
        seas=tuple(seas) or (SeaSpec(),),
        seeds=tuple(seeds),
        observers=tuple(observers),
        duration_s=float(doc.get("duration_s", DEFAULT_DURATION_S)),
        settle_s=float(doc["settle_s"]) if "settle_s" in doc else None,
        loop_observer=str(doc.get("loop_observer", DEFAULT_LOOP_OBSERVER)),
    )
    spec.check()
    return spec
