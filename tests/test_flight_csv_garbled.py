"""nbvkit export of a run whose flight.csv is garbled row by row (the manifest made to match, as
after an edit): each bad row is refused with an error naming flight.csv, the row and the column,
never a traceback, a bare KeyError, or a silently wrong mission."""
from __future__ import annotations

import csv
import math
import shutil

import pytest

from nbvkit.cli import main
from nbvkit.runfolder import MANIFEST, write_manifest

ORIGIN = ["47.3977", "8.5456", "488.0"]
ROW = 2  # the flight row replaced (a profile point); line 4 of the file


@pytest.fixture
def run_dir(tiny_cube_run):
    """A tiny finished run on the cube fixture (conftest's, shared)."""
    return tiny_cube_run


def _with_row(run_dir, dst, line: str):
    """A copy of the run whose flight row ROW is the csv text `line`, its manifest rewritten
    (runfolder.write_manifest) so that the copy is a complete run again."""
    shutil.copytree(run_dir, dst)
    with open(dst / "flight.csv", newline="") as f:
        lines = f.read().split("\r\n")  # csv.writer's line ends
    assert lines[ROW + 1].startswith("profile,")
    lines[ROW + 1] = line
    with open(dst / "flight.csv", "w", newline="") as f:
        f.write("\r\n".join(lines))
    (dst / MANIFEST).unlink()
    write_manifest(dst)
    return dst


def _export(run, out, capsys):
    capsys.readouterr()
    rc = main(["export", str(run), "--origin", *ORIGIN, "--out", str(out)])
    return rc, capsys.readouterr().err


@pytest.mark.parametrize(
    "line, problem",
    [
        ("profile,1,2", "has 3 fields, its header 8 (no z, yaw, pitch, capture, distance_m)"),
        ("profile,1,1,1,0,0,,1,9", "has 9 fields, its header 8"),
        ("profile,1,1,1,0,0,maybe,1", "column capture is 'maybe', expected one of"),
        ("view,1,1,1,0,0,maybe,1", "column stage is 'view', expected one of"),
        ("zzz,1,1,1,0,0,,1", "column stage is 'zzz', expected one of 'start', 'profile', 'nbv'"),
        ("profile,1,1,1,0,50,,1", "column pitch is 50 rad, outside"),
        ("profile,1,1,1,0,-1.6,,1", "column pitch is -1.6 rad, outside"),
        ("profile,1,x,1,0,0,,1", "column y is 'x', not a finite number"),
        ("profile,1,1,inf,0,0,,1", "column z is 'inf', not a finite number"),
    ],
)
def test_a_garbled_flight_row_is_named(run_dir, tmp_path, capsys, line, problem):
    run = _with_row(run_dir, tmp_path / "run", line)
    rc, err = _export(run, tmp_path / "ex", capsys)
    assert rc == 2 and "Traceback" not in err
    assert err.startswith(f"nbvkit export: error: {run / 'flight.csv'}: row {ROW} (line 4)")
    assert problem in err
    assert not (tmp_path / "ex").exists()


def test_an_edited_but_valid_flight_row_exports(run_dir, tmp_path, capsys):
    """The control: the same edit with legal values (a pitch of exactly pi/2, a frame) exports,
    so the errors above come from the row's values, not from the edit or the manifest."""
    with open(run_dir / "flight.csv", newline="") as f:
        rows = list(csv.reader(f))
    row = rows[ROW + 1]
    row[5], row[6] = repr(math.pi / 2), "frame"
    run = _with_row(run_dir, tmp_path / "run", ",".join(row))
    rc, err = _export(run, tmp_path / "ex", capsys)
    assert rc == 0, err
    assert (tmp_path / "ex" / "export.json").is_file()
