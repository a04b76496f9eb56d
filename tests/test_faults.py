"""Faults (issue 36): run folders that are whole or say they are not, write errors that raise,
and an API that is safe from several threads. Real subprocesses for kills, full disks and
shared folders; the fuller battery is bench/fault_battery.py (its table: docs/HOSTILE.md)."""
from __future__ import annotations

import json
import os
import random
import re
import shutil
import signal
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

import nbvkit
from nbvkit.runfolder import (
    MANIFEST,
    IncompleteRunError,
    RunFolder,
    is_complete_run,
    require_complete_run,
)

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))

import fault_battery as fb  # noqa: E402


def _ok(result):
    bad, note = result
    assert bad is None, bad
    return note


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory):
    """One complete tiny run folder made by `nbvkit run` (and its wall time)."""
    out = tmp_path_factory.mktemp("faults") / "base"
    t0 = time.perf_counter()
    rc, _, err = fb.run(fb.run_argv(out))
    assert rc == 0, err
    return out, time.perf_counter() - t0


# ------------------------------------------------------------------------ the run folder


def test_a_run_folder_is_complete_and_consistent(finished_run):
    out, _ = finished_run
    assert fb.run_problems(out) == []
    manifest = json.loads((out / MANIFEST).read_text())
    assert {"summary.json", "cloud.ply", "map.ot", "config.yaml"} <= set(manifest["files"])
    assert not any(k.startswith("cache/") for k in manifest["files"])
    assert fb.leftovers(out) == []
    assert require_complete_run(out) == out


def test_incomplete_folders_are_refused_with_the_reason(tmp_path, finished_run):
    out = tmp_path / "r"
    shutil.copytree(finished_run[0], out)
    (out / "iterations.csv").write_text("iteration\n")  # changed since the run wrote it
    with pytest.raises(IncompleteRunError, match="damaged iterations.csv"):
        require_complete_run(out)
    # a manifest vouching for a file outside the folder (another run's): no run writes one
    other = tmp_path / "other"
    shutil.copytree(finished_run[0], other)
    manifest = json.loads((other / MANIFEST).read_text())
    manifest["files"] = {"../r/summary.json": (out / "summary.json").stat().st_size}
    (other / MANIFEST).write_text(json.dumps(manifest))
    with pytest.raises(IncompleteRunError, match=r"listing \.\./r/summary.json, outside"):
        require_complete_run(other)
    (out / MANIFEST).unlink()
    with pytest.raises(ValueError, match="has no manifest.json"):
        require_complete_run(out)
    with pytest.raises(ValueError, match="does not exist"):
        require_complete_run(tmp_path / "nope")
    assert not is_complete_run(out)
    # an experiment's folder given for one of its runs (it said "did not finish ... run it again")
    (tmp_path / "cmp" / "runs").mkdir(parents=True)
    with pytest.raises(IncompleteRunError, match=r"an experiment's folder .* give one of them"):
        require_complete_run(tmp_path / "cmp")
    from nbvkit.paths import require_complete_run as public

    assert public is require_complete_run


@pytest.mark.parametrize("text", ["{not json", "[1, 2]", "\udcff"])
def test_a_damaged_summary_is_named_by_every_reader(tmp_path, finished_run, capsys, text):
    """A summary.json that is not a JSON object (garbled, a list, not UTF-8) is named by each
    reader of run folders - export, evaluate, the experiments' rows, the notebook's look - with a
    clear ValueError; the plugin hint, a best effort, gives nothing. Its size kept, so the
    manifest still holds: only reading it tells."""

    from nbvkit.cli import main
    from nbvkit.experiment_tables import row_of
    from nbvkit.export.plan import read_run
    from nbvkit.plugins import run_plugins_hint
    from nbvkit.runfolder import read_summary

    out = tmp_path / "r"
    shutil.copytree(finished_run[0], out)
    f = out / "summary.json"
    whole = f.read_bytes()
    data = text.encode("utf-8", "surrogateescape")
    f.write_bytes(data + b" " * (f.stat().st_size - len(data)))
    assert is_complete_run(out)
    why = "not JSON" if text != "[1, 2]" else "not a JSON object"
    for read in (read_summary, read_run, row_of):
        with pytest.raises(ValueError, match=f"run summary {f}.* is damaged.*{why}"):
            read(out)
    assert main(["evaluate", str(out)]) == 2
    assert f"{f} is damaged" in capsys.readouterr().err
    assert run_plugins_hint(out) == ""
    with pytest.raises(FileNotFoundError, match="No such run summary"):
        read_summary(tmp_path)
    f.unlink()
    f.mkdir()  # a folder, or a device, is named, not read
    with pytest.raises(ValueError, match="run summary .*summary.json is a directory"):
        read_summary(out)
    f.rmdir()
    f.write_text("[" * 3 + " " * (5 << 20) + "]" * 3)  # too large to be nbvkit's
    with pytest.raises(ValueError, match="run summary .* bytes, more than the"):
        read_summary(out)
    f.write_bytes(whole)
    (out / "spec.json").write_text("{garbled")
    with pytest.raises(ValueError, match="run spec .*spec.json is damaged, not JSON"):
        row_of(out)


def test_a_failing_run_leaves_nothing_and_the_old_run_stays(tmp_path, finished_run):
    out = tmp_path / "r"
    shutil.copytree(finished_run[0], out)
    before = (out / "summary.json").read_bytes()
    with pytest.raises(RuntimeError, match="boom"):
        with RunFolder(out, overwrite=True) as rf:
            (rf.tmp / "summary.json").write_text("{}")
            raise RuntimeError("boom")
    assert (out / "summary.json").read_bytes() == before
    assert is_complete_run(out)
    assert fb.leftovers(out) == []
    # an overwrite replaces it whole: no old file stays
    with RunFolder(out, overwrite=True) as rf:
        (rf.tmp / "summary.json").write_text("{}")
    assert sorted(os.listdir(out)) == ["cache", MANIFEST, "summary.json"]  # the cache is carried
    assert fb.leftovers(out) == []


def test_checkpoints_are_complete_runs_put_in_place_until_the_run_is(tmp_path, finished_run):
    """RunFolder.checkpoint puts a complete folder in place while the run goes on; one whose
    writing fails leaves the last in place; the run's own commit replaces them, and nothing is
    left beside the target. Over a complete run (--overwrite) they go beside it, in
    r.interrupted, and the old run stays until the new one is whole (a kill after a checkpoint
    replaced a finished run with a few views of the new one)."""

    from nbvkit.runfolder import _problem

    def checkpoint_of(k):
        def write(folder):
            (folder / "summary.json").write_text(json.dumps({"k": k}))

        return write

    def kept(where):
        return json.loads((where / "summary.json").read_text())

    def whole(where):  # as a reader finds it once the run's lock is gone (a kill drops it)
        return _problem(where, check_lock=False) is None

    for over_a_run in (False, True):
        out = tmp_path / "r"
        shutil.rmtree(out, ignore_errors=True)
        if over_a_run:
            shutil.copytree(finished_run[0], out)
        old = None if not over_a_run else (out / "summary.json").read_bytes()
        at = out if not over_a_run else tmp_path / "r.interrupted"
        with RunFolder(out, overwrite=True) as rf:
            rf.checkpoint(checkpoint_of(1))
            assert "being written" in _problem(out)  # while the run goes on, readers wait
            assert whole(at) and kept(at) == {"k": 1} and rf.placed == at
            if over_a_run:
                assert (out / "summary.json").read_bytes() == old and whole(out)
            rf.checkpoint(checkpoint_of(2))
            assert kept(at) == {"k": 2}

            def full_disk(folder):
                checkpoint_of(3)(folder)
                raise OSError(28, "No space left on device")

            with pytest.raises(OSError, match="No space"):
                rf.checkpoint(full_disk)
            assert whole(at) and kept(at) == {"k": 2}  # the last one stays
            assert [x.name for x in tmp_path.glob(".r.ckpt*")] == []
            (rf.tmp / "summary.json").write_text(json.dumps({"k": "final"}))
        assert is_complete_run(out) and kept(out) == {"k": "final"} and rf.placed == out
        assert sorted(x.name for x in tmp_path.iterdir()) == ["r"]


def test_a_stopped_run_over_a_complete_run_goes_beside_it(tmp_path, finished_run):
    """--overwrite of a complete run by a run that is stopped (Ctrl-C, an error, the end-of-run
    outputs failing: RunFolder.partial): the old run stays whole with its cache, what the new
    one flew is put beside it in the first free of r.interrupted, r.interrupted<pid>, ... (what
    an earlier stopped run left there, or a file of that name, is kept); where no such folder
    can be made (a name too long), it is kept in its temporary folder, which `placed` names."""

    out = tmp_path / "r"
    shutil.copytree(finished_run[0], out)
    (out / "cache").mkdir(exist_ok=True)
    old = (out / "summary.json").read_bytes()

    def stopped(target, text):
        with RunFolder(target, overwrite=True) as rf:
            (rf.tmp / "summary.json").write_text(text)
            rf.partial = True
        return rf

    first = stopped(out, '{"k": 1}')
    assert first.placed == tmp_path / "r.interrupted" and is_complete_run(first.placed)
    second = stopped(out, '{"k": 2}')
    assert second.placed == tmp_path / f"r.interrupted{os.getpid()}"
    assert json.loads((tmp_path / "r.interrupted" / "summary.json").read_text()) == {"k": 1}
    assert (out / "summary.json").read_bytes() == old and is_complete_run(out)
    assert (out / "cache").is_dir()  # the kept run keeps its cache
    shutil.rmtree(second.placed)
    shutil.rmtree(tmp_path / "r.interrupted")
    (tmp_path / "r.interrupted").write_text("mine")  # a file of that name
    assert stopped(out, "{}").placed == tmp_path / f"r.interrupted{os.getpid()}"
    assert (tmp_path / "r.interrupted").read_text() == "mine"
    # a name too long for "<name>.interrupted": kept where it was written, not lost
    long = tmp_path / ("n" * 245)
    shutil.copytree(finished_run[0], long)
    rf = stopped(long, '{"k": 3}')
    assert rf.placed == rf.tmp and json.loads((rf.tmp / "summary.json").read_text()) == {"k": 3}
    assert is_complete_run(long)
    # a fresh target takes a stopped run in place
    rf = stopped(tmp_path / "new", "{}")
    assert rf.placed == tmp_path / "new" and is_complete_run(tmp_path / "new")


def test_overwrite_removes_only_what_a_run_wrote(tmp_path, finished_run):
    """--overwrite refuses a folder holding a file its manifest does not list (figures/mine.png),
    a folder of nbvkit's names without a manifest (a user's config.yaml and report.html), and a
    folder holding the run's own mesh or configuration file; nothing is removed."""

    run = tmp_path / "run"
    shutil.copytree(finished_run[0], run)
    (run / "figures").mkdir(exist_ok=True)
    (run / "figures" / "mine.png").write_bytes(b"x")
    with pytest.raises(ValueError, match=r"files nbvkit did not write \(figures/mine.png\)"):
        RunFolder(run, overwrite=True).__enter__()
    assert (run / "figures" / "mine.png").exists()
    (run / "figures" / "mine.png").unlink()
    with pytest.raises(ValueError, match="holds this run's input .*config.yaml"):
        RunFolder(run, overwrite=True, inputs=(run / "config.yaml",)).__enter__()
    (tmp_path / "link").symlink_to(tmp_path)  # the folder reached through a symlinked parent
    with pytest.raises(ValueError, match="holds this run's input .*config.yaml"):
        RunFolder(
            tmp_path / "link" / "run", overwrite=True, inputs=(run / "config.yaml",)
        ).__enter__()
    manifest = (run / MANIFEST).read_text()
    (run / MANIFEST).write_text('{"files": [')  # damaged: nothing tells its files apart
    with pytest.raises(ValueError, match="no readable manifest.json"):
        RunFolder(run, overwrite=True).__enter__()
    with RunFolder(run, overwrite=True, own=True) as rf:  # an experiment's runs/: replaced
        rf.cancel()
    (run / MANIFEST).write_text(manifest)
    user = tmp_path / "user"
    user.mkdir()
    (user / "config.yaml").write_text("seed: 3  # mine\n")
    (user / "report.html").write_text("<html>")
    with pytest.raises(ValueError, match="no readable manifest.json .not a run folder"):
        RunFolder(user, overwrite=True).__enter__()
    assert (user / "config.yaml").read_text() == "seed: 3  # mine\n"
    # a killed export's temporary folder (its process gone) does not block it; a live one does
    import subprocess

    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (run / f".nbvkit-export-{dead.pid}-0a1b2c3d4e5f").mkdir()
    (run / f".nbvkit-export-{dead.pid}-0a1b2c3d4e5f" / "mission.plan").write_text("{}")
    (run / f".nbvkit-export-{os.getpid()}-0a1b2c3d4e5f").mkdir()
    with pytest.raises(ValueError, match=f"did not write \\(.nbvkit-export-{os.getpid()}-"):
        RunFolder(run, overwrite=True).__enter__()
    (run / f".nbvkit-export-{os.getpid()}-0a1b2c3d4e5f").rmdir()
    with RunFolder(run, overwrite=True) as rf:  # the run's own files alone: replaced
        (rf.tmp / "summary.json").write_text("{}")
    assert is_complete_run(run) and not any(x.name.startswith(".nbvkit") for x in run.iterdir())


def test_a_mount_point_is_refused_before_any_work(monkeypatch, tmp_path, mount_ok):
    """A target that is a mount point (a container's volume): the rename onto it at the end
    fails (EBUSY), which lost a whole mission; refused by name at the start (a real tmpfs where
    this test may mount one, else os.path.ismount saying so), and so is an export into it."""
    import subprocess

    target = tmp_path / "vol"
    target.mkdir()
    if mount_ok:
        subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", target], check=True)
    else:
        real = os.path.ismount
        monkeypatch.setattr(os.path, "ismount", lambda p: os.fspath(p) == str(target) or real(p))
    try:
        with pytest.raises(ValueError, match="is a mount point.*give a folder inside it"):
            RunFolder(target)
        from nbvkit.output_paths import check_output_dir

        with pytest.raises(ValueError, match="is a mount point"):
            check_output_dir(target, "output folder", whole_folder=True)
    finally:
        if mount_ok:
            subprocess.run(["umount", target], check=True)
    if mount_ok:  # a bind mount of a folder on the same file system (os.path.ismount: False)
        (tmp_path / "src").mkdir()
        subprocess.run(["mount", "--bind", tmp_path / "src", target], check=True)
        try:
            (tmp_path / "link").symlink_to(target)
            for p in (target, tmp_path / "link"):
                with pytest.raises(ValueError, match="is a mount point"):
                    RunFolder(p)
                with pytest.raises(ValueError, match="is a mount point"):
                    check_output_dir(p, "output folder", whole_folder=True)
        finally:
            subprocess.run(["umount", target], check=True)


def test_checkpoints_change_nothing_in_the_flight(tmp_path, monkeypatch):
    """A mission checkpointed after every view flies exactly as one without checkpoints (their
    summaries drop the planner's memos: the same answers without them); one whose checkpoints
    cannot be written (a full disk) warns and flies on to its own results."""
    from conftest import TINY_RUN
    from nbvkit.config import load_config

    def fly(minutes, out):
        over = [*TINY_RUN, "max_iterations=6", "progress=false", f"checkpoint_minutes={minutes}"]
        s = nbvkit.Mission(load_config(overrides=over)).run(out)
        return s, (out / "trajectory.csv").read_text()

    s0, flight0 = fly(0, tmp_path / "none")
    s1, flight1 = fly(1e-9, tmp_path / "each")
    assert s1["checkpoints"] == s1["iterations"] > 2 and s0["checkpoints"] == 0
    assert flight1 == flight0
    same = ("views", "distance_m", "entropy_final", "coverage", "area_coverage", "cloud_points")
    assert {k: s1[k] for k in same} == {k: s0[k] for k in same}

    def full_disk(self, write):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(RunFolder, "checkpoint", full_disk)
    with pytest.warns(RuntimeWarning, match="checkpoint not saved, the flight goes on: .*space"):
        s2, flight2 = fly(1e-9, tmp_path / "full")
    assert flight2 == flight0 and s2["checkpoints"] == 0 and is_complete_run(tmp_path / "full")


def test_two_runs_on_one_folder_cannot_both_succeed(tmp_path):
    out = tmp_path / "x"
    with RunFolder(out, what="--out"):
        with pytest.raises(ValueError, match="being written by another nbvkit run"):
            RunFolder(out, what="--out").__enter__()
        with pytest.raises(IncompleteRunError, match="being written by an nbvkit run"):
            require_complete_run(out)
    assert is_complete_run(out) and fb.leftovers(out) == []  # no lock file stays
    with pytest.raises(ValueError, match="already holds a complete run.*--overwrite"):
        RunFolder(out).__enter__()


def _count_under_lock(path: str, counter: str, times: int) -> None:
    from nbvkit.locks import FileLock

    for _ in range(times):
        with FileLock(path):
            n = int(Path(counter).read_text())  # read, wait, write: lost updates unless held
            time.sleep(0.001)
            Path(counter).write_text(str(n + 1))


def test_a_lock_removed_by_its_holder_still_excludes(tmp_path):
    """FileLock removes its file before letting go; processes that opened the old file meanwhile
    lock the name again, so 4 processes x 40 read-modify-writes under it lose none, and no
    lock file is left."""
    import multiprocessing

    from nbvkit.locks import FileLock

    lock, counter = tmp_path / ".x.lock", tmp_path / "n"
    counter.write_text("0")
    ctx = multiprocessing.get_context("spawn")
    procs = [
        ctx.Process(target=_count_under_lock, args=(str(lock), str(counter), 40)) for _ in "abcd"
    ]
    for p in procs:
        p.start()
    for p in procs:
        p.join(120)
    assert [p.exitcode for p in procs] == [0, 0, 0, 0]
    assert counter.read_text() == "160" and not lock.exists()
    held = FileLock(lock)
    assert held.acquire(wait=False) and FileLock(lock).acquire(wait=False) is False
    assert held.holder() == f"pid {os.getpid()}"
    held.release()
    assert not lock.exists()


def test_cli_two_runs_at_once_and_a_rerun(tmp_path):
    _ok(fb.shared_case(tmp_path))
    _ok(fb.rerun_case(tmp_path))


def test_python_api_refuses_a_folder_with_another_run(tmp_path):
    from nbvkit.config import load_config

    cfg = load_config(overrides=[*fb.TINY, "scenario=1", "progress=false"])
    out = tmp_path / "api"
    nbvkit.Mission(cfg).run(out)
    assert is_complete_run(out)
    with pytest.raises(ValueError, match="already holds a complete run"):
        nbvkit.Mission(cfg).run(out)
    nbvkit.Mission(cfg).run(out, overwrite=True)
    assert is_complete_run(out)


def test_a_run_with_its_end_of_run_outputs_is_one_complete_folder(tmp_path):
    from nbvkit.config import load_config

    cfg = load_config(overrides=[*fb.TINY, "scenario=1", "progress=false"])
    out = tmp_path / "f"
    summary = nbvkit.Mission(cfg).run(out, finish=True)
    assert fb.run_problems(out) == []
    # summary.json is written once, with the end-of-run figures in it
    assert json.loads((out / "summary.json").read_text())["finish_s"] == summary["finish_s"]
    assert (out / "report.html").exists()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_kill_at_a_random_moment_then_the_same_command_gives_one_complete_run(
    tmp_path, finished_run, seed
):
    delay = random.Random(seed).uniform(0.05, 1.05) * finished_run[1]
    _ok(fb.kill_case(tmp_path, delay, overwrite=seed != 2))


def test_evaluate_refuses_an_incomplete_run_folder(tmp_path, finished_run):
    _ok(fb.reader_case(tmp_path, finished_run[0]))


def test_a_damaged_cache_file_is_recomputed(tmp_path, finished_run):
    _ok(fb.bad_cache_case(tmp_path, finished_run[0]))


def test_a_damaged_cache_file_is_recomputed_in_python(tmp_path, unit_box):
    from nbvkit.observability import observable_surface

    cfg = nbvkit.Config().with_overrides(["evaluation.gt_density=50"])
    a = observable_surface(unit_box, cfg, cache_dir=tmp_path)
    (entry,) = tmp_path.glob("observable-*.npz")
    for damage in (b"", b"PK\x03\x04garbage", entry.read_bytes()[:100]):
        entry.write_bytes(damage)
        b = observable_surface(unit_box, cfg, cache_dir=tmp_path)
        assert not b.cached
        assert (a.observable == b.observable).all()
    assert observable_surface(unit_box, cfg, cache_dir=tmp_path).cached
    assert not list(tmp_path.glob("*.tmp*"))


# ------------------------------------------------------------------------ full disks


@pytest.fixture(scope="module")
def mount_ok():
    return fb.can_mount_tmpfs()


@pytest.mark.parametrize("size", ["64k", "1m", "4m"])
def test_a_full_disk_leaves_no_summary_claiming_a_finished_run(tmp_path, mount_ok, size):
    """A full disk leaves no folder, or (4 MB: the flight's files fit, the report does not) the
    whole flight kept without its end-of-run outputs, summary.json saying saving stopped."""
    note = _ok(fb.disk_full_case(tmp_path, size, mount_ok))
    assert note != "fitted", f"{size} held the whole run: the test tried nothing"


def test_map_save_on_a_full_disk_raises_and_leaves_no_file(mount_ok):
    _ok(fb.map_save_full_case(mount_ok))


def test_write_errors_raise(tmp_path):
    """Every output writer raises on a write error (here: a folder that is not there)."""
    from nbvkit.cloud import write_points

    missing = tmp_path / "gone" / "x"
    m = nbvkit.OccupancyMap(0.5, (0, 0, 0), (2, 2, 2))
    with pytest.raises(FileNotFoundError):
        m.save(str(missing) + ".ot")
    with pytest.raises(OSError):
        write_points(str(missing) + ".ply", np.zeros((3, 3)))
    if Path("/dev/full").exists():  # a file on a full disk: the error names it
        full = tmp_path / "full.ply"
        full.symlink_to("/dev/full")
        with pytest.raises(OSError, match=f"No space left on device: '{full}'"):
            write_points(full, np.zeros((3, 3)))


def test_a_write_that_does_not_fit_names_the_file_and_leaves_none(tmp_path):
    """evaluate --json and scan --out past the file-size limit (as a full disk: the write fails):
    the error names the file; the JSON, written whole or not at all, is not there."""
    import subprocess

    cube_obj = ROOT / "meshes" / "fixtures" / "cube.obj"
    np.save(tmp_path / "c.npy", np.random.default_rng(0).uniform(0, 1, (50, 3)))
    for args, out in (
        (["evaluate", "--mesh", cube_obj, tmp_path / "c.npy", "--json"], tmp_path / "e.json"),
        (["scan", "--mesh", cube_obj, "--pose", "-3", "0.5", "0.5", "0", "--out"],
         tmp_path / "s.ply"),  # fmt: skip
    ):
        p = subprocess.run(
            [sys.executable, "-m", "nbvkit.cli", *map(str, args), str(out)],
            capture_output=True, text=True, timeout=120, env=fb._env(),
            preexec_fn=fb._fsize_limit(256),
        )  # fmt: skip
        assert p.returncode == 2, p.stderr
        assert f"File too large: '{out}'" in p.stderr.strip().splitlines()[-1], p.stderr
        if out.suffix == ".json":
            assert not out.exists() and not list(tmp_path.glob(".e.json.tmp*"))


def test_evaluate_json_into_a_pipe_or_the_shells_stdout_file_keeps_everything(tmp_path):
    """evaluate --json /dev/stdout: into a pipe the JSON arrives (no temporary file beside a
    pipe can be renamed over it), and into the file the shell redirected stdout to, the table
    printed before it stays (a rename would have replaced the file)."""
    import subprocess

    cube_obj = ROOT / "meshes" / "fixtures" / "cube.obj"
    np.save(tmp_path / "c.npy", np.random.default_rng(0).uniform(0, 1, (50, 3)))
    cmd = [sys.executable, "-m", "nbvkit.cli", "evaluate", "--mesh", str(cube_obj)]
    cmd += [str(tmp_path / "c.npy"), "--json", "/dev/stdout"]
    env = {k: v for k, v in fb._env().items() if k != "PYTHONUNBUFFERED"}  # stdout buffered
    piped = subprocess.run(cmd, capture_output=True, text=True, timeout=120, env=env)
    assert piped.returncode == 0, piped.stderr
    log = tmp_path / "log.txt"
    with open(log, "w") as f:
        p = subprocess.run(cmd, stdout=f, stderr=subprocess.PIPE, text=True, timeout=120,
                           env=env)  # fmt: skip
    assert p.returncode == 0, p.stderr
    for text in (piped.stdout, log.read_text()):
        lines = text.splitlines()
        start, end = lines.index("{"), lines.index("}")
        data = json.loads("\n".join(lines[start : end + 1]))
        assert data["cloud_path"] == str(tmp_path / "c.npy") and "covered_cells" in data
        assert any("ground-truth file" in ln for ln in lines[:start])  # the table before it


# ------------------------------------------------------------------------ threads


def test_scanning_while_another_thread_changes_the_thread_count():
    _ok(fb.python_case(fb.THREADS_SCAN.format(seconds=2)))


def test_two_missions_in_two_threads_match_serial_runs():
    _ok(fb.python_case(fb.THREADS_2M.format(over=fb.TINY)))


def test_integrate_on_one_map_from_several_threads_matches_serial():
    _ok(fb.python_case(fb.THREADS_MAP.format(trials=3)))


def test_a_mission_run_twice_gives_a_fresh_missions_result():
    _ok(fb.python_case(fb.MISSION_TWICE.format(over=fb.TINY)))


def test_a_mission_running_in_one_thread_refuses_a_second_run():
    code = """
    import threading, time, nbvkit
    from nbvkit.config import load_config
    m = nbvkit.Mission(load_config(overrides=list({over!r}) + ["scenario=1", "progress=false"]))
    t = threading.Thread(target=m.run)
    t.start()
    while not m._running.locked():
        time.sleep(0.001)
    try:
        m.run()
    except RuntimeError as e:
        assert "already running" in str(e)
        print("refused")
    t.join()
    """
    assert _ok(fb.python_case(textwrap.dedent(code).format(over=fb.TINY))) == "refused"


# ------------------------------------------------------------------------ a flight stopped

STOPPING_PART = """
import os
import sys
import shutil
import signal
import time
from dataclasses import dataclass

import nbvkit
from nbvkit.settings import choice, within


@dataclass(frozen=True)
class StopAtConfig:
    views: int = within(3, 1, 1000)  # views flown before the part stops the flight
    # as Ctrl-C, as a part's bug, as a `kill` (SIGTERM to this process) or a hang-up (SIGHUP)
    how: str = choice("interrupt", ("interrupt", "error", "sigterm", "sighup", "exit", "sigkill"))


class StopAt:
    Settings = StopAtConfig

    def __init__(self, settings, context):
        self.s = settings

    def check(self, world, step):
        if world.state.views >= self.s.views:
            if self.s.how == "interrupt":
                raise KeyboardInterrupt
            if self.s.how == "exit":
                sys.exit(3)  # a part that ends the process
            if self.s.how == "sigkill":  # as the out-of-memory killer: no handler runs
                os.kill(os.getpid(), signal.SIGKILL)
            if self.s.how in ("sigterm", "sighup"):
                os.kill(os.getpid(), signal.Signals[self.s.how.upper()])
                time.sleep(5)  # the handler raises here
            raise ZeroDivisionError("a part's bug, as asked")
        return None


nbvkit.register_termination("stop_at", StopAt)
"""


@pytest.fixture(scope="module")
def stopping_part(tmp_path_factory):
    """A plugin file registering the termination `stop_at`, loaded once (a part registers once)
    and forgotten after this module's tests."""
    from conftest import plugin_fixture_file

    folder = tmp_path_factory.mktemp("plugin")
    parts = {"termination": ["stop_at"]}
    yield from plugin_fixture_file(folder, "stopping_part.py", STOPPING_PART, parts, load=True)


def _stopping(how: str, views: int = 3) -> list[str]:
    from conftest import TINY_RUN

    return [
        *TINY_RUN,
        "max_iterations=20",
        "planner.terminations=[stop_at, budget]",
        f"stop_at.views={views}",
        f"stop_at.how={how}",
        "progress=false",
    ]


@pytest.mark.parametrize(
    "how, cause",
    [("interrupt", KeyboardInterrupt), ("error", ZeroDivisionError), ("exit", SystemExit)],
)
def test_a_flight_stopped_by_ctrl_c_or_a_part_keeps_what_it_flew(
    tmp_path, stopping_part, how, cause
):
    """Mission.run(out_dir): Ctrl-C or a part's error after the views started writes what was
    flown (a whole run folder, its termination "interrupted" or "failed", the cause named), then
    raises the same exception; stopped during the profile, nothing is written."""
    from nbvkit.config import load_config

    out = tmp_path / "run"
    with pytest.raises(cause):
        nbvkit.Mission(load_config(overrides=_stopping(how))).run(out)
    assert is_complete_run(out)
    s = json.loads((out / "summary.json").read_text())
    assert s["termination"] == ("failed" if how == "error" else "interrupted")
    assert s["stopped_by"].startswith(cause.__name__) and not s["stopped_by_budget"]
    assert s["views"] == 3 and s["iterations"] >= 2  # the first view, then two chosen ones
    assert s["area_coverage"]["0.05"] > 0  # scored: the cloud of what was flown
    rows = (out / "iterations.csv").read_text().strip().splitlines()
    assert len(rows) - 1 == s["iterations"]
    assert (out / "cloud.ply").stat().st_size > 0 and (out / "trajectory.csv").exists()
    # a rerun into it says what it holds (it said "a complete run")
    said = rf"already holds a run that was stopped \(termination {s['termination']}: what it flew"
    with pytest.raises(ValueError, match=said):
        RunFolder(out).__enter__()
    # stopped during the profile, before the views: nothing is written
    early = tmp_path / "early"

    def profile(self):
        raise cause

    mission = nbvkit.Mission(load_config(overrides=_stopping(how)))
    mission._profile = profile.__get__(mission)
    with pytest.raises(cause):
        mission.run(early)
    assert not early.exists()


@pytest.mark.parametrize(
    "how, said",
    [
        ("interrupt", r"interrupted: saving what was flown \(Ctrl-C again drops it\)"),
        ("exit", r"interrupted \(SystemExit: 3; plugin file .*stopping_part\.py, line \d+, in"),
        ("error", r"failed \(ZeroDivisionError: a part's bug, as asked; raised by the termination"),
    ],
)
def test_the_console_names_what_stopped_a_flight(tmp_path, stopping_part, capsys, how, said):
    """The console's line as a stopped flight is saved names the cause, and says "Ctrl-C again"
    only after a Ctrl-C: a part's sys.exit() is not reported as if the user had pressed it."""
    from nbvkit.config import load_config

    config = load_config(overrides=[*_stopping(how), "progress=true"])
    with pytest.raises((KeyboardInterrupt, SystemExit, ZeroDivisionError)):
        nbvkit.Mission(config).run(tmp_path / "run")
    err = capsys.readouterr().err
    assert re.search(said, err), err
    assert err.count("saving what was flown (Ctrl-C") == 1
    assert ("again" in err) == (how == "interrupt")


@pytest.mark.parametrize("how", ["interrupt", "sigterm", "sighup"])
def test_nbvkit_run_stopped_says_where_what_it_flew_is(tmp_path, stopping_part, how):
    """Ctrl-C, a `kill` (SIGTERM, as a batch scheduler's time limit sends) or a hang-up (SIGHUP:
    the terminal closed) during the views of `nbvkit run` (its own process): what was flown is
    saved, the console says where, and the exit code is 130."""
    import subprocess

    from conftest import as_from_a_terminal

    out = tmp_path / "run"
    argv = ["run", "--plugin", str(stopping_part), "--out", str(out), "--set", *_stopping(how, 2)]
    p = subprocess.run(
        [sys.executable, "-m", "nbvkit.cli", *argv],
        capture_output=True,
        text=True,
        timeout=300,
        env=dict(os.environ, MPLBACKEND="Agg"),
        preexec_fn=as_from_a_terminal,
    )
    assert p.returncode == 130, (p.returncode, p.stderr)
    # counted as the summary counts: 1 planned view (iterations), 2 views with the first
    said = "the flight stopped after 1 iteration (2 views: the first, where the camera stage"
    assert said in p.stderr and f"saved in {out}/" in p.stderr
    assert "interrupted" in p.stderr and "Traceback" not in p.stderr
    assert "termination: interrupted" in p.stdout and "area cov." in p.stdout  # what it flew
    assert is_complete_run(out)
    s = json.loads((out / "summary.json").read_text())
    assert s["termination"] == "interrupted"
    named = f"Terminated: {how.upper()}" if how.startswith("sig") else "KeyboardInterrupt"
    assert s["stopped_by"].startswith(named)  # a kill is not recorded as a Ctrl-C


def test_nbvkit_run_stopped_by_a_parts_exit_names_it(tmp_path, stopping_part):
    """A part's sys.exit(3) during `nbvkit run`: the console's "flight stopped" line names it
    (the command prints no error line below for an exit: a line pointing "below" left the
    cause unsaid), what was flown is saved, and the process exits 3."""
    import subprocess

    out = tmp_path / "run"
    argv = ["run", "--plugin", str(stopping_part), "--out", str(out), "--set", *_stopping("exit")]
    p = subprocess.run([sys.executable, "-m", "nbvkit.cli", *argv], capture_output=True,
                       text=True, timeout=300, env=dict(os.environ, MPLBACKEND="Agg"))  # fmt: skip
    assert p.returncode == 3, (p.returncode, p.stderr)
    assert re.search(r"the flight stopped after .*\(SystemExit: 3; plugin file .*stopping_part",
                     p.stderr), p.stderr  # fmt: skip
    assert is_complete_run(out)


def test_a_script_killed_keeps_what_it_flew(tmp_path, stopping_part):
    """A script's Mission.run(out) stopped by a `kill` (SIGTERM: a batch scheduler's time
    limit) keeps what was flown, as `nbvkit run` does (it lost the whole flight: the default
    handler ended the process); the signal's default comes back after the run."""
    import subprocess

    out = tmp_path / "run"
    script = textwrap.dedent(
        f"""
        import signal, nbvkit
        nbvkit.load_plugin({str(stopping_part)!r})
        cfg = nbvkit.load_config(overrides={_stopping("sigterm", 2)!r})
        try:
            nbvkit.Mission(cfg).run({str(out)!r})
        except KeyboardInterrupt as e:
            print(type(e).__name__, signal.getsignal(signal.SIGTERM) is signal.SIG_DFL)
        """
    )
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert p.stdout.split() == ["Terminated", "True"], (p.returncode, p.stderr[-2000:])
    s = json.loads((out / "summary.json").read_text())
    assert is_complete_run(out) and s["termination"] == "interrupted"
    assert s["stopped_by"].startswith("Terminated: SIGTERM")


def test_a_kill_while_a_run_is_put_in_place_comes_after_it(tmp_path):
    """A script's kill (the default handler: the process ends) arriving while a whole run is
    renamed into place ended the process there, the run left in its temporary folder; it is
    held until the run is in place (interrupts.signals_held), then ends the process."""
    import subprocess

    from conftest import TINY_RUN

    out = tmp_path / "run"
    script = textwrap.dedent(
        f"""
        import os, signal, nbvkit
        from nbvkit.runfolder import RunFolder
        place = RunFolder._place
        def killed_while_placing(self, src, dst):
            os.kill(os.getpid(), signal.SIGTERM)
            return place(self, src, dst)
        RunFolder._place = killed_while_placing
        cfg = nbvkit.load_config(overrides={[*TINY_RUN, "progress=false"]!r})
        nbvkit.Mission(cfg).run({str(out)!r})
        print("not reached")
        """
    )
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert p.returncode == -signal.SIGTERM and "not reached" not in p.stdout, p.stderr[-2000:]
    assert is_complete_run(out) and not list(tmp_path.glob(".run.tmp*"))


def test_a_kill_held_while_placing_a_run_fails_still_ends_the_process():
    """A kill held by signals_held is raised again however its body ends: an OSError while the
    run is put in place (a full disk) dropped it, and the killed process flew on."""
    import subprocess

    script = textwrap.dedent(
        """
        import os, signal
        from nbvkit.interrupts import signals_held
        try:
            with signals_held():
                os.kill(os.getpid(), signal.SIGTERM)
                raise OSError("disk full while placing the run")
        except OSError:
            pass
        print("not reached")
        """
    )
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert p.returncode == -signal.SIGTERM and "not reached" not in p.stdout, p.stderr[-2000:]


def _nbvkit_cli(*argv):
    """`python -m nbvkit.cli ARGV` in its own process (a signal there is not this one's)."""
    import subprocess

    return subprocess.run(
        [sys.executable, "-m", "nbvkit.cli", *argv],
        capture_output=True,
        text=True,
        timeout=300,
        env=dict(os.environ, MPLBACKEND="Agg"),
    )


def test_a_killed_run_leaves_its_last_checkpoint(tmp_path, stopping_part):
    """SIGKILL during the views (as the out-of-memory killer sends: no handler runs, nothing is
    saved at the end): `nbvkit run` leaves its last checkpoint, a complete run folder of what was
    flown until it, that says it is one and that evaluate reads; without checkpoints the same
    kill leaves nothing. The next run on the folder replaces it, leaving nothing beside it."""
    from nbvkit.recorder import CHECKPOINT_STOP

    runs = {}
    for minutes in ("0", "1e-9"):  # none; one after every view
        out = runs[minutes] = tmp_path / f"run{minutes}"
        over = [*_stopping("sigkill", 4), f"checkpoint_minutes={minutes}"]
        p = _nbvkit_cli("run", "--plugin", str(stopping_part), "--out", str(out), "--set", *over)
        assert p.returncode == -signal.SIGKILL, (p.returncode, p.stderr)
    assert not runs["0"].exists()  # killed before its own save: nothing in place
    out = runs["1e-9"]
    require_complete_run(out)
    s = json.loads((out / "summary.json").read_text())
    assert s["checkpoint"] is True and s["stopped_by"] == CHECKPOINT_STOP
    with pytest.raises(ValueError, match="already holds a checkpoint of a run that was killed"):
        RunFolder(out).__enter__()
    assert s["termination"] == "interrupted" and s["stopped_during"] == "flight"
    assert s["views"] == 4 and s["checkpoints"] == s["iterations"] - 1  # this one not counted
    rows = (out / "iterations.csv").read_text().strip().splitlines()
    assert len(rows) - 1 == s["iterations"]
    assert s["area_coverage"]["0.05"] > 0 and (out / "map.ot").stat().st_size > 0
    scored = tmp_path / "scored.json"
    density = ["--gt-density", "50", "--seed", str(s["seed"])]  # as the run scored it
    p = _nbvkit_cli("evaluate", "--mesh", s["mesh"], *density, str(out), "--json", str(scored))
    assert p.returncode == 0, p.stderr
    assert json.loads(scored.read_text())["coverage"] == pytest.approx(s["coverage"])
    # the next run on it: in place whole, no checkpoint or temporary folder left beside it
    over = [*_stopping("error", 100), "checkpoint_minutes=1e-9", "max_iterations=3"]
    argv = ["run", "--plugin", str(stopping_part), "--out", str(out), "--overwrite", "--set"]
    assert _nbvkit_cli(*argv, *over).returncode == 0
    s = json.loads((out / "summary.json").read_text())
    assert "checkpoint" not in s and s["termination"] == "max_iterations"
    assert [x.name for x in tmp_path.glob(f".{out.name}*")] == []


def test_a_run_stopped_over_a_complete_run_keeps_it(tmp_path, stopping_part):
    """`nbvkit run --overwrite` over a complete run, stopped by a `kill` (SIGTERM) after
    checkpoints: the old run stays whole and unchanged; what the new one flew is a complete run
    in NAME.interrupted, which the console names. Before, the stopped run (and each checkpoint)
    took the old run's place. A whole rerun then replaces the old run; NAME.interrupted, what a
    run flew, stays until the user removes it."""
    out = tmp_path / "run"
    base = ["run", "--plugin", str(stopping_part), "--out", str(out), "--set"]
    whole = [*_stopping("error", 100), "max_iterations=2", "report.enabled=false"]
    assert _nbvkit_cli(*base, *whole).returncode == 0
    old = (out / "summary.json").read_bytes()
    stop = [*_stopping("sigterm", 3), "checkpoint_minutes=1e-9"]
    p = _nbvkit_cli(*base[:-1], "--overwrite", "--set", *stop)
    assert p.returncode == 130, p.stderr
    assert (out / "summary.json").read_bytes() == old and is_complete_run(out)
    beside = tmp_path / "run.interrupted"
    assert f"saved in {beside}/" in p.stderr
    s = json.loads((beside / "summary.json").read_text())
    assert is_complete_run(beside) and s["termination"] == "interrupted" and s["views"] == 3
    # its export says it flies part of a mission
    plugin = ["--plugin", str(stopping_part)]
    ex = ["--origin", "47.4", "8.5", "400", "--out", str(beside.parent / "ex")]
    p = _nbvkit_cli("export", str(beside), *plugin, *ex)
    assert (
        p.returncode == 0
        and "nbvkit export: warning: the run was stopped after 3 views" in p.stderr
    )
    ev = ["--mesh", s["mesh"], "--gt-density", "50", "--json", str(tmp_path / "ev.json")]
    p = _nbvkit_cli("evaluate", str(beside), *plugin, *ev)
    assert (
        p.returncode == 0
        and "nbvkit evaluate: warning: the run was stopped after 3 views" in p.stderr
    )
    said = json.loads((tmp_path / "ev.json").read_text())["warnings"]  # the file says so too
    assert len(said) == 1 and said[0].startswith("the run was stopped after 3 views")
    assert _nbvkit_cli(*base[:-1], "--overwrite", "--set", *whole).returncode == 0
    assert (out / "summary.json").read_bytes() != old and is_complete_run(beside)


@pytest.mark.skipif(sys.version_info < (3, 11), reason="exception notes: Python 3.11+")
@pytest.mark.parametrize(
    "how", ["full_disk", "full_disk_at_the_manifest", "second_ctrl_c", "second_ctrl_c_scoring"]
)
def test_a_flight_that_could_not_be_saved_says_so_and_what_its_folder_holds(
    tmp_path, monkeypatch, capsys, stopping_part, how
):
    """The run's own save failing (a full disk: writing its files, or its manifest as it is put
    in place) or stopped (a second Ctrl-C while what a first one stopped is scored or saved)
    after checkpoints: the error says the flight was not saved and that the folder holds its last
    checkpoint, which reads as killed (it said only "No space left on device", or
    "interrupted"); the command line prints that under the error."""
    import nbvkit.runfolder
    from nbvkit.cli import main
    from nbvkit.recorder import Recorder

    def stopped(self, *args, **kwargs):
        if how.startswith("full_disk"):
            raise OSError(28, "No space left on device")
        raise KeyboardInterrupt

    real_manifest = nbvkit.runfolder.write_manifest

    def manifest(folder, *args, **kwargs):  # the run's own (its checkpoints' are written)
        if ".tmp" in Path(folder).name:
            stopped(None)
        return real_manifest(folder, *args, **kwargs)

    if how == "full_disk_at_the_manifest":
        monkeypatch.setattr(nbvkit.runfolder, "write_manifest", manifest)
    else:
        patched = {"full_disk": "write_keeping", "second_ctrl_c": "write"}
        monkeypatch.setattr(Recorder, patched.get(how, "stopped_flight"), stopped)
    out = tmp_path / "run"
    full = how.startswith("full_disk")
    stop = "error" if full else "interrupt"  # (error: past the 3 views)
    over = [*_stopping(stop, 100 if full else 4), "checkpoint_minutes=1e-9"]
    over = [*over, "max_iterations=3"] if full else over
    rc = main(["run", "--plugin", str(stopping_part), "--out", str(out), "--set", *over])
    assert rc == (2 if full else 130)
    s = json.loads((out / "summary.json").read_text())
    assert s["checkpoint"] is True
    err = capsys.readouterr().err
    said = re.search(
        rf"the flight \((\d+) iterations?\) was not saved; {re.escape(str(out))} holds its last "
        rf"checkpoint \({s['iterations']} iterations?, its summary saying a kill ended it\)",
        err,
    )
    assert said and int(said.group(1)) >= s["iterations"] >= 1, err


@pytest.mark.parametrize("cause", [KeyboardInterrupt, ZeroDivisionError])
def test_a_flight_stopped_while_saving_keeps_the_whole_flight(tmp_path, monkeypatch, cause):
    """Ctrl-C (or an error) during the end-of-run outputs, after the flight ended on its own:
    Mission.run(out_dir, finish=True) writes the whole flight without them (a half-written
    report.html removed), its own termination kept and `stopped_during: saving`, then raises."""
    import nbvkit.finish
    from conftest import TINY_RUN
    from nbvkit.config import load_config

    def stopped_report(out, *args, **kwargs):
        (Path(out) / "report.html").write_text("<html><body>half a rep")  # then stopped
        raise cause

    monkeypatch.setattr(nbvkit.finish, "write_run_report", stopped_report)
    out = tmp_path / "run"
    cfg = load_config(overrides=[*TINY_RUN, "max_iterations=3", "progress=false"])
    with pytest.raises(cause):
        nbvkit.Mission(cfg).run(out, finish=True)
    assert is_complete_run(out)
    s = json.loads((out / "summary.json").read_text())
    assert s["termination"] not in ("interrupted", "failed")  # the flight ended on its own
    assert s["stopped_during"] == "saving" and s["stopped_by"].startswith(cause.__name__)
    assert s["views"] >= 3 and s["area_coverage"]["0.05"] > 0
    assert not (out / "report.html").exists() and not (out / "mesh.ply").exists()
    rows = (out / "iterations.csv").read_text().strip().splitlines()
    assert len(rows) - 1 == s["iterations"] and (out / "cloud.ply").stat().st_size > 0
    with pytest.raises(ValueError, match="holds a run whose saving was stopped .its whole flight"):
        RunFolder(out).__enter__()


@pytest.mark.parametrize("signum", ["SIGINT", "SIGTERM"])
def test_nbvkit_run_killed_while_saving_keeps_the_flight(tmp_path, signum):
    """A real signal to `nbvkit run` once the flight is over, while the flight's files and
    then while the end-of-run outputs are written: the folder holds the whole flight, the
    console says so, exit 130."""
    import subprocess

    from conftest import TINY_RUN

    for stage, patch in (
        ("files", "nbvkit.cloud.write_points"),
        ("finish", "nbvkit.finish.write_run_report"),
    ):
        out = tmp_path / stage
        # the signal comes once, from inside the named writer, as a user's or a scheduler's
        script = textwrap.dedent(
            f"""
            import os, signal, sys, time
            import nbvkit.cloud, nbvkit.finish
            from nbvkit.cli import main
            mod, name = {patch!r}.rsplit(".", 1)
            module = sys.modules[mod]
            real = getattr(module, name)
            sent = []
            def signalled(*args, **kwargs):
                if not sent:
                    sent.append(1)
                    os.kill(os.getpid(), signal.{signum})
                    time.sleep(5)  # the handler raises here
                return real(*args, **kwargs)
            setattr(module, name, signalled)
            sys.exit(main(sys.argv[1:]))
            """
        )
        argv = ["run", "--out", str(out), "--set", *TINY_RUN, "max_iterations=3"]
        p = subprocess.run(
            [sys.executable, "-c", script, *argv],
            capture_output=True,
            text=True,
            timeout=300,
            env=dict(os.environ, MPLBACKEND="Agg"),
        )
        assert p.returncode == 130, (stage, p.returncode, p.stderr)
        assert "saving was stopped after the flight" in p.stderr, (stage, p.stderr)
        assert f"saved in {out}/" in p.stderr and "Traceback" not in p.stderr
        assert is_complete_run(out), stage
        s = json.loads((out / "summary.json").read_text())
        assert s["stopped_during"] == "saving" and s["termination"] != "interrupted"
        assert (out / "cloud.ply").stat().st_size > 0 and not (out / "report.html").exists()


def test_ctrl_c_during_the_open3d_import_is_an_interrupt():
    """open3d's extension turns a Ctrl-C during its (seconds-long) import into
    ImportError("initialization failed"); nbvkit's import of it raises KeyboardInterrupt, so
    the run keeps what it flew and exits 130 rather than reading as open3d missing."""
    import subprocess

    script = textwrap.dedent(
        """
        import builtins, sys
        real = builtins.__import__
        def interrupted(name, *args, **kwargs):
            if name == "open3d":  # as open3d's extension reports a Ctrl-C in its init
                try:
                    raise KeyboardInterrupt
                except KeyboardInterrupt as e:
                    raise ImportError("initialization failed") from e
            return real(name, *args, **kwargs)
        builtins.__import__ = interrupted
        from nbvkit._open3d import open3d
        try:
            open3d()
        except KeyboardInterrupt:
            print("KeyboardInterrupt")
        builtins.__import__ = real
        print(open3d().__name__)  # not interrupted: the module
        """
    )
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert p.stdout.split() == ["KeyboardInterrupt", "open3d"]


def test_a_signal_ignored_before_stays_ignored_within_terminate_as_interrupt():
    """`nohup nbvkit run` (SIGHUP ignored when it starts) flies on when the terminal closes;
    without nohup a hang-up stops it as a kill does; the handlers before come back after."""
    import signal

    from nbvkit.interrupts import Terminated, terminate_as_interrupt

    before = signal.getsignal(signal.SIGHUP), signal.getsignal(signal.SIGTERM)
    try:
        signal.signal(signal.SIGHUP, signal.SIG_IGN)
        with terminate_as_interrupt():
            os.kill(os.getpid(), signal.SIGHUP)  # ignored: nothing raised
            with pytest.raises(Terminated, match="SIGTERM"):
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(5)
        assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN
        signal.signal(signal.SIGHUP, signal.SIG_DFL)
        with terminate_as_interrupt():
            with pytest.raises(Terminated, match="SIGHUP .the terminal"):
                os.kill(os.getpid(), signal.SIGHUP)
                time.sleep(5)
        assert signal.getsignal(signal.SIGHUP) is signal.SIG_DFL
        assert signal.getsignal(signal.SIGTERM) is before[1]
        mine = lambda signum, frame: None  # noqa: E731  (a script's own handler stays its own)
        signal.signal(signal.SIGTERM, mine)
        with terminate_as_interrupt(only_default=True):
            assert signal.getsignal(signal.SIGTERM) is mine
            assert signal.getsignal(signal.SIGHUP) is not signal.SIG_DFL  # (the default: taken)
    finally:
        signal.signal(signal.SIGHUP, before[0])
        signal.signal(signal.SIGTERM, before[1])


def test_an_error_naming_a_removed_temporary_file_says_so(tmp_path, finished_run):
    """A write that fails inside the run folder's temporary folder (a full disk): the error
    names a file of a folder that is removed on the way out; a note says so and that the
    target is as it was (here a complete run an overwrite kept)."""
    out = tmp_path / "r"
    shutil.copytree(finished_run[0], out)
    old = (out / "summary.json").read_bytes()
    with pytest.raises(OSError) as e:
        with RunFolder(out, overwrite=True) as rf:
            bad = rf.tmp / "cloud.ply"
            raise OSError(28, "No space left on device", str(bad))
    notes = " ".join(getattr(e.value, "__notes__", ()))
    assert not bad.parent.exists() and f"{bad.parent.name}, beside {out}" in notes, notes
    assert f"{out} is as it was" in notes and (out / "summary.json").read_bytes() == old
    with pytest.raises(OSError) as e:  # an error naming another file gets no such note
        with RunFolder(out, overwrite=True):
            raise OSError(28, "No space left on device", str(tmp_path / "elsewhere"))
    assert not getattr(e.value, "__notes__", ())


def test_a_run_in_place_whose_folder_cannot_be_synced_is_kept_with_a_warning(tmp_path, monkeypatch):
    """The rename put the run in place; a failing sync of its folder (EIO, a file system that
    cannot) discarded it as if lost, with a note that the flight was not saved."""
    import nbvkit.runfolder
    from conftest import TINY_RUN
    from nbvkit.config import load_config

    def eio(path):
        raise OSError(5, "Input/output error")

    monkeypatch.setattr(nbvkit.runfolder, "_fsync_path", eio)
    out = tmp_path / "run"
    with pytest.warns(RuntimeWarning, match="is in place, but syncing its folder to disk failed"):
        nbvkit.Mission(load_config(overrides=[*TINY_RUN, "progress=false"])).run(out)
    assert is_complete_run(out)


@pytest.mark.skipif(sys.version_info < (3, 11), reason="exception notes: Python 3.11+")
def test_an_interrupt_after_the_flight_was_written_says_it_was_not_saved(tmp_path):
    """A Ctrl-C or a kill between the flight's files written whole and the run folder put in
    place drops them, as it must (the run did not finish): the exception now says so."""
    with pytest.raises(KeyboardInterrupt) as e:
        with RunFolder(tmp_path / "run") as folder:
            folder.saving(2, None)
            (folder.tmp / "summary.json").write_text("{}")
            raise KeyboardInterrupt
    assert "the flight (2 iterations) was not saved" in e.value.__notes__
    assert not (tmp_path / "run").exists()
