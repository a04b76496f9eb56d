"""Bounds on the work a configuration asks for on the structure at hand.

``check_work``: the keys that size work (the profile flight's scans and legs, the ground-truth
samples, the observable-surface lattice, the map) are checked against the work they imply on the
structure, before the mission starts, and reported as a ValueError naming the key, the limit,
and what would fit: the same rule as the map's cell limit (``OccupancyMap``: "holds N cells, more
than the limit"). The bounds on what nbvkit reads (keys, arguments, files): nbvkit.limits. The
limits are documented in docs/HOSTILE.md ("Inputs").
"""
from __future__ import annotations

import math

from .limits import fmt_number

__all__ = [
    "MissionError",
    "check_samples",
    "check_work",
    "units_hint",
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
        f"{thing}: {key} = {fmt_number(value)} makes {n:,.0f} {unit}, more than the limit "
        f"{limit:,} (checked before any work); {fits}"
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


#: map.resolution's upper bound (mapping.MapConfig's): no resolution above it fits
MAX_RESOLUTION = 10.0


def at_least(v: float, digits: int = 3) -> str:
    """`v` (a lower bound that fits) with 1 % to spare, rounded up to `digits` significant
    digits: the value shown fits when it is given back (rounded to nearest it did not)."""
    return _rounded(v * 1.01, digits, math.ceil)


def at_most(v: float, digits: int = 4) -> str:
    """`v` (an upper bound that fits) with 1 % to spare, rounded down likewise."""
    return _rounded(v / 1.01, digits, math.floor)


def _rounded(v: float, digits: int, direction) -> str:
    if not (math.isfinite(v) and v > 0):
        return f"{v:.{digits}g}"
    q = 10.0 ** (math.floor(math.log10(v)) - digits + 1)
    return f"{direction(v / q) * q:.{digits}g}"


def check_profile(cfg, mesh_bounds, ws) -> None:
    """ValueError naming every key by which the profile flight of `cfg` round a structure with
    bounds `mesh_bounds` in workspace `ws` would take more scans, rays, legs or frames than the
    limits (MAX_PROFILE_*), each with the value of that key that would fit; the rays and legs,
    which grow with the scans, only once the scans fit."""
    p = cfg.profiling
    if not p.enabled:
        return
    w = _profile_plan(cfg, mesh_bounds, ws)
    if not w["z_max"] > w["z_min"]:
        raise ValueError(
            f"config keys 'profiling.z_min' / 'profiling.z_max': the sweeps need z_max > z_min "
            f"(null: the navigation box's {float(ws.nav_min[2]):g} / {float(ws.nav_max[2]):g} m), "
            f"got {w['z_min']:g}..{w['z_max']:g}"
        )
    if w["z_min"] < float(ws.nav_min[2]) - 1e-9:  # (the sweeps fly down to it)
        raise ValueError(
            f"config key 'profiling.z_min' = {w['z_min']:g} m lies below the navigation floor, "
            f"z = {float(ws.nav_min[2]):g} m: the height the vehicle keeps above the ground "
            "(vehicle.min_altitude, at least its collision radius + 0.1 m)"
        )
    problems: list[str] = []
    _collect(problems, _profile_scans, cfg, w, ws)
    if not problems:  # the rays and legs grow with the scans: named once those fit
        _collect(problems, _profile_rays, cfg, w)
        _collect(problems, _profile_legs, cfg, w)
    _collect(problems, _profile_frames, cfg, w)
    _raise_all(problems)


def _profile_scans(cfg, w: dict, ws) -> None:
    p = cfg.profiling
    if w["scans"] <= MAX_PROFILE_SCANS:
        return
    fit_per_sweep = MAX_PROFILE_SCANS / w["sweeps"] - 1  # scans per sweep that would fit
    nav_height = float(ws.nav_max[2] - ws.nav_min[2])
    zkeys = [k for k in ("z_max", "z_min") if getattr(p, k) is not None]
    if zkeys and w["height"] > nav_height:
        key = zkeys[0]
        fits = (
            f"a sweep of at most {at_most(fit_per_sweep * p.sweep_step)} m (z_max - z_min, now "
            f"{w['height']:.4g} m; the navigation box is {nav_height:.4g} m tall) would fit"
        )
        value = getattr(p, key)
    elif p.waypoints > 64:
        key, value = "waypoints", p.waypoints
        fits = f"profiling.waypoints <= {max(int(MAX_PROFILE_SCANS / w['per_sweep']) - 1, 1)}"
        fits += " would fit"
    else:
        key, value = "sweep_step", p.sweep_step
        fits = f"profiling.sweep_step >= {at_least(w['height'] / fit_per_sweep)} would fit"
    _refuse(_PROFILE, "laser scans", w["scans"], MAX_PROFILE_SCANS, "profiling." + key, value, fits)


def _profile_rays(cfg, w: dict) -> None:
    rays = w["scans"] * w["beams"]
    if rays > MAX_PROFILE_LASER_RAYS:
        res = cfg.laser.fov_deg / (MAX_PROFILE_LASER_RAYS / w["scans"] - 1)
        _refuse(
            _PROFILE, "laser rays", rays, MAX_PROFILE_LASER_RAYS, "laser.resolution_deg",
            cfg.laser.resolution_deg, f"laser.resolution_deg >= {at_least(res)} would fit",
        )  # fmt: skip


def _profile_legs(cfg, w: dict) -> None:
    p = cfg.profiling
    if w["legs"] > MAX_PROFILE_LEGS:
        chords = MAX_PROFILE_LEGS / 2  # chords of the curve that would fit
        if p.method != "circular" and p.margin / 2 < p.max_segment:
            key, value = "profiling.margin", p.margin  # the grown hull's chords: margin / 2
            fits = f"profiling.margin >= {at_least(2 * w['perimeter'] / chords)} would fit"
        else:
            key, value = "profiling.max_segment", p.max_segment
            fits = f"profiling.max_segment >= {at_least(w['perimeter'] / chords)} would fit"
        _refuse(_PROFILE, "legs", w["legs"], MAX_PROFILE_LEGS, key, value, fits)


def _profile_frames(cfg, w: dict) -> None:
    if w["frames"] > MAX_PROFILE_FRAMES:
        step = w["length"] / MAX_PROFILE_FRAMES
        _refuse(
            _PROFILE, "camera frames", w["frames"], MAX_PROFILE_FRAMES, "profiling.camera_step",
            cfg.profiling.camera_step,
            f"profiling.camera_step >= {at_least(step)} (or 0: none) would fit",
        )  # fmt: skip


_PROFILE = "the profile flight"


class LimitsExceeded(ValueError):
    """Several limits exceeded: `problems`, one message each; its text names them all."""

    def __init__(self, problems: list[str]):
        self.problems = problems
        n = len(problems)
        super().__init__(problems[0] if n == 1 else f"{n} limits exceeded: " + "; ".join(problems))

    def __reduce__(self):  # (from a worker process: rebuilt from its problems, not its text)
        return type(self), (self.problems,), self.__dict__  # (its notes too)


def _collect(problems: list[str], check, *args):
    """check(*args)'s result, or None with its refusals added to `problems`."""
    try:
        return check(*args)
    except ValueError as e:
        problems.extend(getattr(e, "problems", [str(e)]))


def _raise_all(problems: list[str]) -> None:
    if problems:
        raise LimitsExceeded(problems)


def check_samples(area: float, density: float, key: str, shown=None) -> None:
    """ValueError naming `key` when `density` samples per m^2 over `area` m^2 exceed
    MAX_GT_SAMPLES, with the density that would fit (`shown`: how to print the value)."""
    n = area * density
    if n > MAX_GT_SAMPLES:
        raise ValueError(
            f"the ground-truth samples: {key} = {shown or fmt_number(density)} points/m^2 on the "
            f"structure's {area:,.1f} m^2 makes {n:,.0f} samples, more than the limit "
            f"{MAX_GT_SAMPLES:,} (checked before any work); {key} <= "
            f"{at_most(MAX_GT_SAMPLES / area)} would fit"
        )


def check_gt_samples(cfg, area: float) -> float:
    """The number of ground-truth samples of the structure (area x evaluation.gt_density);
    ValueError when a density the user set makes more than MAX_GT_SAMPLES. The default density
    (null) is capped there instead (nbvkit.evaluate's max_gt_points): a large structure (the
    100 m plant: 20,415 m^2) is scored at a lower density, not refused."""
    from ._core import EvaluationOptions  # nbvkit.evaluation.DEFAULT_GT_DENSITY's source

    density = cfg.evaluation.gt_density
    used = EvaluationOptions().gt_density if density is None else density
    if area * used < 0.5:  # (the evaluator rounds the count) a structure of almost no area
        raise ValueError(
            f"the ground-truth samples: evaluation.gt_density = {fmt_number(used)} points/m^2 "
            f"{'(the default) ' if density is None else ''}on the structure's {area:.3g} m^2 "
            f"makes no sample to score against; evaluation.gt_density >= "
            f"{at_least(0.5 / area) if area > 0 else 'inf'} would make one"
        )
    if density is None:  # the default adapts: capped at MAX_GT_SAMPLES (the evaluator warns)
        return min(area * used, MAX_GT_SAMPLES)
    check_samples(area, density, "evaluation.gt_density")
    return area * density


#: a structure's observable-surface lattice holds at least this many spacings along its box's
#: diagonal, and its spacing is not under MIN_POSE_SPACING m (observability.pose_spacing is the
#: most it is)
POSES_ALONG_DIAGONAL = 16
MIN_POSE_SPACING = 0.5
#: the fine lattice is searched only where it holds at least this many times the positions of the
#: configured one (its spacing at most FINE_LATTICE_GAIN^(-1/3) of it: 0.79). One of nearly the
#: same spacing searches every unobservable sample again, the costly ones, for a handful of
#: positions between: on a 31 m office building (a 1.95 m lattice beside the 2 m one) 48 of the
#: 83 s, for 391 more observable samples of 1.95 M (0.02 %)
FINE_LATTICE_GAIN = 2.0


def _lattice_positions(size, step: float) -> int:
    """Positions of the lattice of spacing at most `step` over a box of `size`: each side split
    evenly, both faces included; a side under half the step holds one (_core.observable_samples)."""
    return math.prod(1 if s < step / 2 else math.ceil(s / step - 1e-9) + 1 for s in size)


def _lattice_fit(size, samples: float) -> tuple[float, float]:
    """(positions, spacing): the most lattice positions the limits allow with `samples` tested
    from each, and a spacing over a box of `size` whose lattice keeps within them (counted: a
    thin side's faces add a level each)."""
    fit = min(MAX_OBSERVABILITY_POSES, MAX_OBSERVABILITY_PAIRS / max(samples, 1))
    spacing = max((math.prod(size) / fit) ** (1 / 3), 1e-6)
    while _lattice_positions(size, spacing) > fit:
        spacing *= 1.02
    return fit, spacing


def pose_spacing(config, mesh_bounds, nav_size=None, samples: float = 1) -> float:
    """The spacing of the observable surface's fine lattice for a structure of bounds (lo, hi):
    its box's diagonal / POSES_ALONG_DIAGONAL, not under MIN_POSE_SPACING, nor finer than the
    limits allow over a navigation box of `nav_size` with `samples` tested; at most
    observability.pose_spacing, whose lattice is always searched too (an 8 m boat's 2 m lattice
    alone held 76 positions, and 11 % of its surface, seen by the camera in flight, counted as
    unobservable); observability.pose_spacing itself (no fine lattice) where the fine one would
    not hold FINE_LATTICE_GAIN times its positions."""
    lo, hi = mesh_bounds
    diagonal = math.dist([float(x) for x in lo], [float(x) for x in hi])
    fine = max(MIN_POSE_SPACING, diagonal / POSES_ALONG_DIAGONAL)
    if nav_size is not None:
        fit, spacing = _lattice_fit(nav_size, samples)
        while _lattice_positions(nav_size, fine) > fit:
            fine = max(fine * 1.05, spacing)
    configured = config.observability.pose_spacing
    return fine if fine <= configured * FINE_LATTICE_GAIN ** (-1 / 3) else configured


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
        fits = f"observability.pose_spacing >= {at_least(spacing)} would fit (or observability."
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

    def count(res):  # the workspace grid's cells at resolution res
        return math.prod(max(math.ceil(s / res), 1) for s in size)

    cells = count(r)
    limit = MAX_MAP_BYTES // MAP_BYTES_PER_CELL
    if cells > limit:
        need = r * (cells / limit) ** (1 / 3)
        while count(float(at_least(need))) > limit:  # counted: a thin side's cells round up
            need *= 1.01
        fit = min(float(at_least(need)), MAX_RESOLUTION)  # (the key's largest, where it fits)
        coarser = f"map.resolution >= {fit:g} would fit, or " if count(fit) <= limit else ""
        raise ValueError(
            f"the map: workspace {[round(s, 3) for s in size]} m at map.resolution = {r:g} m "
            f"holds {cells:,} cells (~{cells * MAP_BYTES_PER_CELL / 2**30:.1f} GiB), more than "
            f"the limit {limit:,} cells (checked before any work); {coarser}a smaller workspace "
            + (
                "(workspace.bounds_min / bounds_max, workspace.square=false for a long structure)"
                if cfg.workspace.bounds_min is None
                else "(workspace.bounds_min / bounds_max)"
            )
            + (
                ""
                if coarser or cfg.workspace.bounds_min is not None  # (bounds given: not the scale)
                else f", or a smaller mesh.scale (map.resolution <= {MAX_RESOLUTION:g})"
            )
        )
    return True


def check_work(cfg, mesh, ws) -> None:
    """Every work check of a mission on `mesh` (an nbvkit.Mesh) in workspace `ws`: the map's
    memory, the profile flight, the ground-truth samples and the observable-surface lattice.
    One ValueError names every limit exceeded, each with what would fit (one at a time, a user
    who followed the first hint met the next)."""
    problems: list[str] = []
    if _collect(problems, check_map, cfg, ws) is False:
        return  # beyond OctoMap's range: the map names it (and the shift that brings it near)
    _collect(problems, check_profile, cfg, mesh.bounds, ws)
    samples = _collect(problems, check_gt_samples, cfg, float(mesh.area))
    _collect(problems, check_observability, cfg, ws, MAX_GT_SAMPLES if samples is None else samples)
    _raise_all(problems)
