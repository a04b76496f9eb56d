"""Shared fixtures: small analytic meshes and the optional third-party meshes in ../shared."""
from __future__ import annotations

import signal
from pathlib import Path

import numpy as np
import pytest

import nbvkit

ROOT = Path(__file__).resolve().parent.parent
SHARED_MESHES = ROOT.parent / "shared" / "meshes"

#: Config overrides that make a run (and a Table 2 row) take seconds: for tests of the plumbing.
TINY_RUN = (
    "map.resolution=0.4",
    "evaluation.gt_density=50",
    "max_iterations=2",
    "evaluation.coverage_every=1",
    "profiling.sweep_step=0.5",
    "profiling.waypoints=3",
)

CUBE_MESH = ROOT / "meshes" / "fixtures" / "cube.obj"


def as_from_a_terminal() -> None:
    """preexec_fn of a child process that a test hangs up on (SIGHUP): the signal at its default,
    as in a process a terminal started. Under `nohup pytest` the tests' own process ignores it,
    the children inherit that, and nbvkit keeps a hang-up ignored where it was (a nohup run)."""
    signal.signal(signal.SIGHUP, signal.SIG_DFL)


@pytest.fixture(scope="session")
def tiny_cube_run(tmp_path_factory):
    """A tiny finished run (`nbvkit run`, TINY_RUN, no report) on the cube fixture: read it, or
    copy it to change it."""
    from nbvkit.cli import main

    out = tmp_path_factory.mktemp("tiny_cube") / "run"
    argv = ["run", "--mesh", str(CUBE_MESH), "--no-progress", "--out", str(out), "--set"]
    assert main([*argv, *TINY_RUN, "report.enabled=false"]) == 0
    return out


#: Config overrides of a short mission on a small analytic scene (a coarse map and ground truth).
QUICK_MISSION = (
    "map.resolution=0.4",
    "progress=false",
    "evaluation.gt_density=50",
    "evaluation.coverage_every=0",
    "profiling.sweep_step=0.25",
    "symmetry.voxel_size=0.4",
)


def shared_mesh(name: str) -> Path:
    """Path of a mesh in ../shared/meshes, or skip the test when the folder is absent."""
    p = SHARED_MESHES / name
    if not p.exists():
        pytest.skip(f"{p} not available (../shared is absent on a user's fresh clone)")
    return p


def wall_mesh(x: float = 5.0, half: float = 50.0) -> nbvkit.Mesh:
    """A square wall in the plane x = `x`, spanning +-half in y and z (two triangles)."""
    v = np.array([[x, -half, -half], [x, half, -half], [x, half, half], [x, -half, half]], float)
    f = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    return nbvkit.Mesh(v, f)


def eval_cells(p, r):
    """(N, 3) integer cells of points p at cell size r as nbvkit.evaluate defines them, written
    here independently: floor(p / r), with a coordinate within 1e-9 (relative) of a cell
    boundary in the cell above."""
    q = np.asarray(p, float) / r
    c = np.floor(q)
    return (c + ((c + 1.0 - q) < 1e-9 * (np.abs(q) + 1.0))).astype(np.int64)


def box_mesh(lo, hi) -> nbvkit.Mesh:
    """An axis-aligned box [lo, hi] as 12 outward-facing triangles."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    c = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], float)
    v = lo + c * (hi - lo)
    f = np.array(
        [
            [0, 2, 1],
            [1, 2, 3],
            [4, 5, 6],
            [5, 7, 6],
            [0, 1, 4],
            [1, 5, 4],
            [2, 6, 3],
            [3, 6, 7],
            [0, 4, 2],
            [2, 4, 6],
            [1, 3, 5],
            [3, 7, 5],
        ],
        np.int32,
    )
    return nbvkit.Mesh(v, f)


def seen_box_world():
    """A World round a 6 x 6 x 5 m box at 0.4 m, which the laser and the camera have each seen
    once from the start."""
    from nbvkit.config import Config
    from nbvkit.world import World

    c = Config().with_overrides(
        ["map.resolution=0.4", "progress=false", "evaluation.gt_density=100"]
    )
    w = World(c, mesh=box_mesh([-3, -3, 0], [3, 3, 5]))
    w.take_off()
    w.sense("laser")
    w.sense("view")
    return w


@pytest.fixture
def wall():
    return wall_mesh()


@pytest.fixture
def unit_box():
    return box_mesh((0, 0, 0), (1, 1, 1))


def execute_notebook(name: str, env: dict):
    """Runs notebooks/<name> headless (no DISPLAY) with the environment variables `env` set for
    its kernel; returns the text of its code cells' outputs."""
    import os

    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    nb = nbformat.read(ROOT / "notebooks" / name, as_version=4)
    old = {k: os.environ.get(k) for k in (*env, "DISPLAY")}
    os.environ.update(env)
    os.environ.pop("DISPLAY", None)
    try:
        nbclient.NotebookClient(
            nb,
            timeout=300,
            kernel_name="python3",
            resources={"metadata": {"path": str(ROOT / "notebooks")}},
        ).execute()
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    return "".join(
        o.get("text", "") for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
    )


def plugin_fixture_file(folder, name: str, source: str, parts: dict, load: bool = False):
    """A plugin file `name` holding `source`, in `folder` (with `load`, loaded here): yielded by
    a fixture, which on teardown forgets it and the parts it registered (`parts`: {"generator" |
    "termination": [names]}), so that later tests (and the run folders their fixtures write,
    whose config.yaml would hold the parts' sections) see only the package's own parts."""
    from nbvkit import load_plugin, plugins
    from nbvkit.planning import registry

    path = folder / name
    path.write_text(source)
    if load:
        load_plugin(path)
    yield path
    for kind, names in parts.items():
        table = registry.GENERATORS if kind == "generator" else registry.TERMINATIONS
        for n in names:
            table.pop(n, None)
    if str(path.resolve()) in plugins.LOADED:
        plugins.LOADED.remove(str(path.resolve()))
