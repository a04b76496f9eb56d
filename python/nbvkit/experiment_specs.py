"""What an experiment runs: RunSpec (one mission: a scenario from a start on a structure, with
config overrides) and the spec lists of Table 2 (table2_specs), a sweep file (sweep_specs) and a
planner comparison (compare_specs). Re-exported by nbvkit.experiments."""
from __future__ import annotations

import hashlib
import itertools
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

from .limits import shorten


@dataclass(frozen=True)
class RunSpec:
    """One mission: a scenario from a start on a structure, with config overrides."""

    scenario: str
    start: int
    mesh: str | None = None  # None: the shipped airliner
    mesh_scale: float = 1.0
    mesh_up: str = "z"
    overrides: tuple = ()  # ("key=value", ...)
    config_file: str | None = None
    labels: tuple = field(default=())  # (("name", value), ...) extra columns for the tidy table

    @property
    def run_id(self) -> str:
        name = Path(self.mesh).stem if self.mesh else "airliner"
        h = hashlib.sha1(
            json.dumps(
                [self.mesh, self.mesh_scale, self.mesh_up, list(self.overrides), self.config_file]
            ).encode()
        ).hexdigest()[:8]
        return f"{name}_s{self.scenario}_start{self.start}_{h}"

    def config(self):
        from .config import load_config

        over = [
            *self.overrides,
            f"scenario={json.dumps(self.scenario)}",
            f"start={self.start}",
            f"mesh.scale={self.mesh_scale}",
            f"mesh.up={self.mesh_up}",
            "progress=false",
        ]
        if self.mesh:
            over.append(f"mesh.path={json.dumps(str(self.mesh))}")
        return load_config(self.config_file, over)


def _spec_dict(spec: RunSpec) -> dict:
    return {
        "scenario": spec.scenario,
        "start": spec.start,
        "mesh": spec.mesh,
        "mesh_scale": spec.mesh_scale,
        "mesh_up": spec.mesh_up,
        "overrides": list(spec.overrides),
        "config_file": spec.config_file,
        "labels": [list(x) for x in spec.labels],
    }


def table2_specs(mesh=None, mesh_scale=1.0, mesh_up="z", starts=5, overrides=()) -> list[RunSpec]:
    """The Profile row and Scenarios 1-5, each from `starts` predefined starts."""
    return [
        RunSpec(sc, k, mesh, mesh_scale, mesh_up, tuple(overrides))
        for sc in ("profile", "1", "2", "3", "4", "5")
        for k in range(starts)
    ]


#: Runs one sweep file may describe (meshes x scenarios x starts x grid values).
MAX_SWEEP_RUNS = 100_000

#: The keys of a sweep description.
SWEEP_KEYS = (
    "meshes",
    "scenarios",
    "starts",
    "grid",
    "set",
    "config",
    "out",
    "workers",
    "scheduler",
)


def sweep_specs(sweep: dict) -> list[RunSpec]:
    """Specs of a sweep description (see `nbvkit sweep --help`): meshes x scenarios x starts x
    every combination of the grid's values, with the fixed overrides in `set`."""
    unknown = set(sweep) - set(SWEEP_KEYS)
    if unknown:
        raise KeyError(f"unknown sweep key(s) {sorted(unknown)}; known: {sorted(SWEEP_KEYS)}")
    meshes = _sweep_meshes(sweep)
    scenarios = _sweep_scenarios(sweep)
    starts = _sweep_starts(sweep)
    grid, fixed = _sweep_grid(sweep)
    keys = list(grid)
    runs = len(meshes) * len(scenarios) * len(starts) * math.prod(len(grid[k]) for k in keys)
    if runs > MAX_SWEEP_RUNS:
        raise ValueError(
            f"the sweep makes {runs:,} runs (meshes x scenarios x starts x grid values), more "
            f"than the limit {MAX_SWEEP_RUNS:,}; split it into smaller sweeps"
        )
    specs = []
    for mesh in meshes:
        m = mesh if isinstance(mesh, dict) else {"path": mesh}
        for combo in itertools.product(*[grid[k] for k in keys]):
            over = fixed + [f"{k}={json.dumps(v)}" for k, v in zip(keys, combo)]
            labels = tuple((k, v) for k, v in zip(keys, combo))
            for sc in scenarios:
                for st in starts:
                    specs.append(
                        RunSpec(
                            sc,
                            int(st),
                            m.get("path"),
                            float(m.get("scale", 1.0)),
                            m.get("up", "z"),
                            tuple(over),
                            sweep.get("config"),
                            labels,
                        )
                    )
    validate_specs(specs)
    return specs


def _sweep_meshes(sweep: dict) -> list:
    """The sweep's meshes: paths, mappings (path, scale, up) or None (the shipped airliner)."""
    meshes = sweep.get("meshes") or [None]
    if not isinstance(meshes, list):
        raise ValueError(
            f"sweep 'meshes' must be a list of paths or mappings, got {shorten(meshes)}"
        )
    for m in meshes:
        if isinstance(m, dict):
            bad = set(m) - {"path", "scale", "up"}
            if bad:
                raise KeyError(
                    f"unknown key(s) {sorted(bad)} in sweep mesh entry {shorten(m)}; "
                    "known: ['path', 'scale', 'up']"
                )
            scale = m.get("scale", 1.0)
            if isinstance(scale, bool) or not isinstance(scale, (int, float)):
                raise ValueError(f"sweep mesh entry {shorten(m)}: 'scale' must be a number")
        elif m is not None and not isinstance(m, str):
            raise ValueError(f"sweep mesh entry {shorten(m)} must be a path, a mapping or null")
    return meshes


def _sweep_scenarios(sweep: dict) -> list[str]:
    scenarios = sweep.get("scenarios", ["5"])
    if not isinstance(scenarios, list):
        raise ValueError(
            f'sweep \'scenarios\' must be a list (e.g. ["1", "5"]), got {shorten(scenarios)}'
        )
    return [str(s) for s in scenarios]


def _sweep_starts(sweep: dict) -> list:
    """The sweep's start indices: a list, or a count of the five predefined starts."""
    starts = sweep.get("starts", [0])
    if isinstance(starts, int) and not isinstance(starts, bool):
        if not 0 <= starts <= 5:
            raise ValueError(f"sweep 'starts' count must be 0..5 (five predefined starts), "
                             f"got {shorten(starts)}")  # fmt: skip
        starts = list(range(starts))
    if not isinstance(starts, list) or not all(
        isinstance(s, int) and not isinstance(s, bool) for s in starts
    ):
        raise ValueError(
            f"sweep 'starts' must be a count or a list of start indices, got {shorten(starts)}"
        )
    return starts


def _sweep_grid(sweep: dict) -> tuple[dict, list]:
    """The sweep's grid (config key -> list of values) and its fixed overrides ("key=value",
    from `set`)."""
    grid = sweep.get("grid") or {}
    if not isinstance(grid, dict) or not all(isinstance(v, list) for v in grid.values()):
        raise ValueError("sweep 'grid' must map config keys to lists of values")
    fixed_set = sweep.get("set") or {}
    if not isinstance(fixed_set, dict):
        raise ValueError(
            f"sweep 'set' must map config keys to values (e.g. {{max_iterations: 200}}), "
            f"got {shorten(fixed_set)}"
        )
    return grid, [f"{k}={json.dumps(v)}" for k, v in fixed_set.items()]


def validate_specs(specs: list[RunSpec]) -> None:
    """Builds each distinct configuration once, so that a bad key or value fails before any run."""
    for s in {(sp.mesh, sp.overrides, sp.config_file) for sp in specs}:
        RunSpec("1", 0, s[0], overrides=s[1], config_file=s[2]).config()


def compare_specs(planners, mesh=None, mesh_scale=1.0, mesh_up="z", starts=5, overrides=()):
    """Every planner (scenario name) from `starts` predefined starts, with the same overrides.
    Progress coverage is sampled every 5 views (the coverage-vs-distance figure)."""
    from .scenarios import SCENARIOS

    for p in planners:
        if p not in SCENARIOS:
            raise ValueError(f"unknown planner {p!r}; known: {', '.join(SCENARIOS)}")
    over = ("evaluation.coverage_every=5", *overrides)
    return [
        RunSpec(p, k, mesh, mesh_scale, mesh_up, tuple(over))
        for p in planners
        for k in range(starts)
    ]
