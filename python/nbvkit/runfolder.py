"""Run folders that are whole or say they are not.

A run's results (``Mission.run(out_dir)``, ``nbvkit run --out``, each run of an experiment) are
written into a hidden temporary folder beside the target, ``.<name>.tmp<pid>``, and moved into
place when complete: the last file written into it is ``manifest.json`` (every output file with
its size), then the temporary folder is renamed onto the target (swapped with an old run in one
step where the file system can, with ``renameat2(RENAME_EXCHANGE)``). So a crash, a kill or a full
disk leaves the target as it was (absent, or the previous whole run) plus a hidden temporary
folder that the next run on that target removes. A long mission also puts checkpoints in place
as it flies (``RunFolder.checkpoint``; every ``checkpoint_minutes``): each a complete run of what
was flown so far, so a kill loses at most that much of the flight.

``manifest.json`` is the completion marker: a folder is a complete run when it holds one and
every file it lists has the listed size (``require_complete_run``). Commands that read a run
folder (evaluate, compare, sweep resume, export) call ``require_complete_run`` first.

While a run is written, it holds an exclusive lock (``flock``) on ``.<name>.lock`` beside the
target: a second run on the same folder fails at once with a message naming the first one's
process (or, for the experiment runner, waits and then reuses it). The kernel drops the lock
when its process dies, so a killed run never blocks the next. The lock file is removed by the
run that holds it, before it lets go (``nbvkit.locks.FileLock``: a run that opened the removed
file locks it again by its name), so only a killed run leaves one, which the next run on that
target removes.

A folder that already holds anything is refused unless ``overwrite`` is given; an overwrite
replaces it whole (no old file stays beside the new ones) and only when it is a run folder
(its manifest) holding nothing but the files its manifest lists (and nbvkit's caches and
export): ``--overwrite`` never removes a user's other files, nor a run's own inputs (``inputs``:
its mesh or configuration file inside the folder). A run that replaces a complete run and is
stopped (Ctrl-C, a kill, an error, its end-of-run outputs failing) keeps the old run: its
checkpoints and what it flew go beside it, in ``<name>.interrupted`` (``RunFolder.placed``). A
mount point is refused as a target (a folder renamed onto it fails at the end: give a folder
inside it).
"""
from __future__ import annotations

import ctypes
import glob
import json
import math
import os
import re
import shutil
import warnings
from pathlib import Path

import numpy as np

from .limits import add_note, require_bool
from .locks import RunLock
from .output_paths import MANIFEST, check_output_dir, write_text_atomic
from .interrupts import signals_held
from .run_manifest import (  # noqa: F401  (re-exported: the readers import them from here)
    IncompleteRunError,
    _fsync_path,
    _kept_state,
    _problem,
    _stale_export,
    _unlisted_files,
    is_complete_run,
    looks_like_run,
    mark_incomplete,
    read_json_object,
    read_summary,
    require_complete_run,
    run_workspace,
    stopped_note,
    stopped_note_of,
    write_manifest,
)

__all__ = [
    "MANIFEST",
    "OUTPUT_NAMES",
    "IncompleteRunError",
    "RunFolder",
    "is_complete_run",
    "looks_like_run",
    "require_complete_run",
    "mark_incomplete",
    "read_summary",
    "run_name",
    "write_manifest",
]

#: every name nbvkit writes at the top of a run folder (an overwrite removes only these)
OUTPUT_NAMES = frozenset(
    {
        MANIFEST,
        "config.yaml",
        "summary.json",
        "iterations.csv",
        "trajectory.csv",
        "flight.csv",
        "export",
        "cloud.ply",
        "map.ot",
        "mesh.ply",
        "report.html",
        "spec.json",
        "figures",
        "cache",
    }
)


# ---------------------------------------------------------------------------------- writing


def _exchange(a: Path, b: Path) -> bool:
    """Atomically swaps the paths a and b (Linux renameat2 RENAME_EXCHANGE); False where the
    system or file system cannot."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return False
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    at_fdcwd, rename_exchange = -100, 2
    return fn(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0


class RunFolder:
    """Writes one run folder whole, or not at all::

        with RunFolder("runs/x", overwrite=False, what="--out") as rf:
            ...write the results into rf.tmp...
        # here runs/x holds the complete run (manifest.json last); on an exception or a kill
        # runs/x is as it was before

    Entering checks before any work: the folder can be written (ValueError naming ``what``
    otherwise); no other run is writing it (the lock: ValueError, or with ``wait`` blocks until
    the other run ends); it is empty or absent, or ``overwrite`` is given and it holds only
    nbvkit's outputs. ``cancel()`` inside the block drops what was written and keeps the target
    as it is (the experiment runner, finding the run finished by another worker meanwhile).
    """

    def __init__(
        self,
        path,
        *,
        overwrite: bool = False,
        wait: bool = False,
        what: str = "run folder",
        carry: tuple = ("cache",),
        inputs: tuple = (),
        own: bool = False,
    ):
        if isinstance(path, bytes) or not isinstance(path, (str, os.PathLike)):
            raise TypeError(f"{what} must be a folder path, got {type(path).__name__}")
        overwrite = require_bool(overwrite, "overwrite")
        p = Path(os.fspath(path)).expanduser()
        if p.is_symlink():
            p = Path(os.path.realpath(p))
        p = Path(os.path.abspath(p))
        if p.parent == p:
            raise ValueError(f"{what} {p} is the root folder: choose a folder to hold the run")
        check_output_dir(p, what, whole_folder=True)  # a file, an unwritable place, a mount
        self.path, self.overwrite, self.what, self.carry = p, overwrite, what, tuple(carry)
        self.inputs = tuple(Path(os.path.realpath(os.fspath(i))) for i in inputs if i)
        self.own = own  # a folder only nbvkit writes (an experiment's runs/): any state replaced
        #: set by the writer when what it writes is a stopped run (fly_into): with a complete
        #: run in the target it goes beside it (`placed`), as its checkpoints do
        self.partial = False
        #: where the results were put (the target, or beside a complete run it kept)
        self.placed: Path | None = None
        #: while a flight is saved into it (`saving`): what a failure to put it in place loses
        self.unsaved: str | None = None
        self._keep_old = False
        self._beside: Path | None = None  # the folder beside a kept run this run put in place
        self._carried: list = []
        self._lock = RunLock(p, what, wait)
        self.tmp: Path | None = None
        self._cancelled = False

    def __enter__(self) -> "RunFolder":
        p = self.path
        p.parent.mkdir(parents=True, exist_ok=True)
        self._lock.acquire()
        try:
            self._check_target()
            # a complete run overwritten is replaced only by a whole new one
            self._keep_old = not self.own and p.exists() and _problem(p, check_lock=False) is None
            self._remove_stale()
            self.tmp = p.parent / f".{p.name}.tmp{os.getpid()}"
            try:
                self.tmp.mkdir()
            except OSError as e:
                raise ValueError(
                    f"{self.what} {p} cannot be written: results are written beside it in "
                    f"{p.parent} first, which refuses: {e.strerror or e}"
                ) from None
            for name in self.carry:  # an overwritten run's cache serves the new run
                if p.exists() and (p / name).is_dir():
                    os.rename(p / name, self.tmp / name)
                    self._carried.append(name)
        except BaseException:
            self._lock.release()
            raise
        return self

    def cancel(self) -> None:
        self._cancelled = True

    def _check_target(self) -> None:
        p = self.path
        if not p.exists():
            return
        entries = sorted(os.listdir(p))
        if not entries:
            return
        if not self.overwrite:
            complete = _problem(p, check_lock=False) is None
            state = _kept_state(p) if complete else "files (an unfinished run?)"
            raise ValueError(
                f"{self.what} {p} already holds {state}: pass --overwrite (Python: "
                "overwrite=True) to replace it, or choose another folder"
            )
        foreign = [e for e in entries if e not in OUTPUT_NAMES and not _stale_export(e)]
        if not foreign and not self.own:
            foreign = _unlisted_files(p)
            if foreign is None:
                raise ValueError(
                    f"{self.what} {p} holds files but no readable {MANIFEST} (not a run folder, "
                    "or one whose manifest was lost or damaged): nbvkit cannot tell its files "
                    "from others, so it does not overwrite it; move them away or choose another "
                    "folder"
                )
        if foreign:
            shown = ", ".join(foreign[:5]) + (", ..." if len(foreign) > 5 else "")
            raise ValueError(
                f"{self.what} {p} holds files nbvkit did not write ({shown}): not overwriting "
                "it; move them away or choose another folder"
            )
        real = Path(os.path.realpath(p))
        for i in self.inputs:
            if i.is_relative_to(real):
                raise ValueError(
                    f"{self.what} {p} holds this run's input {i}: overwriting the folder would "
                    "replace it; copy it elsewhere first or choose another folder"
                )

    def _remove_stale(self) -> None:
        """Temporary folders of earlier runs on this target (killed: we hold the lock now)."""
        p = self.path
        for kind in ("tmp", "old", "ckpt"):
            prefix = f".{p.name}.{kind}"
            for d in p.parent.glob(f"{glob.escape(prefix)}*"):
                if d.is_dir() and d.name[len(prefix) :].isdigit():
                    shutil.rmtree(d, ignore_errors=True)

    def _destination(self, partial: bool) -> Path:
        """Where results go: the target, or, for a stopped run (partial), beside the complete
        run the target holds: the first of <name>.interrupted, <name>.interrupted<pid>, ... that is
        free (chosen once: this run's checkpoints and stopped run replace each other there,
        never what another run left)."""
        p = self.path
        if not (partial and self._keep_old):
            return p
        if self._beside is None:
            names = [f"{p.name}.interrupted", f"{p.name}.interrupted{os.getpid()}"]
            names += [f"{p.name}.interrupted{os.getpid()}-{k}" for k in range(1, 100)]
            self._beside = next(
                (p.parent / n for n in names if not os.path.lexists(p.parent / n)),
                p.parent / names[-1],
            )
        return self._beside

    def checkpoint(self, write) -> None:
        """Puts a complete run in place as the target while this one goes on: what
        ``write(folder)`` writes into a fresh hidden folder, its manifest last, swapped onto the
        target as a commit is (replacing the previous checkpoint). A run killed later leaves the
        last checkpoint in place of nothing; one that finishes replaces it. An exception while
        writing it drops the checkpoint (the target stays as it was) and propagates."""
        p = self.path
        ck = p.parent / f".{p.name}.ckpt{os.getpid()}"
        shutil.rmtree(ck, ignore_errors=True)
        try:
            ck.mkdir()
            write(ck)
            write_manifest(ck)
            self.placed = self._destination(partial=True)  # a checkpoint is a stopped run
            self._place(ck, self.placed)  # (an OSError: the checkpoint is dropped)
        finally:
            shutil.rmtree(ck, ignore_errors=True)  # (after a swap: the previous checkpoint)

    def __exit__(self, exc_type, exc, tb) -> None:
        with signals_held():  # Ctrl-C or a kill meanwhile comes once the run is in place
            self._exit(exc_type, exc)

    def _exit(self, exc_type, exc) -> None:
        try:
            if exc_type is not None or self._cancelled:
                self._discard()
                self._note_discarded(exc)
                if exc is not None and self.unsaved:  # (a flight whole in self.tmp, dropped)
                    add_note(exc, self.unsaved)
                return
            try:
                write_manifest(self.tmp)
                self.placed = self._destination(self.partial)
                if self.placed != self.path:  # beside the kept run: it keeps its cache
                    self._give_back()
                    if not self._place_beside():
                        return  # kept in self.tmp (placed), which the caller names
                else:
                    self._place(self.tmp, self.placed)
                    if self._beside is not None:  # a checkpoint of this run: the run is whole
                        shutil.rmtree(self._beside, ignore_errors=True)
            except BaseException as e:
                self._discard()
                self._note_discarded(e)
                if self.unsaved:  # (the flight's files were whole in self.tmp)
                    add_note(e, self.unsaved)
                raise
        finally:
            self._lock.release()

    def saving(self, n: int, checkpoint: int | None) -> None:
        """A flight of `n` iterations (its views) is being saved into this folder: an error (a
        full disk), an interrupt or an exit that stops it from here until the folder is in place
        notes the flight lost (__exit__), and what the folder holds instead (`checkpoint`: its
        last checkpoint's views; None: none), whose summary reads as killed."""
        text = f"the flight ({n} iteration{'' if n == 1 else 's'}) was not saved"
        if checkpoint is not None and self.placed is not None:
            text += (
                f"; {self.placed} holds its last checkpoint ({checkpoint} "
                f"iteration{'' if checkpoint == 1 else 's'}, its summary saying a kill ended it)"
            )
        self.unsaved = text

    def _note_discarded(self, exc) -> None:
        """An error naming a file of the temporary folder, which _discard removed, says so
        (a reader would look for it there)."""
        names = [getattr(exc, a, None) for a in ("filename", "filename2")]
        if any(isinstance(n, str) and n.startswith(os.fspath(self.tmp)) for n in names):
            add_note(
                exc,
                f"(a file of the results being written in {self.tmp.name}, beside {self.path}, "
                f"which was removed; {self.path} is as it was)",
            )

    def _discard(self) -> None:
        """Drops the temporary folder, giving back what was carried over from the target."""
        self._give_back()
        shutil.rmtree(self.tmp, ignore_errors=True)

    def _give_back(self) -> None:
        """Moves what was carried over from the target (its cache) back into it."""
        for name in self._carried:
            try:
                if self.path.is_dir() and not (self.path / name).exists():
                    os.rename(self.tmp / name, self.path / name)
            except OSError:
                pass
        self._carried = []

    def _place_beside(self) -> bool:
        """Puts a stopped run beside the kept one (placed); where that fails (a name too long,
        a folder that refuses), leaves it in its temporary folder, which `placed` then names
        (False), rather than losing it."""
        try:
            self._place(self.tmp, self.placed)
            return True
        except OSError:
            self.placed = self.tmp
            return False

    def _place(self, src: Path, p: Path) -> None:
        """Moves the folder `src` onto `p` (the target, or beside it) in one step (the old one
        removed)."""
        if p.exists() and os.listdir(p):
            if _exchange(src, p):  # src now holds the old run
                shutil.rmtree(src, ignore_errors=True)
                _synced(p)
                return
            old = p.parent / f".{p.name}.old{os.getpid()}"
            os.rename(p, old)
            try:
                os.rename(src, p)
            except OSError:
                os.rename(old, p)  # the old run back in place
                raise
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.rename(src, p)  # onto an absent or empty folder
        _synced(p)


def _synced(p: Path) -> None:
    """The rename that put `p` in place made durable (its folder synced); a failure to sync it
    (EIO, or a file system that cannot) is a warning: the run is in place, not lost."""
    try:
        _fsync_path(p.parent)
    except OSError as e:
        warnings.warn(
            f"{p} is in place, but syncing its folder to disk failed: {e}", RuntimeWarning
        )


def run_name(folder) -> str:
    """The name a run folder has once in place: ``x`` for its temporary ``.x.tmp<pid>``."""
    name = Path(folder).name
    m = re.fullmatch(r"\.(.+)\.tmp\d+", name)
    return m.group(1) if m else name


# ------------------------------------------------------------------ atomic files
def write_json_atomic(path: Path, data: dict) -> None:
    write_text_atomic(path, json.dumps(_jsonable(data), indent=2, allow_nan=False))


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    return x
