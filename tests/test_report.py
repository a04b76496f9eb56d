"""End-of-run outputs: mesh.ply and its scores, coverage.png, report.html (opened in headless
Chromium), the too-few-points case, and the experiment report."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import nbvkit

from conftest import execute_notebook
from nbvkit.report import (
    MIN_MESH_POINTS,
    coverage_classes,
    reconstruct_mesh,
    score_mesh,
    write_experiment_report,
)

ROOT = Path(__file__).resolve().parent.parent
TINY = (
    "map.resolution=0.4",
    "evaluation.gt_density=50",
    "max_iterations=3",
    "evaluation.coverage_every=1",
    "profiling.sweep_step=0.5",
    "profiling.waypoints=3",
    "report.view_points=20000",
)


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    from nbvkit.cli import main

    out = tmp_path_factory.mktemp("run") / "r"
    assert main(["run", "--scenario", "5", "--no-progress", "--set", *TINY, "--out", str(out)]) == 0
    return out


def sphere_points(n=20000, r=2.0, seed=0):
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(n, 3))
    return r * p / np.linalg.norm(p, axis=1, keepdims=True) + [0, 0, 5]


def test_poisson_reconstructs_a_sphere_and_scores_it():
    pts = sphere_points()
    mesh, info = reconstruct_mesh(pts, depth=7, viewpoints=[[0, 0, 5 + 10], [0, 0, -5], [10, 0, 5]])
    # viewpoints outside the sphere only partly surround it: orient by nearest viewpoint anyway
    assert mesh is not None, info
    assert info["triangles"] > 1000
    assert abs(info["area_m2"] - 4 * np.pi * 4) / (4 * np.pi * 4) < 0.15
    gt = sphere_points(20000, seed=1)
    s = score_mesh(mesh, gt, taus=(0.05, 0.1))
    assert s["mesh_accuracy"]["0.1"] > 0.9 and s["mesh_completeness"]["0.1"] > 0.9
    assert s["hausdorff95_m"] < 0.15
    # against an Evaluator of the same points: its kd-tree, the same scores
    assert score_mesh(mesh, nbvkit.Evaluator(gt), taus=(0.05, 0.1)) == s


def test_too_few_points_give_a_clear_message_and_no_mesh():
    mesh, info = reconstruct_mesh(sphere_points(MIN_MESH_POINTS - 1))
    assert mesh is None and f"at least {MIN_MESH_POINTS}" in info["message"]
    # non-finite rows are dropped before the count (and the finite ones are used as they are)
    pts = sphere_points(MIN_MESH_POINTS + 5)
    pts[:6, 1] = [np.nan, np.inf, -np.inf, np.nan, np.nan, np.inf]
    mesh, info = reconstruct_mesh(pts)
    assert mesh is None and f"has {MIN_MESH_POINTS - 1} points" in info["message"]


def test_coverage_classes():
    pts = np.array([[0.05, 0.05, 0.05], [1.05, 0.05, 0.05], [2.05, 0.05, 0.05]])
    cls = coverage_classes(pts, pts[:1] + 0.01, observable=[True, True, False])
    assert cls.tolist() == [0, 1, 2]
    assert coverage_classes(pts, np.zeros((0, 3))).tolist() == [1, 1, 1]
    # on a cell boundary plane (z = 12.4), a few ulps apart: one cell, as nbvkit.evaluate counts
    on = np.array([[0.31, 0.52, 12.4 - 2 * np.spacing(12.4)], [0.77, 0.12, 12.4]])
    near = on + [[0.0, 0.0, 3 * np.spacing(12.4)], [0.0, 0.0, -np.spacing(12.4)]]
    assert coverage_classes(on, near, resolution=0.05).tolist() == [0, 0]


def test_cell_keys_are_the_evaluation_cells():
    # a point at the middle of cell (i, j, k) has the key of (i, j, k), packed as the C++ core
    # packs voxels (21 bits an axis, offset by 2^20); points a few ulps either side of a boundary
    # plane share the cell above it
    r = 0.05
    ijk = np.array([[0, 0, 0], [-1, 2, 3], [1000, -2000, 7], [-(2**20), 2**20 - 1, 0]])
    k = ijk + (1 << 20)
    want = (k[:, 0] << 42) | (k[:, 1] << 21) | k[:, 2]
    assert nbvkit._core.cell_keys((ijk + 0.5) * r, r).tolist() == want.tolist()
    z = 12.4  # cell 248 at 0.05 m
    on = [[0.01, 0.01, z - 2 * np.spacing(z)], [0.01, 0.01, z], [0.01, 0.01, z + np.spacing(z)]]
    keys = nbvkit._core.cell_keys(np.array(on), r)
    assert len(set(keys.tolist())) == 1 and (int(keys[0]) & (2**21 - 1)) == 248 + (1 << 20)
    for bad, words in (([[2**20 * r + r, 0, 0]], "too far from the origin"),
                       ([[np.nan, 0, 0]], "NaN")):  # fmt: skip
        with pytest.raises(ValueError, match=words):
            nbvkit._core.cell_keys(np.array(bad), r)
    with pytest.raises(ValueError, match="positive"):
        nbvkit._core.cell_keys(np.zeros((1, 3)), 0.0)


def test_coverage_classes_refuse_points_beyond_the_grid():
    # a point past 2^20 cells from the origin has no cell of the evaluation's grid: its class
    # would alias another cell's, so the classes are refused, naming the cause
    pts = np.array([[0.05, 0.05, 0.05], [2**20 * 0.1 + 0.05, 0.05, 0.05]])
    with pytest.raises(ValueError, match="too far from the origin"):
        coverage_classes(pts, pts[:1])


def test_coverage_classes_by_slices_of_the_cloud(monkeypatch):
    # The cloud looked up a slice at a time (7 points here) gives the classes of one lookup of
    # its whole set of cells (np.isin), on points and clouds spread over negative and positive
    # coordinates.
    import nbvkit.coverage_view as cv

    rng = np.random.default_rng(3)
    pts = rng.uniform(-2, 2, (500, 3))
    cloud = np.vstack([pts[:150] + rng.normal(0, 0.03, (150, 3)), rng.uniform(-2, 2, (150, 3))])
    obs = rng.random(500) < 0.8

    def keys(p):
        k = np.floor(p / 0.1).astype(np.int64) + (1 << 20)
        return (k[:, 0] << 42) | (k[:, 1] << 21) | k[:, 2]

    want = np.where(np.isin(keys(pts), keys(cloud)), 0, 1)
    want[~obs] = 2
    monkeypatch.setattr(cv, "_SLICE", 7)
    got = cv.coverage_classes(pts, cloud, obs)
    assert got.tolist() == want.tolist() and 0 < (got == 0).sum() < (obs).sum()
    # the same cloud as SurfaceClouds read in place (slices that end inside either cloud)
    a = nbvkit._core.SurfaceCloud(voxel_size=1e-3, min_z=-10.0)
    b = nbvkit._core.SurfaceCloud(voxel_size=1e-3, min_z=-10.0)
    a.add(cloud[:100])
    b.add(cloud[100:])
    np.testing.assert_allclose(nbvkit._core.stack_points([a, b]), cloud, atol=1e-12)
    assert cv.coverage_classes(pts, [a, b], obs).tolist() == want.tolist()


def test_mesh_of_clouds_read_in_place_equals_mesh_of_their_points():
    # clouds thinned a part at a time (voxelgrid_sampling_of) and whole: the same mesh
    pts = sphere_points(12000)
    a = nbvkit._core.SurfaceCloud(voxel_size=0.01, min_z=-10.0)
    b = nbvkit._core.SurfaceCloud(voxel_size=0.02, min_z=-10.0)
    a.add(pts[:8000])
    b.add(pts[8000:])
    stacked = nbvkit._core.stack_points([a, b])
    around = [[0, 0, 15], [0, 0, -5], [10, 0, 5], [-10, 0, 5], [0, 10, 5], [0, -10, 5]]
    for max_points in (3000, 10**6):  # thinned, and kept whole
        one, info1 = reconstruct_mesh(stacked, depth=6, max_points=max_points, viewpoints=around)
        two, info2 = reconstruct_mesh([a, b], depth=6, max_points=max_points, viewpoints=around)
        assert info1 == info2 and info1["points_used"] <= max_points
        np.testing.assert_array_equal(np.asarray(one.vertices), np.asarray(two.vertices))


def test_a_run_writes_mesh_figures_and_report(tiny_run):
    s = json.loads((tiny_run / "summary.json").read_text())
    for k in ("coverage_observable", "area_coverage_observable", "observable_fraction"):
        assert set(s[k]) == {"0.05", "0.1", "0.5"}
        assert all(0 <= v <= 1 for v in s[k].values())
    # relative to a smaller ground truth, coverage can only grow
    for r in ("0.05", "0.1", "0.5"):
        assert s["area_coverage_observable"][r] >= s["area_coverage"][r] - 1e-12
    assert 0.5 < s["observable_area_fraction"] < 1.0
    assert (tiny_run / "mesh.ply").exists()
    m = s["reconstructed_mesh"]
    assert m["written"] and m["triangles"] > 0
    assert set(m["mesh_completeness"]) == {"0.05", "0.1"} and m["hausdorff95_m"] > 0
    assert (tiny_run / "figures" / "coverage.png").stat().st_size > 10000
    text = (tiny_run / "report.html").read_text()
    assert "Plotly.newPlot('view3d'" in text and "covered" in text
    assert "<script src=" not in text  # self-contained
    # the mesh's scores in % as the coverage rows beside them (they were bare fractions)
    c = m["mesh_completeness"]["0.1"]
    assert f"<td>mesh completeness @ 0.1 m</td><td>{100 * c:.2f} %</td>" in text
    assert s["finish_s"]["total"] > 0
    assert list((tiny_run / "cache").glob("observable-*.npz"))


def test_the_report_shows_the_flight_time_of_the_finished_folder(tiny_run):
    """finish_run estimates the flight from the mission in memory (the folder has no
    summary.json yet): the same section as the finished folder's estimate gives."""
    from nbvkit.export import estimate_flight
    from nbvkit.report import FLIGHT_BEGIN, FLIGHT_END, flight_section

    text = (tiny_run / "report.html").read_text()
    section = text[text.index(FLIGHT_BEGIN) : text.index(FLIGHT_END) + len(FLIGHT_END)]
    assert "estimated flight time (min)" in section
    assert section == flight_section(estimate_flight(tiny_run))


def test_an_empty_cloud_writes_everything_but_the_mesh(tmp_path, capsys):
    from nbvkit.cli import main

    out = tmp_path / "empty"
    # sensors too short to reach the structure from anywhere the vehicle flies (its collision
    # sphere is 0.8 m): the reconstruction stays empty
    assert (
        main(
            [
                "run",
                "--scenario",
                "5",
                "--no-progress",
                "--set",
                *TINY,
                "camera.max_range=0.6",
                "laser.max_range=0.3",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert "mesh.ply not written" in capsys.readouterr().out
    s = json.loads((out / "summary.json").read_text())
    assert s["cloud_points"] == 0 and not s["reconstructed_mesh"]["written"]
    assert "at least" in s["reconstructed_mesh"]["message"]
    assert not (out / "mesh.ply").exists()
    for f in ("report.html", "figures/coverage.png", "cloud.ply", "iterations.csv"):
        assert (out / f).exists(), f
    assert s["coverage_observable"]["0.05"] == 0.0


def test_experiment_report_links_each_run(tmp_path, tiny_run):
    import pandas as pd

    root = tmp_path / "exp"
    shutil.copytree(tiny_run, root / "runs" / "a")
    (root / "figures").mkdir()
    shutil.copy(tiny_run / "figures" / "coverage.png", root / "figures" / "coverage.png")
    df = pd.DataFrame(
        [
            {"run_id": "a", "scenario": "5", "coverage_0.05": 0.5},
            {"run_id": "b", "scenario": "1", "coverage_0.05": 0.25},
        ]
    )
    p = write_experiment_report(root, df, "test experiment", "| table |")
    text = p.read_text()
    assert "href='runs/a/report.html'" in text and "runs/b/report.html" not in text
    assert "data:image/png;base64," in text and "| table |" in text


def _chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        p = shutil.which(name)
        if p:
            return p
    return None


def test_report_renders_in_headless_chromium(tiny_run, tmp_path):
    exe = _chromium()
    if exe is None:
        pytest.skip("Chromium is not installed (Debian: apt-get install chromium; make deps)")
    shot = tmp_path / "shot.png"
    cmd = [
        exe,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--use-gl=swiftshader",
        "--enable-unsafe-swiftshader",
        "--enable-logging=stderr",
        "--v=0",
        "--hide-scrollbars",
        f"--user-data-dir={tmp_path / 'profile'}",
        "--window-size=1280,1800",
        "--virtual-time-budget=15000",
        f"--screenshot={shot}",
        (tiny_run / "report.html").resolve().as_uri(),
    ]
    env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=180, env=env)
    assert shot.exists(), r.stderr[-3000:]
    console = [ln for ln in r.stderr.splitlines() if "CONSOLE" in ln or "Uncaught" in ln]
    errors = [ln for ln in console if "rror" in ln or "Uncaught" in ln]
    assert errors == [], "\n".join(errors)
    import matplotlib.image as mpimg

    img = mpimg.imread(shot)[..., :3]
    # the 3D view's points: the class colours (covered green, missed red) are on screen
    green = np.array([0x2C, 0xA0, 0x2C]) / 255
    red = np.array([0xD6, 0x27, 0x28]) / 255
    near = lambda c: (np.abs(img - c).max(axis=2) < 0.12).sum()  # noqa: E731
    assert near(green) + near(red) > 500


def test_run_notebook_executes_headless(tiny_run):
    text = execute_notebook("run.ipynb", {"NBVKIT_RUN": str(tiny_run)})
    assert "showing the plotly view" in text and "observable but missed" in text


def test_a_plots_strings_cannot_end_its_script_element():
    """A trace's text is written into the page's <script> (a plugin generator's source, a file's
    name): one holding `</script>` ended the element and opened the rest as markup. Read back by
    an independent HTML parser, the page has the one script element, and its JSON the strings."""
    from html.parser import HTMLParser

    from nbvkit.htmlpage import plot_div

    hostile = "ring</script><script>document.title='pwned'</script><!-- & <b>"

    class Scripts(HTMLParser):
        def __init__(self):
            super().__init__()
            self.scripts, self.tags = [], []

        def handle_starttag(self, tag, attrs):
            self.tags.append(tag)

        def handle_data(self, data):
            if self.tags and self.tags[-1] == "script":
                self.scripts.append(data)

    page = Scripts()
    page.feed(plot_div("d", [{"type": "scatter", "text": [hostile], "name": hostile}], {}))
    assert page.tags == ["div", "script"], page.tags
    (script,) = page.scripts
    data = script.split("Plotly.newPlot('d', ", 1)[1].rsplit(", {}, {responsive", 1)[0]
    assert json.loads(data) == [{"type": "scatter", "text": [hostile], "name": hostile}]


def test_a_run_view_keeps_its_cache_in_the_run_not_two_folders_above(tiny_run, tmp_path):
    """A run of its own without a cache (observability off) had the observable surface cached
    in the folder two above it (a user's runs/myrun: the repository's root); a run inside an
    experiment (DIR/runs/RUN) uses the experiment's cache (DIR/cache)."""
    import shutil

    from nbvkit.runview import run_view

    run = tmp_path / "a" / "r"
    shutil.copytree(tiny_run, run, ignore=shutil.ignore_patterns("cache"))
    run_view(run, view_points=500)
    assert (run / "cache").is_dir() and not (tmp_path / "cache").exists()
    inside = tmp_path / "exp" / "runs" / "r"
    shutil.copytree(tiny_run, inside, ignore=shutil.ignore_patterns("cache"))
    (tmp_path / "exp" / "cache").mkdir()
    run_view(inside, view_points=500)
    assert any((tmp_path / "exp" / "cache").iterdir()) and not (inside / "cache").exists()
