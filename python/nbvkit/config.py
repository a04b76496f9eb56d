"""Loading a mission's configuration: YAML, dotted overrides, coercion and checks.

The sections are declared by the parts that read them (nbvkit.settings): each keeps a frozen
dataclass beside its class, e.g. ``camera`` in nbvkit.sensors, ``tour`` beside the tour
generator. ``Config`` composes them: the mission's own keys, the sections of the world and its
stages, and one section per registered planner part (generator or termination; a part
registered from a script gets its section too), named like the part. Nothing here knows what a
key means beyond its type and declared range.

Scenarios (nbvkit.scenarios) are presets: resolving a configuration applies the chosen scenario's
settings to every key the user did not set (``Config.from_dict``, ``load_config`` and
``with_overrides`` all resolve). Unknown keys are rejected with the key's full dotted name; keys
renamed in this release (``RENAMED``) still work, with a DeprecationWarning.
``Config.to_dict()`` gives the resolved configuration written beside every run's results;
``configs/default.yaml`` is generated from it (``python -m nbvkit.config_docs``).
"""
from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass, field, fields, is_dataclass, replace
from pathlib import Path
from typing import Any, Optional

import yaml

from .cloud import CloudConfig
from .evaluation import EvaluationConfig
from .limits import shorten
from .mapping import MapConfig
from .mesh import MeshConfig
from .observability import ObservabilityConfig
from .planning.placement import PlacementConfig, TargetsConfig
from .planning.planner import PlannerConfig
from .planning.registry import BUILT_IN, part_settings
from .planning.scoring import UtilityConfig
from .profiling import ProfilingConfig
from .report import ReportConfig
from .scenarios import DEFAULT as DEFAULT_SCENARIO
from .scenarios import SCENARIOS
from .sensors import CAMERA_PRESETS, CameraConfig, LaserConfig, check_view_camera
from .settings import build, choice, coerce, field_bound, type_hints, unknown_key, validate
from .settings import PLUGIN_SECTIONS, within
from .symmetry import SymmetryConfig
from .workspace import WorkspaceConfig
from .world import VehicleConfig
from .yamlio import parse_yaml, read_yaml_mapping

#: Keys renamed in this release: old dotted key (or section) -> new. The old names still load,
#: with a DeprecationWarning, until the next release.
RENAMED = {
    "sampling": "lattice",  # the lattice generator's section, named like the part
    "termination": "entropy",  # the entropy termination's
    "targets.coverage_cone_deg": "utility.coverage_cone_deg",  # one cone for both
}


@dataclass(frozen=True)
class Config:
    """A mission: scenario (Table 2 row), start (0..4), NBV iteration cap, the sections of the
    world and its stages, and one section per registered planner part (``config.<name>``,
    ``section(name)``)."""

    seed: int = within(0, 0, 2**64 - 2)  # noise and sampling seed; same seed, same mission
    # a preset (nbvkit.scenarios): profile, 1..5, surface, ...
    scenario: str = choice(DEFAULT_SCENARIO, lambda: tuple(SCENARIOS))
    start: int = within(0, 0, 4)  # which of the five predefined start poses
    start_pose: Optional[tuple] = None  # (x, y, z, yaw[, pitch]) instead of a predefined start
    # planned views after the first (iterations; views = iterations + 1); null: 0.5 per m^2 of
    # surface, at least 1000
    max_iterations: Optional[int] = within(None, 0, 10**6)
    progress: bool = True  # progress bar on stderr
    # wall-clock minutes between checkpoints of a run's folder (what a kill loses at most; compare,
    # table and sweep fly a run that did not finish again instead); 0: none
    checkpoint_minutes: float = within(10.0, 0.0, 1e6)
    mesh: MeshConfig = field(default_factory=MeshConfig)
    workspace: WorkspaceConfig = field(default_factory=WorkspaceConfig)
    map: MapConfig = field(default_factory=MapConfig)
    camera: CameraConfig = field(default_factory=CameraConfig)
    laser: LaserConfig = field(default_factory=LaserConfig)
    cloud: CloudConfig = field(default_factory=CloudConfig)
    vehicle: VehicleConfig = field(default_factory=VehicleConfig)
    utility: UtilityConfig = field(default_factory=UtilityConfig)
    targets: TargetsConfig = field(default_factory=TargetsConfig)
    placement: PlacementConfig = field(default_factory=PlacementConfig)
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    profiling: ProfilingConfig = field(default_factory=ProfilingConfig)
    symmetry: SymmetryConfig = field(default_factory=SymmetryConfig)
    evaluation: EvaluationConfig = field(default_factory=EvaluationConfig)
    observability: ObservabilityConfig = field(default_factory=ObservabilityConfig)
    report: ReportConfig = field(default_factory=ReportConfig)
    # the planner parts' sections (generators, terminations: planning.registry), by name
    _parts: dict = field(default_factory=dict, repr=False, compare=False)
    # what the user set (nested dict), applied over the scenario's preset; not a key
    _user: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self):
        _check_fields(self)
        for name, cls in part_settings().items():  # every registered part's section
            self._parts.setdefault(name, cls())
        # the scenario's preset fills every key the user did not set (Config() resolves too)
        if self.scenario not in SCENARIOS:
            raise ValueError(
                f"config key 'scenario' must be one of {', '.join(SCENARIOS)}; "
                f"got {shorten(self.scenario)}"
            )
        _apply_preset(self)
        # then the named camera's keys (and its stand-off room), under what the user set
        for key, value in CAMERA_PRESETS.get(self.camera.preset, {}).items():
            if not _has_dotted(self._user, key):
                _set_field(self, key, value)
        validate(self, "")

    def __getattr__(self, name: str):
        """A planner part's section (``config.<name>``); a renamed section by its old name."""
        if name.startswith("_"):
            raise AttributeError(name)
        parts = self.__dict__.get("_parts", {})
        if name in parts:
            return parts[name]
        registered = part_settings()
        if name in registered:  # a part registered after this configuration was built
            return registered[name]()
        if name in RENAMED:
            _deprecated(name)
            return getattr(self, RENAMED[name])
        raise AttributeError(f"Config has no section {name!r}")

    def section(self, name: str):
        """The settings of the section `name` (a planner part's or any other)."""
        return getattr(self, name)

    def sections(self):
        """(name, settings) of every section, in the order of the configuration file."""
        for f in fields(self):
            if f.name.startswith("_"):
                continue
            yield f.name, getattr(self, f.name)
            if f.name == "planner":
                yield from self._parts.items()

    def check(self, key: str) -> None:
        """What spans several sections, and what a mission derives from the configuration alone
        (sensor options, the view camera), checked before any work."""
        _check_start_pose(self)
        if self.mesh.path is not None and not self.mesh.path.strip():
            raise ValueError(
                f"config key 'mesh.path' is empty ({self.mesh.path!r}): give a mesh file's path, "
                "or null (leave it out) for the shipped airliner"
            )
        if not self.planner.generators and not self.profiling.enabled:
            from .planning.registry import GENERATORS

            raise ValueError(
                "config key 'planner.generators' is empty and profiling is off "
                "(profiling.enabled = false): the mission would fly nothing; name a generator "
                f"({', '.join(GENERATORS)}) or enable profiling"
            )
        check_view_camera(self.camera, self.laser, self.utility, self.map.resolution)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_dict(cls, data: dict | None) -> "Config":
        """A configuration from a nested dict of the keys to set; the rest come from the
        scenario's preset and the defaults."""
        if data is not None and not isinstance(data, dict):  # (dict() took a list of pairs)
            raise ValueError(f"config must be a mapping of keys, got {type(data).__name__}")
        try:
            return _build_config(dict(data or {}))
        except RecursionError:  # (a traceback from the copy of what the user set)
            raise ValueError("config is nested too deeply, or holds itself") from None

    @classmethod
    def from_yaml(cls, path: str | Path) -> "Config":
        """Its errors name the file; a run folder's config.yaml names in its errors the plugin
        files the run was flown with (its summary.json's `plugins`) that this process has not
        loaded."""
        data = read_yaml_mapping(path, "config file", "for the defaults write {} in it")
        p = Path(os.fsdecode(path))
        try:
            return cls.from_dict(data)
        except (KeyError, ValueError) as e:
            from .plugins import run_plugins_hint

            hint = run_plugins_hint(p.parent)
            msg = e.args[0] if isinstance(e, KeyError) and e.args else str(e)
            msg = f"{p}: {msg}" + (f"; {hint}" if hint else "")
            raise (KeyError if isinstance(e, KeyError) else ValueError)(msg) from e

    def with_overrides(self, overrides: list[str] | dict | None) -> "Config":
        """Apply ``key=value`` strings (dotted keys for nested sections; values parsed as YAML)
        on top of what the user set so far; a new scenario brings its own preset."""
        if overrides is None:
            return self
        if isinstance(overrides, str) or not isinstance(overrides, (list, tuple, dict)):
            raise TypeError(
                "overrides must be a list of 'key=value' strings or a dict, "
                f"got {type(overrides).__name__}"
            )
        if not overrides:
            return self
        if not all(isinstance(o, str) for o in overrides):  # a dict's keys too
            raise TypeError(
                "overrides must be a list of 'key=value' strings or a dict of dotted keys, "
                f"got {shorten(next(o for o in overrides if not isinstance(o, str)))}"
            )
        items = overrides.items() if isinstance(overrides, dict) else [_split(o) for o in overrides]
        data = _deep_copy(self._user)
        for given, value in items:
            key = _renamed_key(given)
            _check_renamed_section(given, key, value)
            _check_dotted(key)
            _put_dotted(data, key, value)
        return Config.from_dict(data)

    def to_dict(self, every_part: bool = False) -> dict:
        """Every section (a run's config.yaml), less those of parts registered from a script or
        a plugin that this configuration does not fly (not in planner.generators nor
        planner.terminations) unless `every_part`: a run flown without a plugin's parts reads
        back where it is not loaded."""
        used = {*BUILT_IN, *self.planner.generators, *self.planner.terminations}
        return {
            name: _to_plain(value)
            for name, value in self.sections()
            if every_part or name not in self._parts or name in used
        }

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.to_dict(), sort_keys=False)


def _apply_preset(cfg: Config) -> None:
    """Sets the scenario's preset on every key the user did not set, then checks the sections
    it set (they were built before it: their checks, named with the scenario and its keys)."""
    name, applied = cfg.scenario, {}
    for key, value in SCENARIOS[name].settings.items():
        if _has_dotted(cfg._user, key):
            continue
        try:
            _set_field(cfg, key, value)
        except (AttributeError, KeyError, TypeError):  # a registered scenario's
            raise KeyError(
                f"scenario {name!r} sets {key!r}, which is not a config key (a part's section "
                "exists once the part is registered)"
            ) from None
        except ValueError as e:  # not of the key's type, or a section's own __post_init__
            raise ValueError(f"scenario {name!r} sets {key} = {shorten(value)}: {e}") from e
        applied.setdefault(_renamed_key(key, warn=False).split(".")[0], []).append((key, value))
    top = {f.name: f for f in fields(cfg)}
    for head, keys in applied.items():
        try:
            if head in top and not is_dataclass(getattr(cfg, head)):
                field_bound(Config, top[head]).check(head, getattr(cfg, head))
            else:
                validate(getattr(cfg, head), head + ".")
        except ValueError as e:
            sets = ", ".join(f"{k} = {shorten(v)}" for k, v in keys)
            raise ValueError(f"scenario {name!r} sets {sets}: {e}") from e


def _deprecated(old: str) -> None:
    warnings.warn(
        f"config key {old!r} is now {RENAMED[old]!r}; the old name works until the next release",
        DeprecationWarning,
        stacklevel=3,
    )


def _renamed_key(key: str, warn: bool = True) -> str:
    """A dotted key under its current name (a renamed one warns, if `warn`)."""
    for old, new in RENAMED.items():
        if key == old or key.startswith(old + "."):
            if warn:
                _deprecated(old)
            return new + key[len(old) :]
    return key


def _renamed(data: dict) -> dict:
    """A nested dict of keys with every renamed key under its current name (each warns); an old
    and a new name given together is an error."""
    out = _deep_copy(data)
    for old in RENAMED:
        if not _has_dotted(out, old):
            continue
        new = _renamed_key(old)
        if _has_dotted(out, new):
            raise ValueError(f"config keys {old!r} (renamed) and {new!r} are both set")
        *path, last = old.split(".")
        node = out
        for p in path:
            node = node[p]
        value = node.pop(last)
        _check_renamed_section(old, new, value)
        if path and not node:
            _pop_empty(out, path)
        _put_dotted(out, new, value)
    return out


def _check_renamed_section(given: str, key: str, value) -> None:
    """ValueError naming the key the user wrote (`given`, a renamed section's old name, now
    `key`) when its value is neither a mapping of the section's keys nor null."""
    if given == key or "." in key or value is None or isinstance(value, dict):
        return
    hint = type_hints(Config).get(key)
    if key in part_settings() or is_dataclass(hint):
        raise ValueError(
            f"config section {given!r} (now {key!r}) must be a mapping of its keys, "
            f"got {shorten(value)}"
        )


def _pop_empty(data: dict, path: list) -> None:
    node = data
    for p in path[:-1]:
        node = node[p]
    node.pop(path[-1])


def _build_config(data: dict) -> Config:
    if not isinstance(data, dict):
        raise ValueError("config section <root> must be a mapping")
    data = _renamed(data)
    hints = type_hints(Config)
    static = {f.name for f in fields(Config) if not f.name.startswith("_")}
    parts = part_settings()
    for k in data:
        if k not in static and k not in parts:
            raise unknown_key(str(k), static | set(parts), PLUGIN_SECTIONS)
    kwargs = {k: coerce(hints[k], v, k) for k, v in data.items() if k in static}
    sections = {k: build(cls, _or_empty(data.get(k)), k + ".") for k, cls in parts.items()}
    return Config(**kwargs, _parts=sections, _user=_deep_copy(data))


def _check_fields(cfg: Config) -> None:
    """A Config built directly (``Config(...)``, ``dataclasses.replace``) as from_dict builds
    one: each key of its type, each section of its class and checked (``Config(max_iterations=-5)``
    flew; ``Config(map=5)`` failed later on an AttributeError)."""
    hints = type_hints(Config)
    for f in fields(cfg):
        if f.name.startswith("_"):
            continue
        value, tp = getattr(cfg, f.name), hints[f.name]
        if not is_dataclass(tp):
            object.__setattr__(cfg, f.name, coerce(tp, value, f.name))
        elif isinstance(value, tp):
            validate(value, f.name + ".")
        else:
            raise ValueError(
                f"config section {f.name!r} must be a {tp.__name__} (a mapping goes to "
                f"Config.from_dict), got {shorten(value)}"
            )


def _or_empty(value):
    """A section's value: {} for null (every key its default); anything else as given (a
    non-mapping, even 0 or [], is refused by settings.build, naming the section)."""
    return {} if value is None else value


def _split(item: str) -> tuple[str, Any]:
    if "=" not in item:
        raise ValueError(f"override {shorten(item)} must look like key=value")
    key, raw = item.split("=", 1)
    key = key.strip()
    if not key:
        raise ValueError(f"override {shorten(item)} has an empty key")
    try:
        value = parse_yaml(raw) if raw.strip() else None
    except ValueError as e:
        raise ValueError(f"override {shorten(item)}: cannot parse the value: {e}") from None
    return key, value


def _set_dotted(data: dict, key: str, value: Any) -> None:
    parts = key.split(".")
    node = data
    for i, part in enumerate(parts[:-1]):
        here, where = ".".join(parts[: i + 1]), f" (in override {shorten(key)})"
        if part not in node:  # (a part's section unknown: its plugin not loaded, or misspelt)
            raise unknown_key(here, node, (PLUGIN_SECTIONS if i == 0 else "") + where)
        if not isinstance(node[part], dict):
            raise KeyError(f"config key {shorten(here)} is a value, not a section{where}")
        node = node[part]
    if parts[-1] not in node:
        raise unknown_key(key, node, "" if len(parts) > 1 else PLUGIN_SECTIONS)
    node[parts[-1]] = value


def _check_dotted(key: str) -> None:
    """KeyError naming `key` unless it is a key of the configuration."""
    _set_dotted(Config().to_dict(every_part=True), key, None)


def _put_dotted(data: dict, key: str, value: Any) -> None:
    """Sets `key` in `data`; a mapping given for a section is merged into what is set there
    (``mesh.scale=2 mesh={up: y}`` keeps the scale)."""
    parts = key.split(".")
    node = data
    for part in parts[:-1]:
        node = node.setdefault(part, {})
        if not isinstance(node, dict):
            raise ValueError(f"config key {key!r}: {part!r} is not a section")
    old = node.get(parts[-1])
    node[parts[-1]] = _merged(old, value) if isinstance(old, dict) else value


def _merged(old: dict, new: Any) -> Any:
    """`new` laid over `old`, section by section (`new` itself unless it is a mapping)."""
    if not isinstance(new, dict):
        return new
    out = _deep_copy(old)
    for k, v in new.items():
        out[k] = _merged(out[k], v) if isinstance(out.get(k), dict) else v
    return out


def _has_dotted(data: dict, key: str) -> bool:
    node = data
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            return False
        node = node[part]
    return True


def _set_field(cfg, key: str, value) -> None:
    """Sets a (nested) field of a frozen config in place, coerced to its type (presets)."""
    parts = _renamed_key(key).split(".")
    chain = [cfg]
    for part in parts[:-1]:
        chain.append(getattr(chain[-1], part))
    hint = type_hints(type(chain[-1]))[parts[-1]]
    if len(chain) == 1:
        object.__setattr__(cfg, parts[-1], coerce(hint, value, key))
        return
    new = replace(chain[-1], **{parts[-1]: coerce(hint, value, key)})
    for obj, part in zip(reversed(chain[:-1]), reversed(parts[:-1])):
        if obj is cfg:
            if part in cfg._parts:
                cfg._parts[part] = new
            else:
                object.__setattr__(cfg, part, new)
            return
        new = replace(obj, **{part: new})


def _deep_copy(d):
    return {k: _deep_copy(v) if isinstance(v, dict) else v for k, v in d.items()}


def _to_plain(obj: Any) -> Any:
    if is_dataclass(obj):
        return {
            f.name: _to_plain(getattr(obj, f.name))
            for f in fields(obj)
            if not f.name.startswith("_")
        }
    if isinstance(obj, tuple):
        return [_to_plain(x) for x in obj]
    return obj


def _check_start_pose(cfg) -> None:
    pose = cfg.start_pose
    if pose is None:
        return
    if len(pose) not in (4, 5):
        raise ValueError(
            "config key 'start_pose' must be 4 numbers (x, y, z, yaw) or 5 (x, y, z, yaw, "
            f"pitch), got {shorten(list(pose))}"
        )
    if not all(math.isfinite(x) for x in pose):
        raise ValueError(f"config key 'start_pose' must be finite numbers, got {list(pose)!r}")
    if len(pose) == 5:
        lo, hi = cfg.camera.gimbal_pitch_deg
        pitch = math.degrees(pose[4])
        if not lo - 1e-9 <= pitch <= hi + 1e-9:
            raise ValueError(
                f"config key 'start_pose': its pitch {pose[4]!r} rad ({pitch:g} deg) is "
                f"outside camera.gimbal_pitch_deg [{lo:g}, {hi:g}] deg"
            )


def load_config(
    path: str | Path | None = None, overrides: list[str] | dict | None = None
) -> Config:
    """The default configuration, updated from a YAML file and then from overrides."""
    if isinstance(path, str) and not path.strip():  # (the defaults were flown in its place)
        raise ValueError(f"config path is empty ({path!r}): give a file, or None for the defaults")
    cfg = Config.from_yaml(path) if path is not None else Config()
    return cfg.with_overrides(overrides)


if __name__ == "__main__":  # the generator of configs/default.yaml moved
    raise SystemExit("configs/default.yaml is written by: python -m nbvkit.config_docs")
