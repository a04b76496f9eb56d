"""Output paths checked before any work: a mission or a sweep must not run for minutes and then
fail to write its results, nor a command overwrite one of its inputs or a finished run's files
(check_not_input). (Imported by nbvkit.runfolder; users import these from nbvkit.paths.)"""
from __future__ import annotations

import contextlib
import functools
import json
import os
import re
import stat
import sys
import tempfile
from pathlib import Path

from .limits import MAX_TEXT_FILE_BYTES, check_input_file

__all__ = [
    "MANIFEST",
    "check_experiment_dir",
    "check_not_input",
    "check_output_dir",
    "check_output_file",
    "naming_the_file",
]

#: a run folder's completion marker (every file and its size), written last (nbvkit.runfolder)
MANIFEST = "manifest.json"


@contextlib.contextmanager
def naming_the_file(path):
    """An OSError raised inside that names no file (a write to a full disk says only "No space
    left on device") raised again naming `path`, as an error of the same kind."""
    try:
        yield
    except OSError as e:
        if e.filename is not None or e.errno is None:
            raise
        raise OSError(e.errno, e.strerror or str(e), os.fspath(path)) from e


def is_mount_point(path) -> bool:
    """Whether `path` (resolved: a symlink to one counts) is a mount point: another file system
    (os.path.ismount), or any mount the kernel lists (/proc/self/mountinfo: a bind mount of a
    folder of the same file system, which os.path.ismount does not see)."""
    real = os.path.realpath(os.fspath(path))
    if os.path.ismount(real):
        return True
    try:
        with open("/proc/self/mountinfo", encoding="utf-8", errors="replace") as f:
            points = [line.split()[4] for line in f if len(line.split()) > 4]
    except OSError:
        return False
    # the mount point field escapes space, tab, newline and backslash as octal (\040 ...)
    unescape = functools.partial(re.sub, r"\\([0-7]{3})", lambda m: chr(int(m.group(1), 8)))
    return real in {unescape(p) for p in points}


def check_output_dir(path, what: str = "output folder", whole_folder: bool = False) -> Path:
    """ValueError naming `what` unless `path` is (or can be created as) a writable folder; with
    `whole_folder` (a folder written beside it and renamed into place: a run, an export) also
    when it is a mount point, which no rename reaches.

    Checks by creating it (and any missing parents) and a probe file in it; whatever the check
    created is removed again, so a later failure leaves nothing behind."""
    p = Path(os.fspath(path)).expanduser()
    if p.exists() and not p.is_dir():
        raise ValueError(f"{what} {p} exists and is not a folder")
    if whole_folder and is_mount_point(p):
        raise ValueError(
            f"{what} {p} is a mount point: its results are written beside it and renamed onto "
            f"it, which a mount point refuses; give a folder inside it ({p / 'run'})"
        )
    created = []
    q = p
    while not q.exists() and q != q.parent:
        created.append(q)
        q = q.parent
    try:
        p.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=p, prefix=".nbvkit-probe"):
            pass
    except OSError as e:
        raise ValueError(f"{what} {p} cannot be written: {e.strerror or e}") from None
    finally:
        for c in created:  # deepest first
            try:
                c.rmdir()
            except OSError:
                break
    return p


def check_experiment_dir(path, what: str = "output folder") -> Path:
    """check_output_dir, and ValueError naming `what` when the folder is (or lies in) a finished
    nbvkit run's folder: an experiment (compare, table, sweep) writes its own report.html,
    runs.csv and runs/ there, and the run's manifest no longer vouches for its files."""
    p = check_output_dir(path, what)
    run = _run_folder_holding(p / "report.html")
    if run is not None:
        where = "is" if _same_file(run, p) else f"lies in {run},"
        raise ValueError(
            f"{what} {p} {where} a finished nbvkit run's folder: an experiment's report and "
            "runs would be written over its files; choose another folder"
        )
    return p


def check_output_file(path, what: str = "output file") -> Path:
    """ValueError naming `what` unless a file can be written at `path` (not a folder, its folder
    exists and is writable). Nothing is left behind."""
    p = Path(os.fspath(path)).expanduser()
    if p.is_dir():
        raise ValueError(f"{what} {p} is a folder, not a file")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise ValueError(f"{what} {p}: folder {parent} does not exist")
    existed = p.exists()
    try:
        with open(p, "ab"):
            pass
    except OSError as e:
        raise ValueError(f"{what} {p} cannot be written: {e.strerror or e}") from None
    if not existed:
        p.unlink()
    return p


@contextlib.contextmanager
def atomic_open(path: Path, mode: str = "w", **kw):
    """A file opened for writing at a temporary name beside `path`, renamed over it once closed
    without error (a write error, e.g. a full disk, raises OSError and leaves `path` as it was)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        with naming_the_file(path), open(tmp, mode, **kw) as f:
            yield f
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def write_text_atomic(path: Path, text: str) -> None:
    with atomic_open(path) as f:
        f.write(text)


def write_text_output(path, text: str) -> None:
    """Writes a user's output file: whole or not at all (atomic_open at its target, through a
    link) where a file can be swapped in; through this process's own stdout or stderr where the
    path is that file or pipe (/dev/stdout: what was printed there stays, in order); else in
    place, after what was printed: a pipe, a device, or a file in a folder nbvkit may not create
    files in."""
    given = Path(os.fspath(path)).expanduser()
    try:
        st = os.stat(given)  # through /dev/stdout -> /proc/self/fd/1: the stream's own file
    except OSError:
        st = None
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError, AttributeError):
            if st is not None and os.path.samestat(os.fstat(stream.fileno()), st):
                stream.write(text)
                stream.flush()
                return
    sys.stdout.flush()
    sys.stderr.flush()
    target = given.resolve()
    regular = st is None or stat.S_ISREG(st.st_mode)
    if not regular or not os.access(target.parent, os.W_OK | os.X_OK):
        with naming_the_file(given), open(given, "w") as f:
            f.write(text)
    else:
        write_text_atomic(target, text)


def check_not_input(path, inputs, what: str = "output file") -> None:
    """ValueError naming both paths when writing the file `path` would overwrite one of the
    command's `inputs` ((description, path or None) pairs: the same file, also through a
    symbolic or hard link) or change a finished nbvkit run: `path` lies in a folder holding a
    run's manifest (nbvkit.runfolder)."""
    p = Path(os.fspath(path)).expanduser()
    for desc, src in inputs:
        if src is not None and _same_file(p, Path(os.fspath(src)).expanduser()):
            raise ValueError(
                f"{what} {p} is {desc} {src}, an input of this command: choose another file"
            )
    run = _run_folder_holding(p)
    if run is not None:
        raise ValueError(
            f"{what} {p} lies in the nbvkit run folder {run}, whose files are the run's "
            "results: choose a file outside it"
        )


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist (yet): compare where their links lead
        return os.path.realpath(a) == os.path.realpath(b)


def check_export_dir(out: Path) -> None:
    """ValueError where the export folder `out` is a run folder or lies in one other than in
    its export/ (symbolic links resolved): its files would lie among the run's, which
    --overwrite then refused as not nbvkit's."""
    real = Path(os.path.realpath(out))
    run = _run_folder_holding(real / "x")  # real itself or a folder above it
    if run is not None and not real.is_relative_to(run / "export"):
        where = "is" if run == real else f"lies in {run},"
        raise ValueError(f"output folder {out} {where} a run folder: give a folder of its own")


def _run_folder_holding(p: Path) -> Path | None:
    """The innermost folder above the file p (symbolic links resolved) holding an nbvkit run's
    manifest (a JSON object listing "files", as nbvkit.runfolder writes it), or None."""
    for folder in Path(os.path.realpath(p)).parents:
        try:
            m = check_input_file(folder / MANIFEST, "run manifest", MAX_TEXT_FILE_BYTES)
            manifest = json.loads(m.read_text())
        except (OSError, UnicodeDecodeError, ValueError):
            continue
        if isinstance(manifest, dict) and "files" in manifest:
            return folder
    return None
