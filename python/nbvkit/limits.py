"""Bounds on what nbvkit reads and on the work a configuration asks for.

Three kinds of limits, all checked before any work and reported as a ValueError (or
FileNotFoundError) naming the key or the path, the limit, and what would fit:

- ``Bound``: the range of one configuration key, declared on its field (nbvkit.config); every
  integer key has a maximum, and no key takes NaN or an infinity unless it says so.
- ``check_input_file``: every file nbvkit reads (a config, a sweep, a point cloud, a mesh) must
  be a regular file (not a FIFO, a device, a socket or a directory) of at most a size per kind.
- ``check_work``: the keys that size work (the profile flight's scans and legs, the
  ground-truth samples, the observable-surface lattice, the map) are checked against the work
  they imply on the structure at hand, before the mission starts: the same rule as the map's
  cell limit (``OccupancyMap``: "holds N cells, more than the limit").

The limits are documented in docs/HOSTILE.md ("Inputs").
"""
from __future__ import annotations

import math
import numbers
import os
import stat
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = [
    "Bound",
    "MissionError",
    "check_input_file",
    "check_samples",
    "check_work",
    "require_config",
    "require_type",
    "shorten",
    "units_hint",
    "MAX_TEXT_FILE_BYTES",
    "MAX_DATA_FILE_BYTES",
    "MAX_YAML_NODES",
    "MAX_INT",
    "MAX_VIEW_RAYS",
    "MAX_GT_SAMPLES",
    "MAX_PROFILE_SCANS",
    "MAX_PROFILE_LASER_RAYS",
    "MAX_PROFILE_LEGS",
    "MAX_PROFILE_FRAMES",
    "MAX_OBSERVABILITY_POSES",
    "MAX_OBSERVABILITY_PAIRS",
    "MAX_MAP_BYTES",
]

#: Largest config or sweep file read (bytes): a configuration is a few kB.
MAX_TEXT_FILE_BYTES = 4 << 20
#: Largest mesh or point-cloud file read (bytes), as the C++ mesh loader (kMaxMeshFileBytes).
MAX_DATA_FILE_BYTES = 2 << 30
#: Largest YAML document, counted as the nodes its aliases expand to (a "billion laughs" file
#: holds a few aliases that expand to 10^9 nodes).
MAX_YAML_NODES = 100_000
#: The largest value of an integer key without a maximum of its own (C++ int).
MAX_INT = 2**31 - 1

#: Rays per candidate view of the view camera (utility.rays_x x rays_y; null: one per map cell on
#: the far plane, 47 x 34 = 1,598 at the default 8 m and 0.2 m), scored for every candidate of
#: every iteration.
MAX_VIEW_RAYS = 250_000
#: Ground-truth surface samples of a mission (area x evaluation.gt_density): ~150 bytes each over
#: the mission (points, source faces, KD-tree, coverage cells, observability); a full run of the
#: unit cube with 8 M samples peaks at 1.3 GB. The office building (5,815 m^2) at the default
#: 1000 /m^2 takes 5.8 M.
MAX_GT_SAMPLES = 8_000_000
#: Laser scans of the profile flight (profiling.waypoints sweeps of (z_max - z_min) /
#: sweep_step scans each, ~0.7 ms each): the default airliner profile takes ~2,000.
MAX_PROFILE_SCANS = 100_000
#: Laser rays of the profile flight (scans x beams per scan).
MAX_PROFILE_LASER_RAYS = 500_000_000
#: Straight legs of the profile flight (the curve round the structure in chords of at most
#: profiling.max_segment, the grown hull's of at most profiling.margin / 2, and the sweeps).
MAX_PROFILE_LEGS = 200_000
#: Camera frames of the profile flight (its length / profiling.camera_step, ~2.5 ms each).
MAX_PROFILE_FRAMES = 10_000
#: Candidate positions of the observable-surface lattice (navigation box / pose_spacing^3): each
#: takes ~1 kB while it is computed.
MAX_OBSERVABILITY_POSES = 500_000
#: Candidate positions x surface samples tested from them (the airliner at the default 2 m:
#: 8e8, ~1.5 s on 2 cores).
MAX_OBSERVABILITY_PAIRS = 10**13  # the 100 m plant at 2 m: 75,625 x 8 M = 6e11, ~29 s
#: Memory a mission's map takes (bytes): the flat workspace grid, the octree and the per-cell
#: state of the surface observations and the planners, ~50 bytes per workspace cell in a
#: mission (a 9.6 M-cell workspace: 465 MB); OccupancyMap's own limit (400 M cells) is 20 GB.
#: The airliner's default workspace holds 3.1 M cells at 0.2 m, 25 M at 0.1 m.
MAX_MAP_BYTES = 6 << 30  # 6 GiB: 129 M cells (the 100 m plant at 0.2 m: 77 M)
MAP_BYTES_PER_CELL = 50


def shorten(value, limit: int = 120) -> str:
    """repr(value), cut to about `limit` characters (messages quote what they were given, and a
    hostile value may be gigabytes long)."""
    import reprlib

    r = reprlib.Repr()
    r.maxstring = r.maxother = limit
    r.maxlist = r.maxtuple = r.maxdict = r.maxset = 8
    r.maxlevel = 3
    text = r.repr(value)
    return text if len(text) <= limit + 10 else text[:limit] + "..."


# ---------------------------------------------------------------------------- config bounds


def require_type(value, cls, what: str, name: str) -> None:
    """TypeError "`what` must be `name`, got <its type>" unless `value` is a `cls` (a class or a
    tuple of them): an argument of the Python API, checked where it is taken rather than where
    Python first reads an attribute of it."""
    if not isinstance(value, cls):
        raise TypeError(f"{what} must be {name}, got {type(value).__name__}")


def require_config(value, what: str = "config") -> None:
    """require_type for an nbvkit.Config, by the sections every reader takes (the modules below
    nbvkit.config cannot import its class)."""
    if not all(hasattr(value, s) for s in ("mesh", "camera", "workspace", "vehicle", "map")):
        raise TypeError(
            f"{what} must be an nbvkit.Config (nbvkit.load_config()), got {type(value).__name__}"
        )


def is_bool(x) -> bool:
    """Whether x is True or False, numpy's too (a string such as "no", which is true, or 0 and 1
    are not)."""
    return isinstance(x, (bool, np.bool_))


def require_bool(value, name: str) -> bool:
    """value as a bool; TypeError naming the argument `name` unless is_bool(value)."""
    if not is_bool(value):
        raise TypeError(f"{name} must be True or False, got {shorten(value)}")
    return bool(value)


def is_number(x) -> bool:
    """Whether x is a real number: an int or a float, numpy's too; not a bool (True is no 1 in
    a file or an argument; numpy's bool is no number either), not a string."""
    return isinstance(x, numbers.Real) and not isinstance(x, bool)


def _fmt(x) -> str:
    if isinstance(x, int) and not isinstance(x, bool):
        if x.bit_length() > 100:  # (str() fails past 4,300 digits)
            return f"{'-' if x < 0 else ''}~1e{int(x.bit_length() * math.log10(2))}"
        return f"{x:,}".replace(",", "_") if abs(x) >= 100_000 else str(x)
    return f"{x:g}"


@dataclass(frozen=True)
class Bound:
    """The range of a configuration key: ``lo <= value <= hi`` (``lo < value`` when `lo_open`);
    None: no bound on that side. NaN is always refused, an infinity unless `inf` (+inf allowed,
    e.g. "no limit"). `hi` of an integer key defaults to MAX_INT (see ``for_type``)."""

    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    inf: bool = False
    hi_open: bool = False  # the value must be below hi

    def describe(self) -> str:
        """The range as text: "> 0", ">= 0 and <= 1000", "1..1000", "(0.5, 1)"."""
        lo, hi = self.lo, self.hi
        if lo is not None and hi is not None and not self.lo_open and not self.hi_open:
            return f"{_fmt(lo)}..{_fmt(hi)}"
        if lo is not None and hi is not None:
            left, right = "(["[not self.lo_open], ")]"[not self.hi_open]
            return f"{left}{_fmt(lo)}, {_fmt(hi)}{right}"
        parts = []
        if lo is not None:
            parts.append(f"{'>' if self.lo_open else '>='} {_fmt(lo)}")
        if hi is not None:
            parts.append(f"{'<' if self.hi_open else '<='} {_fmt(hi)}")
        return " and ".join(parts)

    def check(self, key: str, v) -> None:
        """ValueError naming `key` unless `v` (a number or None) lies within the bound."""
        if v is None or isinstance(v, (bool, str)) or not isinstance(v, (int, float)):
            return
        if isinstance(v, float) and math.isnan(v):
            raise ValueError(f"config key {key!r} must be a finite number, got nan")
        if isinstance(v, float) and math.isinf(v) and not (self.inf and v > 0):
            raise ValueError(f"config key {key!r} must be finite, got {v!r}")
        if self.lo is not None and (v <= self.lo if self.lo_open else v < self.lo):
            what = "positive" if self.lo == 0 and self.lo_open else None
            if what is None:
                what = f"{'>' if self.lo_open else '>='} {_fmt(self.lo)}"
            raise ValueError(f"config key {key!r} must be {what}, got {_fmt(v)}")
        if self.hi is None or (self.inf and math.isinf(v)):
            return
        if self.hi_open and v >= self.hi:
            raise ValueError(f"config key {key!r} must be in {self.describe()}, got {_fmt(v)}")
        if v > self.hi:
            raise ValueError(
                f"config key {key!r} = {_fmt(v)} is more than its limit {_fmt(self.hi)} "
                f"(range {self.describe()})"
            )

    def for_type(self, tp) -> "Bound":
        """This bound, with MAX_INT as the maximum of an integer key that has none."""
        if tp is int and self.hi is None:
            return Bound(self.lo, MAX_INT, self.lo_open, self.inf, self.hi_open)
        return self


# ---------------------------------------------------------------------------- input files


def check_input_file(path, what: str = "file", max_bytes: int = MAX_DATA_FILE_BYTES) -> Path:
    """The path (expanded, as a Path) of a regular file of at most `max_bytes` bytes.

    FileNotFoundError (with the path) when it does not exist; ValueError naming `what` and the
    path for a directory, anything that is not a regular file (a FIFO would block the reader
    forever, /dev/zero never ends), a file larger than `max_bytes`, or one that cannot be
    inspected. Any path the OS accepts is taken: str, bytes (also not UTF-8) or os.PathLike."""
    try:
        name = os.fsdecode(path)
    except TypeError:
        raise TypeError(f"{what} path must be a str, bytes or os.PathLike, got {path!r}") from None
    if "\0" in name:  # (os.stat: "embedded null byte", naming nothing)
        raise ValueError(f"{what} path {name!r} holds a NUL byte: no file has such a name")
    p = Path(name).expanduser()
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise FileNotFoundError(2, f"No such {what}", str(p)) from None
    except OSError as e:
        raise ValueError(f"cannot read {what} {p}: {e.strerror or e}") from None
    if stat.S_ISDIR(st.st_mode):
        raise ValueError(f"{what} {p} is a directory, not a file")
    if not stat.S_ISREG(st.st_mode):
        kind = (
            "a FIFO (named pipe)"
            if stat.S_ISFIFO(st.st_mode)
            else "a character device"
            if stat.S_ISCHR(st.st_mode)
            else "a block device"
            if stat.S_ISBLK(st.st_mode)
            else "a socket"
            if stat.S_ISSOCK(st.st_mode)
            else "not a regular file"
        )
        raise ValueError(f"{what} {p} is {kind}: nbvkit reads regular files only")
    if st.st_size > max_bytes:
        raise ValueError(
            f"{what} {p} is {st.st_size:,} bytes, more than the {max_bytes:,} bytes nbvkit reads "
            f"as a {what}"
        )
    return p


# ---------------------------------------------------------------------------- work


class MissionError(ValueError):
    """A mission that cannot start: bad start pose, unknown option, missing stage."""


def units_hint(mesh_bounds, scale: float) -> str:
    """ "; the structure is E m across ..." for an error about a structure whose size makes a unit
    other than the metre likely (over 1 km, or under 1 m, across), naming the mesh.scale that
    flies it in metres; "" for any other size."""
    e = max(float(b) - float(a) for a, b in zip(*mesh_bounds))
    if 1.0 <= e <= 1000.0:
        return ""
    across = f"{e:,.0f}" if e > 1000.0 else f"{e:.3g}"
    hint = f"; the structure is {across} m across at mesh.scale = {scale:g} (nbvkit works in metres"
    if e > 1000.0:
        return (
            f"{hint}: if the mesh is in millimetres, mesh.scale = {scale / 1000:g} makes it "
            f"{e / 1000:,.3g} m across; in centimetres, {scale / 100:g} makes it {e / 100:,.3g} m; "
            "--mesh-scale S on the command line)"
        )
    return (
        f"{hint}: a model in another unit, or normalized to a unit size, needs the mesh.scale "
        "that gives its real size; --mesh-scale S on the command line)"
    )


def _refuse(thing: str, unit: str, n: float, limit: int, key: str, value, fits: str) -> None:
    """ValueError "THING: KEY = VALUE makes N UNIT, more than the limit L (...); FITS"."""
    raise ValueError(
        f"{thing}: {key} = {_fmt(value)} makes {n:,.0f} {unit}, more than the limit {limit:,} "
        f"(checked before any work); {fits}"
    )


def _profile_plan(cfg, mesh_bounds, ws) -> dict:
    """Upper estimates of the profile flight's work: laser scans, laser rays, legs, camera
    frames, and what each depends on."""
    p = cfg.profiling
    z_min = p.z_min if p.z_min is not None else float(ws.nav_min[2])
    z_max = p.z_max if p.z_max is not None else float(ws.nav_max[2])
    height = max(z_max - z_min, 0.0)
    b = [[float(x) for x in row] for row in mesh_bounds]
    half = [(b[1][a] - b[0][a]) / 2 for a in range(2)]
    radius = math.hypot(*half) + p.margin  # the circle round the structure
    fm = p.flight_margin
    wmin = [float(x) - fm for x in ws.bounds_min[:2]]
    wmax = [float(x) + fm for x in ws.bounds_max[:2]]
    # the curve is planned in chords round the structure (circle or grown hull, at most the
    # circle's length); it is flown clipped to the flight volume
    perimeter = 2 * math.pi * radius
    volume_perimeter = 2 * ((wmax[0] - wmin[0]) + (wmax[1] - wmin[1]))
    sweeps = p.waypoints + 1 if p.method != "bbox" else 8 + 1
    per_sweep = math.ceil(height / p.sweep_step) + 1
    scans = sweeps * per_sweep
    chord = p.max_segment if p.method == "circular" else min(p.max_segment, p.margin / 2)
    legs = perimeter / chord + sweeps * (height / p.max_segment + per_sweep + 2)
    length = min(perimeter, volume_perimeter) * 1.5 + sweeps * height + volume_perimeter
    frames = length / p.camera_step if p.camera_step > 0 else 0.0
    beams = math.floor(cfg.laser.fov_deg / cfg.laser.resolution_deg) + 1
    return dict(
        scans=scans, per_sweep=per_sweep, sweeps=sweeps, height=height, legs=legs,
        perimeter=perimeter, chord=chord, length=length, frames=frames, beams=beams,
        z_min=z_min, z_max=z_max,
    )  # fmt: skip


def check_profile(cfg, mesh_bounds, ws) -> None:
    """ValueError naming the key when the profile flight of `cfg` round a structure with
    bounds `mesh_bounds` in workspace `ws` would take more scans, rays, legs or frames than the
    limits (MAX_PROFILE_*), with the value of that key that would fit."""
    p = cfg.profiling
    if not p.enabled:
        return
    w = _profile_plan(cfg, mesh_bounds, ws)
    what = "the profile flight"
    if not w["z_max"] > w["z_min"]:
        raise ValueError(
            f"config keys 'profiling.z_min' / 'profiling.z_max': the sweeps need z_max > z_min "
            f"(null: the navigation box's {float(ws.nav_min[2]):g} / {float(ws.nav_max[2]):g} m), "
            f"got {w['z_min']:g}..{w['z_max']:g}"
        )
    if not w["z_max"] > w["z_min"]:
        raise ValueError(
            f"config keys 'profiling.z_min' / 'profiling.z_max': the sweeps need z_max > z_min "
            f"(null: the navigation box's {float(ws.nav_min[2]):g} / {float(ws.nav_max[2]):g} m), "
            f"got {w['z_min']:g}..{w['z_max']:g}"
        )
    if w["scans"] > MAX_PROFILE_SCANS:
        fit_per_sweep = MAX_PROFILE_SCANS / w["sweeps"] - 1  # scans per sweep that would fit
        nav_height = float(ws.nav_max[2] - ws.nav_min[2])
        zkeys = [k for k in ("z_max", "z_min") if getattr(p, k) is not None]
        if zkeys and w["height"] > nav_height:
            key = zkeys[0]
            fits = (
                f"a sweep of at most {fit_per_sweep * p.sweep_step:.4g} m (z_max - z_min, now "
                f"{w['height']:.4g} m; the navigation box is {nav_height:.4g} m tall) would fit"
            )
            value = getattr(p, key)
        elif p.waypoints > 64:
            key, value = "waypoints", p.waypoints
            fits = f"profiling.waypoints <= {max(int(MAX_PROFILE_SCANS / w['per_sweep']) - 1, 1)}"
            fits += " would fit"
        else:
            key, value = "sweep_step", p.sweep_step
            fits = f"profiling.sweep_step >= {w['height'] / fit_per_sweep:.3g} would fit"
        _refuse(what, "laser scans", w["scans"], MAX_PROFILE_SCANS, "profiling." + key, value, fits)
    rays = w["scans"] * w["beams"]
    if rays > MAX_PROFILE_LASER_RAYS:
        res = cfg.laser.fov_deg / (MAX_PROFILE_LASER_RAYS / w["scans"] - 1)
        _refuse(
            what, "laser rays", rays, MAX_PROFILE_LASER_RAYS, "laser.resolution_deg",
            cfg.laser.resolution_deg, f"laser.resolution_deg >= {res:.3g} would fit",
        )  # fmt: skip
    if w["legs"] > MAX_PROFILE_LEGS:
        chords = MAX_PROFILE_LEGS / 2  # chords of the curve that would fit
        if p.method != "circular" and p.margin / 2 < p.max_segment:
            key, value = "profiling.margin", p.margin  # the grown hull's chords: margin / 2
            fits = f"profiling.margin >= {2 * w['perimeter'] / chords:.3g} would fit"
        else:
            key, value = "profiling.max_segment", p.max_segment
            fits = f"profiling.max_segment >= {w['perimeter'] / chords:.3g} would fit"
        _refuse(what, "legs", w["legs"], MAX_PROFILE_LEGS, key, value, fits)
    if w["frames"] > MAX_PROFILE_FRAMES:
        step = w["length"] / MAX_PROFILE_FRAMES
        _refuse(
            what, "camera frames", w["frames"], MAX_PROFILE_FRAMES, "profiling.camera_step",
            p.camera_step, f"profiling.camera_step >= {step:.3g} (or 0: none) would fit",
        )  # fmt: skip


def check_samples(area: float, density: float, key: str, shown=None) -> None:
    """ValueError naming `key` when `density` samples per m^2 over `area` m^2 exceed
    MAX_GT_SAMPLES, with the density that would fit (`shown`: how to print the value)."""
    n = area * density
    if n > MAX_GT_SAMPLES:
        raise ValueError(
            f"the ground-truth samples: {key} = {shown or _fmt(density)} points/m^2 on the "
            f"structure's {area:,.1f} m^2 makes {n:,.0f} samples, more than the limit "
            f"{MAX_GT_SAMPLES:,} (checked before any work); {key} <= "
            f"{MAX_GT_SAMPLES / area:.4g} would fit"
        )


def check_gt_samples(cfg, area: float) -> float:
    """The number of ground-truth samples of the structure (area x evaluation.gt_density);
    ValueError when a density the user set makes more than MAX_GT_SAMPLES. The default density
    (null) is capped there instead (nbvkit.evaluate's max_gt_points): a large structure (the
    100 m plant: 20,415 m^2) is scored at a lower density, not refused."""
    from ._core import EvaluationOptions  # nbvkit.evaluation.DEFAULT_GT_DENSITY's source

    density = cfg.evaluation.gt_density
    if density is None:  # the default adapts: capped at MAX_GT_SAMPLES (the evaluator warns)
        return min(area * EvaluationOptions().gt_density, MAX_GT_SAMPLES)
    check_samples(area, density, "evaluation.gt_density")
    return area * density


#: a structure's observable-surface lattice holds at least this many spacings along its box's
#: diagonal, and its spacing is not under MIN_POSE_SPACING m (observability.pose_spacing is the
#: most it is)
POSES_ALONG_DIAGONAL = 16
MIN_POSE_SPACING = 0.5


def _lattice_positions(size, step: float) -> int:
    """Positions of the lattice of spacing `step` over a box of `size` (centre + multiples)."""
    return math.prod(2 * math.floor(s / 2 / step + 1e-9) + 1 for s in size)


def _lattice_fit(size, samples: float) -> tuple[float, float]:
    """(positions, spacing): the most lattice positions the limits allow with `samples` tested
    from each, and about the spacing over a box of `size` that keeps within them."""
    fit = min(MAX_OBSERVABILITY_POSES, MAX_OBSERVABILITY_PAIRS / max(samples, 1))
    return fit, (math.prod(size) / fit) ** (1 / 3) * 1.05


def pose_spacing(config, mesh_bounds, nav_size=None, samples: float = 1) -> float:
    """The spacing of the observable surface's fine lattice for a structure of bounds (lo, hi):
    its box's diagonal / POSES_ALONG_DIAGONAL, not under MIN_POSE_SPACING, nor finer than the
    limits allow over a navigation box of `nav_size` with `samples` tested; at most
    observability.pose_spacing, whose lattice is always searched too (an 8 m boat's 2 m lattice
    alone held 76 positions, and 11 % of its surface, seen by the camera in flight, counted as
    unobservable)."""
    lo, hi = mesh_bounds
    diagonal = math.dist([float(x) for x in lo], [float(x) for x in hi])
    fine = max(MIN_POSE_SPACING, diagonal / POSES_ALONG_DIAGONAL)
    if nav_size is not None:
        fit, spacing = _lattice_fit(nav_size, samples)
        while _lattice_positions(nav_size, fine) > fit:
            fine = max(fine * 1.05, spacing)
    return min(config.observability.pose_spacing, fine)


def check_observability(cfg, ws, samples: float) -> None:
    """ValueError when the observable-surface lattice (observability.pose_spacing over the
    navigation box) holds more than MAX_OBSERVABILITY_POSES positions, or its positions times
    the `samples` tested from them exceed MAX_OBSERVABILITY_PAIRS. (A small structure's finer
    lattice, pose_spacing, is kept within them.)"""
    o = cfg.observability
    if not o.enabled:
        return
    size = [float(b - a) for a, b in zip(ws.nav_min, ws.nav_max)]
    n = _lattice_positions(size, o.pose_spacing)
    fit, spacing = _lattice_fit(size, samples)
    if n > fit:
        if n > MAX_OBSERVABILITY_POSES:
            unit, limit, count = "candidate positions", MAX_OBSERVABILITY_POSES, n
        else:
            unit = f"tests ({n:,} candidate positions x {samples:,.0f} surface samples)"
            limit, count = MAX_OBSERVABILITY_PAIRS, n * samples
        fits = f"observability.pose_spacing >= {spacing:.3g} would fit (or observability."
        fits += "enabled=false)"
        key = "observability.pose_spacing"
        _refuse("the observable surface", unit, count, limit, key, o.pose_spacing, fits)


def check_map(cfg, ws) -> bool:
    """ValueError when the map's workspace grid would take more than MAX_MAP_BYTES (the
    structure is too large, or too long and thin in a square workspace, for the resolution).
    False (nothing checked) for a workspace beyond OctoMap's range, which OccupancyMap reports."""
    r = cfg.map.resolution
    reach = 32767 * r  # OctoMap's keys each way: beyond them OccupancyMap names the range
    if any(abs(float(x)) > reach for x in (*ws.bounds_min, *ws.bounds_max)):
        return False
    size = [float(b - a) for a, b in zip(ws.bounds_min, ws.bounds_max)]
    cells = math.prod(max(math.ceil(s / r), 1) for s in size)
    limit = MAX_MAP_BYTES // MAP_BYTES_PER_CELL
    if cells > limit:
        fit = r * (cells / limit) ** (1 / 3)
        raise ValueError(
            f"the map: workspace {[round(s, 3) for s in size]} m at map.resolution = {r:g} m "
            f"holds {cells:,} cells (~{cells * MAP_BYTES_PER_CELL / 2**30:.1f} GiB), more than "
            f"the limit {limit:,} cells (checked before any work); map.resolution >= "
            f"{fit * 1.01:.3g} would fit, or a smaller workspace (workspace.bounds_min / "
            "bounds_max, workspace.square=false for a long structure)"
        )
    return True


def check_work(cfg, mesh, ws) -> None:
    """Every work check of a mission on `mesh` (an nbvkit.Mesh) in workspace `ws`: the map's
    memory, the profile flight, the ground-truth samples and the observable-surface lattice."""
    if not check_map(cfg, ws):
        return  # beyond OctoMap's range: the map names it (and the shift that brings it near)
    check_profile(cfg, mesh.bounds, ws)
    samples = check_gt_samples(cfg, float(mesh.area))
    check_observability(cfg, ws, samples)
