"""Reading run folders: the manifest that says a run folder is whole (``write_manifest``, written
last), the checks of it (``require_complete_run``, ``is_complete_run``) and the run's summary.
nbvkit.runfolder writes run folders and re-exports these names."""
from __future__ import annotations

import json
import math
import os
import re
import stat
import time
from pathlib import Path

from ._version import __version__
from .limits import MAX_TEXT_FILE_BYTES, check_input_file, is_number
from .locks import lock_holder, pid_alive
from .output_paths import MANIFEST

#: folders whose files are not listed in the manifest (caches are rewritten independently)
_UNLISTED = ("cache", "export")  # nbvkit export writes its folder after the run, whole


class IncompleteRunError(ValueError):
    """A folder that is not a complete run folder (no manifest, or files that do not match it)."""


# ---------------------------------------------------------------------------------- reading


def _listed_files(folder: Path) -> dict:
    """{relative posix path: size} of every regular file in folder (not the manifest, not
    caches)."""
    out = {}
    for root, dirs, files in os.walk(folder):
        rel_root = Path(root).relative_to(folder)
        if rel_root == Path("."):
            dirs[:] = [d for d in dirs if d not in _UNLISTED]
        for name in files:
            rel = (rel_root / name).as_posix()
            if rel == MANIFEST:
                continue
            out[rel] = os.stat(os.path.join(root, name)).st_size
    return dict(sorted(out.items()))


def _unlisted_files(folder: Path) -> list | None:
    """The files in run folder `folder` that its manifest does not list (not caches, not the
    export): a user's; None where there is no readable manifest (nothing tells them apart)."""
    try:
        listed = read_json_object(folder / MANIFEST, "manifest").get("files")
    except (OSError, ValueError):
        return None
    if not isinstance(listed, dict):
        return None
    return [
        rel
        for rel in _listed_files(folder)
        if rel not in listed and not _stale_export(rel.split("/", 1)[0])
    ]


def _stale_export(name: str) -> bool:
    """Whether `name` is the temporary folder of an export into the run folder (its export/)
    whose process is gone (killed while writing: nbvkit.export.TMP_PREFIX)."""
    m = re.fullmatch(r"\.nbvkit-export-(\d+)-[0-9a-f]+", name)
    return m is not None and not pid_alive(int(m.group(1)))


def _kept_state(folder: Path) -> str:
    """What complete run folder `folder` holds, in words: a checkpoint a killed run left, what a
    stopped run flew (interrupted or failed), or a complete run."""
    try:
        s = read_summary(folder)
    except (OSError, ValueError):
        return "a complete run"
    if s.get("checkpoint") is True:
        return "a checkpoint of a run that was killed (what it flew until then)"
    if s.get("stopped_during") == "saving":
        return "a run whose saving was stopped (its whole flight, without the end-of-run outputs)"
    if "stopped_by" in s:
        return f"a run that was stopped (termination {s.get('termination')}: what it flew)"
    return "a complete run"


def _problem(path: Path, check_lock: bool = True) -> str | None:
    """Why path is not a complete run folder, or None. (check_lock=False: by the run that holds
    its lock.)"""
    holder = lock_holder(path) if check_lock else None
    if holder:
        return f"is being written by an nbvkit run ({holder}); wait for it to finish"
    if not path.exists():
        return "does not exist"
    if not path.is_dir():
        return "is not a folder"
    m = path / MANIFEST
    if not m.exists() and (path / "runs").is_dir():  # (compare, table and sweep: runs/RUN)
        return (
            f"has no {MANIFEST}: it is an experiment's folder (compare, table or sweep), whose "
            f"runs are its runs/ folders: give one of them, {path / 'runs' / 'RUN'}"
        )
    if not m.exists():
        return (
            f"has no {MANIFEST}: the run that wrote it did not finish (interrupted, killed or "
            "failed), or it was written by nbvkit before run folders were marked complete; "
            "run it again"
        )
    try:
        manifest = read_json_object(m, MANIFEST)
        files = manifest["files"]
        if not isinstance(files, dict):
            raise TypeError
    except (OSError, ValueError, KeyError, TypeError):
        return f"has an unreadable {MANIFEST}; run it again"
    for rel, size in files.items():
        f = path / rel
        if Path(rel).is_absolute() or ".." in Path(rel).parts:  # (a run writes only in itself)
            return f"has a {MANIFEST} listing {rel}, outside the folder; run it again"
        try:
            st = f.stat()
        except OSError:
            return f"lacks {rel}, which its run wrote; run it again"
        if not stat.S_ISREG(st.st_mode):  # (a FIFO in its place would block its reader)
            return f"holds {rel}, which is not a regular file (its run wrote one); run it again"
        actual = st.st_size
        if actual != size:
            return (
                f"holds a damaged {rel} ({actual} bytes; its run wrote {size}): truncated or "
                "changed since; run it again"
            )
    return None


def read_json_object(path, what: str) -> dict:
    """The JSON object in the file `path` that a run wrote (`what`: "run summary", ...).
    FileNotFoundError naming it when it is missing; ValueError naming it when it is not a
    regular file of at most MAX_TEXT_FILE_BYTES, or not a JSON object (damaged, or not
    nbvkit's)."""
    path = check_input_file(path, what, MAX_TEXT_FILE_BYTES)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, ValueError) as e:
        raise ValueError(f"{what} {path} is damaged, not JSON ({e}); fly the run again") from None
    if not isinstance(data, dict):
        raise ValueError(f"{what} {path} is damaged: not a JSON object; fly the run again")
    return data


def read_summary(folder) -> dict:
    """The run folder `folder`'s summary.json as a dict (read_json_object). Reads it as it is:
    require_complete_run first where the run must be whole."""
    return read_json_object(Path(os.fspath(folder)).expanduser() / "summary.json", "run summary")


def run_workspace(summary: dict, source) -> dict:
    """The workspace of a run's summary (`source`: its summary.json), its bounds_min and
    bounds_max checked: three finite numbers each, min below max on every axis; ValueError
    naming the file and the key otherwise (a summary edited or damaged at the same size)."""
    ws = summary.get("workspace")
    if not isinstance(ws, dict) or "bounds_min" not in ws or "bounds_max" not in ws:
        raise ValueError(f"{source} has no workspace bounds (workspace.bounds_min/bounds_max)")
    for key in ("bounds_min", "bounds_max"):
        v = ws[key]
        if not (
            isinstance(v, list)
            and len(v) == 3
            and all(is_number(x) for x in v)
            and all(math.isfinite(x) for x in v)
        ):
            raise ValueError(f"{source}: workspace.{key} must be three finite numbers, got {v!r}")
    if not all(a < b for a, b in zip(ws["bounds_min"], ws["bounds_max"])):
        raise ValueError(f"{source}: workspace.bounds_min must lie below bounds_max on each axis")
    return ws


def looks_like_run(folder) -> bool:
    """Whether folder is (or is becoming) an nbvkit run folder: it holds a manifest or a summary,
    is a run's temporary folder, or a run is writing it."""
    f = Path(os.fspath(folder)).expanduser()
    return (
        (f / MANIFEST).exists()
        or (f / "summary.json").exists()
        or re.fullmatch(r"\.(.+)\.tmp\d+", f.name) is not None
        or lock_holder(f) is not None
    )


def is_complete_run(path) -> bool:
    """Whether path is a complete run folder (see require_complete_run)."""
    return _problem(Path(os.fspath(path)).expanduser()) is None


def require_complete_run(path, what: str = "run folder") -> Path:
    """The run folder ``path`` as a Path if it is complete: it holds ``manifest.json`` (written
    last by the run) and every file listed there with the listed size. Otherwise raises
    IncompleteRunError (a ValueError) naming the folder and what is wrong: missing, being written
    by another run, interrupted, or a file truncated or changed since."""
    p = Path(os.fspath(path)).expanduser()
    why = _problem(p)
    if why is not None:
        raise IncompleteRunError(f"{what} {p} is not a complete nbvkit run: it {why}")
    return p


def write_manifest(folder, only=None) -> Path:
    """Writes ``folder/manifest.json`` (every file's size; `only`: of those of these relative
    paths, what a manifest listed, not a user's files added since), flushed to disk, as the last
    file of a run. Raises OSError if it cannot be written whole."""
    folder = Path(folder)
    files = _listed_files(folder)
    if only is not None:
        files = {rel: size for rel, size in files.items() if rel in only}
    for rel in files:  # the outputs reach the disk before the marker that vouches for them
        _fsync_path(folder / rel)
    data = {"nbvkit": __version__, "written": time.time(), "files": files}
    tmp = folder / (MANIFEST + ".tmp")
    with open(tmp, "w") as f:
        f.write(json.dumps(data, indent=1) + "\n")
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, folder / MANIFEST)
    _fsync_path(folder)
    return folder / MANIFEST


def mark_incomplete(folder) -> list | None:
    """Removes ``folder/manifest.json`` before a run folder is changed in place (finish_run on a
    finished Mission's folder); returns the files it listed (write_manifest(folder, only=them)
    after), or None where there was none or none readable (not a complete run: left so)."""
    m = Path(folder) / MANIFEST
    try:
        listed = list(read_json_object(m, "manifest").get("files") or [])
    except (FileNotFoundError, ValueError, TypeError):
        return None
    try:
        m.unlink()
    except FileNotFoundError:
        return None
    _fsync_path(Path(folder))
    return listed


def _fsync_path(p: Path) -> None:
    fd = os.open(p, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def stopped_note(summary: dict) -> str | None:
    """What a reader of a run's results (export, evaluate) is told where its summary says it was
    stopped before its end (Ctrl-C, a kill, an error; a checkpoint a kill left): it flew part of
    its mission. None for a whole run."""
    if summary.get("termination") not in ("interrupted", "failed") and not summary.get(
        "checkpoint"
    ):
        return None
    what = "is a checkpoint, left by a kill" if summary.get("checkpoint") else "was stopped"
    return (
        f"the run {what} after {summary.get('views', '?')} views "
        f"({summary.get('stopped_by') or summary.get('termination')}): it flew part of its "
        "mission"
    )


def stopped_note_of(folder) -> str | None:
    """stopped_note of the run folder `folder`'s summary; None where it has none readable (a
    cloud file outside a run folder)."""
    if not (Path(os.fspath(folder)) / "summary.json").is_file():
        return None
    try:
        return stopped_note(read_summary(folder))
    except (OSError, ValueError):
        return None
