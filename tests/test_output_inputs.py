"""An output file that is one of the command's own inputs, or lies in a finished run folder, is
refused before any work (nbvkit.output_paths.check_not_input): the input is left byte for byte
as it was, and the error names both paths."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from conftest import CUBE_MESH
from nbvkit.cli import main
from nbvkit.runfolder import require_complete_run, write_manifest

CUBE = CUBE_MESH
POSE = ["0", "-5", "0.5", "1.57"]
TRIANGLE_PLY = """ply
format ascii 1.0
element vertex 3
property float x
property float y
property float z
element face 1
property list uchar int vertex_indices
end_header
-1 0 0
1 0 0
0 0 1
3 0 1 2
"""


@pytest.fixture
def run_dir(tiny_cube_run):
    """A tiny finished run on the cube fixture (conftest's, shared)."""
    return tiny_cube_run


@pytest.fixture
def files(run_dir, tmp_path):
    """A copy of the run, and beside it its cloud (c.ply), the cube (m.obj) and a link to it."""
    shutil.copytree(run_dir, tmp_path / "run")
    shutil.copy(run_dir / "cloud.ply", tmp_path / "c.ply")
    shutil.copy(CUBE, tmp_path / "m.obj")
    (tmp_path / "link.obj").symlink_to(tmp_path / "m.obj")
    return tmp_path


def _refused(argv, guarded: Path, capsys, *named) -> str:
    """Runs argv, which must fail with exit 2 leaving `guarded` byte for byte as it was and
    naming each of `named` in its one-line error; returns the error."""
    before = guarded.read_bytes()
    capsys.readouterr()
    assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err
    assert guarded.read_bytes() == before
    assert err.startswith(f"nbvkit {argv[0]}: error: ") and "Traceback" not in err
    for n in named:
        assert str(n) in err, (n, err)
    return err


def test_evaluate_json_onto_the_run_summary_is_refused_and_the_run_stays_whole(files, capsys):
    run = files / "run"
    err = _refused(
        ["evaluate", run, "--json", run / "summary.json"], run / "summary.json", capsys, run
    )
    assert "run folder" in err
    require_complete_run(run)  # export and evaluate still take it
    names = sorted(p.name for p in run.iterdir())
    _refused(["evaluate", run, "--json", run / "figures" / "e.json"], run / "cloud.ply", capsys)
    assert sorted(p.name for p in run.iterdir()) == names
    assert not (run / "figures" / "e.json").exists()


@pytest.mark.parametrize("target", ["m.obj", "c.ply", "link.obj"])
def test_evaluate_json_onto_its_mesh_or_cloud_is_refused(files, capsys, target):
    guarded = files / ("c.ply" if target == "c.ply" else "m.obj")
    argv = ["evaluate", files / "c.ply", "--mesh", files / "m.obj", "--json", files / target]
    _refused(argv, guarded, capsys, files / target, guarded)


def test_evaluate_json_onto_a_mesh_given_through_a_link_is_refused(files, capsys):
    argv = ["evaluate", files / "c.ply", "--mesh", files / "link.obj", "--json", files / "m.obj"]
    _refused(argv, files / "m.obj", capsys, files / "m.obj", files / "link.obj")


def test_evaluate_json_onto_the_reference_cloud_or_the_config_is_refused(files, capsys):
    ref = files / "ref.ply"
    shutil.copy(files / "c.ply", ref)
    argv = ["evaluate", files / "c.ply", "--reference-cloud", ref, "--json", ref]
    _refused(argv, ref, capsys, ref, "reference cloud")
    cfg = files / "cfg.yaml"
    cfg.write_text("seed: 0\n")
    argv = ["evaluate", files / "c.ply", "--mesh", files / "m.obj", "--observable"]
    _refused([*argv, "--config", cfg, "--json", cfg], cfg, capsys, cfg, "configuration")


def test_evaluate_json_elsewhere_is_written(files, capsys):
    """The check refuses only inputs and run folders: a folder holding another program's
    manifest.json is no run folder."""
    (files / "other").mkdir()
    (files / "other" / "manifest.json").write_text('{"name": "not nbvkit"}\n')
    out = files / "other" / "e.json"
    argv = ["evaluate", files / "c.ply", "--mesh", files / "m.obj", "--json", out]
    assert main([str(a) for a in argv]) == 0
    assert '"coverage"' in out.read_text()


def test_scan_out_onto_its_mesh_is_refused(tmp_path, capsys):
    mesh = tmp_path / "tri.ply"
    mesh.write_text(TRIANGLE_PLY)
    argv = ["scan", "--mesh", mesh, "--pose", *POSE]
    err = _refused([*argv, "--out", mesh], mesh, capsys, mesh)
    assert "the mesh" in err
    assert main([str(a) for a in argv] + ["--out", str(tmp_path / "scan.ply")]) == 0
    assert (tmp_path / "scan.ply").stat().st_size > 0 and mesh.read_text() == TRIANGLE_PLY


def test_scan_out_into_a_run_folder_is_refused(files, capsys):
    run = files / "run"
    out = run / "scan.ply"
    argv = ["scan", "--mesh", files / "m.obj", "--pose", *POSE, "--out", out]
    _refused(argv, run / "manifest.json", capsys, out, run)
    assert not out.exists()
    require_complete_run(run)


@pytest.mark.parametrize(
    "key, value",
    [("gt_density", '"abcd"'), ("gt_density", "NaN"), ("seed", "NaN"), ("seed", "-1")],
)
def test_evaluate_names_a_run_summary_value_changed_since_the_run(files, capsys, key, value):
    """evaluate RUN scores at the run's own ground-truth density and seed (summary.json): a
    value no run records (the file changed at its size since) is named with the file and key,
    not blamed on --gt-density or --seed, which the user never gave."""
    import json
    import re

    run = files / "run"
    summary = run / "summary.json"
    text = summary.read_text()
    was = json.dumps(json.loads(text)[key])
    new = re.sub(rf'"{key}": {re.escape(was)}', f'"{key}": {value}', text, count=1)
    assert new != text
    summary.write_text(new)
    write_manifest(run)  # the manifest vouches for sizes only: as if changed at its size
    assert main(["evaluate", str(run)]) == 2
    err = capsys.readouterr().err
    assert str(summary) in err and f"'{key}'" in err and "Traceback" not in err, err


def test_evaluate_refuses_a_run_whose_mesh_file_changed_since(tmp_path, capsys):
    """evaluate RUN scored the run's cloud against its mesh file as it is now: one stretched
    since the run read 41.5 % against 84.7 %, without a word. The run records its mesh's SHA-1;
    a file changed since is refused, naming it; --mesh scores against the file given."""
    import json

    from conftest import TINY_RUN

    mesh = tmp_path / "struct.obj"
    shutil.copy(CUBE, mesh)
    run = tmp_path / "run"
    argv = ["run", "--mesh", mesh, "--out", run, *sum((["--set", o] for o in TINY_RUN), [])]
    assert main([str(a) for a in argv]) == 0
    assert len(json.loads((run / "summary.json").read_text())["mesh_sha1"]) == 40
    assert main(["evaluate", str(run)]) == 0
    with open(mesh, "a") as f:
        f.write("v 9 9 9\n")
    capsys.readouterr()
    assert main(["evaluate", str(run)]) == 2
    err = capsys.readouterr().err
    assert str(mesh) in err and "changed since" in err and "Traceback" not in err, err
    assert main(["evaluate", str(run), "--mesh", str(mesh)]) == 0
    # a run that records no SHA-1 (older runs): scored, with a word that the file is unchecked
    summary = json.loads((run / "summary.json").read_text())
    del summary["mesh_sha1"]
    (run / "summary.json").write_text(json.dumps(summary))
    write_manifest(run)
    capsys.readouterr()
    assert main(["evaluate", str(run)]) == 0
    err = capsys.readouterr().err
    assert "records no SHA-1 of its mesh" in err and str(mesh) in err, err
