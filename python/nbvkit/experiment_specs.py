"""What an experiment runs: RunSpec (one mission: a scenario from a start on a structure, with
config overrides) and the spec lists of Table 2 (table2_specs), a sweep file (sweep_specs) and a
planner comparison (compare_specs). Re-exported by nbvkit.experiments."""
from __future__ import annotations

import functools
import hashlib
import itertools
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

from .limits import is_number, shorten
from .mesh import default_mesh_path, file_up_axis


#: The mesh keys a RunSpec may give (RunSpec field -> config key).
MESH_FIELDS = (("mesh", "mesh.path"), ("mesh_scale", "mesh.scale"), ("mesh_up", "mesh.up"))


@dataclass(frozen=True)
class RunSpec:
    """One mission: a scenario from a start on a structure, with config overrides.

    The mesh flown is the resolved configuration's ``mesh`` section: the defaults (the shipped
    airliner, scale 1, up auto), then the scenario's preset (a registered one may set mesh keys),
    then the config file, then ``mesh``/``mesh_scale``/``mesh_up``
    where given (not None), then the overrides. A mesh key given both here and in the overrides
    (``--mesh X`` with ``--set mesh.path=Y``, a sweep's mesh entry with ``set``/``grid``
    ``mesh.path``) is refused: ValueError. The run id, the table's mesh columns and the resume
    digest all follow the mesh flown (``flown_mesh``)."""

    scenario: str
    start: int
    mesh: str | None = None  # None: the configuration's (the shipped airliner unless set)
    mesh_scale: float | None = None  # None: the configuration's (1 unless set)
    mesh_up: str | None = None  # None: the configuration's ("auto" unless set)
    overrides: tuple = ()  # ("key=value", ...)
    config_file: str | None = None
    labels: tuple = field(default=())  # (("name", value), ...) extra columns for the tidy table

    @property
    def run_id(self) -> str:
        path, scale, up = self.flown_mesh
        name = Path(path).stem if path else "airliner"
        h = hashlib.sha1(
            json.dumps([path, scale, up, list(self.overrides), self.config_file]).encode()
        ).hexdigest()[:8]
        return f"{name}_s{self.scenario}_start{self.start}_{h}"

    @property
    def flown_mesh(self) -> tuple:
        """(path or None for the shipped airliner, scale, up) of the resolved configuration."""
        return _flown_mesh(
            self.scenario,
            self.mesh,
            self.mesh_scale,
            self.mesh_up,
            tuple(self.overrides),
            self.config_file,
        )

    def mesh_overrides(self) -> list[str]:
        """The overrides of the mesh keys this spec gives; ValueError when the overrides give
        one of them too (mesh_overrides_once)."""
        return mesh_overrides_once(self.overrides, self.mesh, self.mesh_scale, self.mesh_up)

    def config(self):
        from .config import load_config

        over = [
            *self.overrides,
            *self.mesh_overrides(),  # after the overrides: a whole `mesh={...}` keeps them
            f"scenario={json.dumps(self.scenario)}",
            f"start={self.start}",
            "progress=false",
        ]
        return load_config(self.config_file, over)


#: The config keys RunSpec.config sets on every run itself (an override of one would be replaced,
#: the run labelled with the spec's value), and what gives them instead, by experiment. (It sets
#: progress=false too: a progress setting changes no result, and is allowed.)
SPEC_KEYS = ("scenario", "start")
_SPEC_KEYS_BY = {
    "sweep": "the sweep file's 'scenarios:' and 'starts:' lists",
    "compare": "the planners (--planners, each a scenario) and starts (--starts)",
    "table": "starts (--starts; Table 2 flies the Profile row and Scenarios 1-5 itself)",
}


def refuse_spec_keys(keys, by: str, experiment: str) -> None:
    """ValueError when one of the config `keys` (as given: dotted, or a whole override
    "key=value") is one RunSpec.config sets on every run itself (SPEC_KEYS): `by` names where
    it was given ("sweep 'grid'", "--set"), `experiment` ("sweep", "compare", "table") what
    gives it instead."""
    for k in keys:
        key = str(k).split("=", 1)[0].strip()
        if key in SPEC_KEYS:
            raise ValueError(
                f"{by} sets {key!r}, which each run of the {experiment} sets itself (the "
                f"value given there would not be the one flown): give it with "
                f"{_SPEC_KEYS_BY[experiment]}"
            )


def mesh_overrides_once(
    overrides,
    mesh=None,
    scale=None,
    up=None,
    by: str = "the spec (--mesh/--mesh-scale/--mesh-up, or a sweep's 'meshes' entry)",
) -> list[str]:
    """The overrides of the mesh keys given (not None: mesh.path, mesh.scale, mesh.up; `by`
    names where they come from); ValueError when `overrides` set one of them too (one would
    silently replace the other): nbvkit run, compare, table and sweep refuse it alike."""
    given = {
        key: value for (_, key), value in zip(MESH_FIELDS, (mesh, scale, up)) if value is not None
    }
    also = _override_mesh_keys(overrides) if given else {}
    both = [k for k in given if k in also]
    if both:
        k = both[0]
        raise ValueError(
            f"{k} is given twice: {shorten(given[k])} by {by} and {also[k]} by the overrides "
            "(--set, or a sweep's set/grid); give it once"
        )
    from .mesh import mesh_overrides

    return mesh_overrides(mesh, scale, up)


def _override_mesh_keys(overrides) -> dict:
    """{mesh key: the override setting it} of the mesh keys (mesh.path, mesh.scale, mesh.up)
    that overrides set, a whole ``mesh={...}`` included."""
    from .config import _split

    out = {}
    for o in overrides:
        key, value = _split(o)
        key = key.strip()
        if key == "mesh" and isinstance(value, dict):
            for sub in value:
                out[f"mesh.{sub}"] = o
        elif key.startswith("mesh."):
            out[key] = o
    return {k: shorten(v) for k, v in out.items()}


def with_mesh_shift(overrides, shift: list, option: str = "--mesh-shift") -> list:
    """overrides followed by `shift` (the override of --mesh-shift, or []); ValueError when the
    overrides set mesh.shift too (one would silently replace the other)."""
    if shift and "mesh.shift" in _override_mesh_keys(overrides):
        raise ValueError(
            f"mesh.shift is given twice: by {option} and by "
            f"{_override_mesh_keys(overrides)['mesh.shift']} (--set); give it once"
        )
    return [*overrides, *shift]


def _flown_mesh(scenario, mesh, scale, up, overrides: tuple, config_file) -> tuple:
    """(path or None, scale, up axis: y or z, mesh.up=auto read from the file) that a spec's
    resolved configuration flies; the configuration's part cached (the start
    does not change the mesh, nor the scenario unless its preset sets mesh keys; the config file
    by its size and time)."""
    stat = None
    if config_file is not None:
        try:
            st = Path(config_file).stat()
            stat = (st.st_size, st.st_mtime_ns)
        except OSError:
            pass
    preset = _mesh_preset(scenario)
    path, scale, up = _resolved_mesh(
        scenario if preset else "1", preset, mesh, scale, up, overrides, config_file, stat
    )
    try:  # the axis the file is turned by ("auto" read from it, now: a file may change)
        up = file_up_axis(path or default_mesh_path(), up)
    except (OSError, ValueError):
        pass  # unreadable here: the run itself names the problem
    return path, scale, up


def _mesh_preset(scenario) -> tuple:
    """The mesh keys the scenario's preset sets ((key, JSON value), ...; () for none, as every
    shipped scenario, or an unknown scenario)."""
    from .scenarios import SCENARIOS

    sc = SCENARIOS.get(scenario)
    settings = sc.settings if sc is not None else {}
    return tuple(
        (k, json.dumps(v, sort_keys=True, default=str))
        for k, v in sorted(settings.items())
        if k == "mesh" or k.startswith("mesh.")
    )


@functools.lru_cache(maxsize=65536)
def _resolved_mesh(scenario, preset, mesh, scale, up, overrides: tuple, config_file, stat):
    """_flown_mesh's answer, by the scenario's mesh `preset` and the config file's `stat` too (a
    scenario registered again, a changed file: resolved again)."""
    m = RunSpec(scenario, 0, mesh, scale, up, overrides, config_file).config().mesh
    return (m.path, float(m.scale), m.up)


def _spec_dict(spec: RunSpec) -> dict:
    """The spec as given, and the mesh it flies ("flown_mesh": path (None: the shipped airliner),
    scale, up of the resolved configuration: what the tables label the run with)."""
    path, scale, up = spec.flown_mesh
    return {
        "scenario": spec.scenario,
        "start": spec.start,
        "mesh": spec.mesh,
        "mesh_scale": spec.mesh_scale,
        "mesh_up": spec.mesh_up,
        "overrides": list(spec.overrides),
        "config_file": spec.config_file,
        "labels": [list(x) for x in spec.labels],
        "flown_mesh": {"path": path, "scale": scale, "up": up},
    }


def table2_specs(mesh=None, mesh_scale=None, mesh_up=None, starts=5, overrides=()) -> list[RunSpec]:
    """The Profile row and Scenarios 1-5, each from `starts` predefined starts (mesh, mesh_scale,
    mesh_up: None for the configuration's, see RunSpec)."""
    refuse_spec_keys(overrides, "overrides (--set)", "table")
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
    "plugins",
)


def sweep_specs(sweep: dict) -> list[RunSpec]:
    """Specs of a sweep description (see `nbvkit sweep --help`): meshes x scenarios x starts x
    every combination of the grid's values, with the fixed overrides in `set`."""
    unknown = set(sweep) - set(SWEEP_KEYS)
    if unknown:
        raise KeyError(f"unknown sweep key(s) {sorted(unknown)}; known: {sorted(SWEEP_KEYS)}")
    if sweep.get("config") is not None and not isinstance(sweep["config"], str):
        raise ValueError(
            f"sweep 'config' must be a config file's path, got {shorten(sweep['config'])}"
        )
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
                            None if m.get("scale") is None else float(m["scale"]),
                            m.get("up"),
                            tuple(over),
                            sweep.get("config"),
                            labels,
                        )
                    )
    validate_specs(specs)
    _check_distinct_runs(specs, "the sweep")
    return specs


def _duplicates(values: list) -> list:
    """The values that occur more than once in values (each once, in order; == equality, a
    bool never equal to a number)."""
    seen: list = []
    dup: list = []
    for v in values:
        k = (type(v) is bool, v)
        if k in seen:
            if k not in dup:
                dup.append(k)
        else:
            seen.append(k)
    return [v for _, v in dup]


def _refuse_duplicates(what: str, values: list) -> None:
    dup = _duplicates(values)
    if dup:
        raise ValueError(
            f"{what} lists {', '.join(shorten(v) for v in dup)} more than once: each run would "
            "be flown and counted twice; give each value once"
        )


def _refuse_empty(what: str, values: list) -> None:
    if not values:
        raise ValueError(f"{what} is empty: the sweep would fly no run; give at least one value")


def _check_distinct_runs(specs: list[RunSpec], what: str) -> None:
    """Two specs of one experiment that fly the same run (spelled differently: a mesh given as a
    path and as {path: ...}, 1 and 1.0) are refused."""
    seen: dict = {}
    for s in specs:
        first = seen.setdefault(s.run_id, s)
        if first is not s:
            raise ValueError(
                f"{what} describes the run {s.run_id} twice ({_describe(first)} and "
                f"{_describe(s)}); give each once"
            )


def _describe(spec: RunSpec) -> str:
    labels = ", ".join(f"{k}={shorten(v)}" for k, v in spec.labels)
    mesh = spec.mesh if spec.mesh is not None else "the configuration's mesh"
    return f"scenario {spec.scenario}, start {spec.start}, {mesh}" + (
        f", {labels}" if labels else ""
    )


def _sweep_meshes(sweep: dict) -> list:
    """The sweep's meshes: paths, mappings (path, scale, up; a key left out or null: the
    configuration's) or None (the configuration's mesh: the shipped airliner unless the config
    file, set or grid says otherwise)."""
    meshes = sweep.get("meshes")
    if meshes is None:
        meshes = [None]
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
            for k in ("path", "up"):
                if m.get(k) is not None and not isinstance(m[k], str):
                    raise ValueError(f"sweep mesh entry {shorten(m)}: {k!r} must be a string")
            scale = m.get("scale")
            if scale is not None and not is_number(scale):
                raise ValueError(f"sweep mesh entry {shorten(m)}: 'scale' must be a number")
        elif m is not None and not isinstance(m, str):
            raise ValueError(f"sweep mesh entry {shorten(m)} must be a path, a mapping or null")
    _refuse_empty("sweep 'meshes'", meshes)
    _refuse_duplicates("sweep 'meshes'", meshes)
    return meshes


def _sweep_scenarios(sweep: dict) -> list[str]:
    scenarios = sweep.get("scenarios", ["5"])
    if not isinstance(scenarios, list):
        raise ValueError(
            f'sweep \'scenarios\' must be a list (e.g. ["1", "5"]), got {shorten(scenarios)}'
        )
    scenarios = [str(s) for s in scenarios]
    _refuse_empty("sweep 'scenarios'", scenarios)
    _refuse_duplicates("sweep 'scenarios'", scenarios)
    _refuse_unknown("sweep scenario", scenarios, "the sweep's 'plugins' or --plugin")
    return scenarios


def _refuse_unknown(what: str, names, plugins: str) -> None:
    """ValueError naming the first of `names` that is no registered scenario (`what`: "sweep
    scenario", "planner"), the known ones, and where a plugin's scenario comes from
    (`plugins`)."""
    from .scenarios import SCENARIOS

    for s in names:
        if s not in SCENARIOS:
            raise ValueError(
                f"unknown {what} {s!r}; known: {', '.join(SCENARIOS)} (a plugin's scenario "
                f"needs its file: {plugins})"
            )


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
    _refuse_empty("sweep 'starts'", starts)
    _refuse_duplicates("sweep 'starts'", starts)
    bad = [s for s in starts if not 0 <= s <= 4]
    if bad:  # before any run (each had failed on its own)
        raise ValueError(f"sweep 'starts' are indices 0..4 (five predefined starts), got {bad}")
    return starts


def _sweep_grid(sweep: dict) -> tuple[dict, list]:
    """The sweep's grid (config key -> list of values) and its fixed overrides ("key=value",
    from `set`)."""
    grid = sweep.get("grid") or {}
    if not isinstance(grid, dict) or not all(isinstance(v, list) for v in grid.values()):
        raise ValueError("sweep 'grid' must map config keys to lists of values")
    refuse_spec_keys(grid, "sweep 'grid'", "sweep")
    for k, values in grid.items():
        _refuse_empty(f"sweep grid {k!r}", values)
        _refuse_duplicates(f"sweep grid {k!r}", values)
    fixed_set = sweep.get("set") or {}
    if not isinstance(fixed_set, dict):
        raise ValueError(
            f"sweep 'set' must map config keys to values (e.g. {{max_iterations: 200}}), "
            f"got {shorten(fixed_set)}"
        )
    refuse_spec_keys(fixed_set, "sweep 'set'", "sweep")
    return grid, override_strings(fixed_set)


def override_strings(overrides) -> list[str]:
    """Config overrides as RunSpec holds them, "key=value" strings: a list of them as it is, a
    {key: value} dict's values written as JSON (which the configuration reads back as YAML), None
    as none. TypeError for anything else, or a value JSON cannot write."""
    if isinstance(overrides, dict):
        out = []
        for k, v in overrides.items():
            try:  # numpy numbers and arrays as their lists
                out.append(f"{k}={json.dumps(v, default=lambda o: o.tolist(), allow_nan=False)}")
            except (AttributeError, TypeError, ValueError):
                raise TypeError(f"overrides {k!r}: {shorten(v)} is not a YAML value") from None
        return out
    if overrides is None or (
        isinstance(overrides, (list, tuple)) and all(isinstance(o, str) for o in overrides)
    ):
        return list(overrides or ())
    raise TypeError(
        f"overrides must be a list of 'key=value' strings or a dict, got {shorten(overrides)}"
    )


def validate_specs(specs: list[RunSpec]) -> None:
    """Builds each distinct configuration once, so that a bad key or value (a mesh key given
    twice, a registered scenario's preset naming a missing key or part) fails before any run."""
    from .scenarios import BUILT_IN

    for s in {
        (sp.scenario, sp.mesh, sp.mesh_scale, sp.mesh_up, tuple(sp.overrides), sp.config_file)
        for sp in specs
    }:
        _flown_mesh(*s)  # (which builds a scenario without mesh keys as Scenario 1)
    for sp in {sp.scenario: sp for sp in specs if sp.scenario not in BUILT_IN}.values():
        sp.config()  # a scenario of the user's: its preset, once (nbvkit's own are checked)


def compare_specs(planners, mesh=None, mesh_scale=None, mesh_up=None, starts=5, overrides=()):
    """Every planner (scenario name) from `starts` predefined starts, with the same overrides
    (mesh, mesh_scale, mesh_up: None for the configuration's, see RunSpec). Progress coverage is
    sampled every 5 views (the coverage-vs-distance figure). A planner named twice is refused
    (ValueError): its runs would be counted twice."""
    _refuse_unknown("planner", planners, "--plugin or nbvkit.load_plugin")
    # as a sweep's lists: the runs of different planners differ by their scenario in the run
    # id, so this also keeps two specs from flying the same run (_check_distinct_runs)
    _refuse_duplicates("planners (--planners)", list(planners))
    refuse_spec_keys(overrides, "overrides (--set)", "compare")
    over = ("evaluation.coverage_every=5", *overrides)
    return [
        RunSpec(p, k, mesh, mesh_scale, mesh_up, tuple(over))
        for p in planners
        for k in range(starts)
    ]
