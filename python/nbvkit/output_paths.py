"""Output paths checked before any work: a mission or a sweep must not run for minutes and then
fail to write its results. (Imported by nbvkit.runfolder; users import these from nbvkit.paths.)"""
from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

from .limits import MAX_TEXT_FILE_BYTES, check_input_file

__all__ = ["check_output_dir", "check_output_file", "check_not_input"]


def check_output_dir(path, what: str = "output folder") -> Path:
    """ValueError naming `what` unless `path` is (or can be created as) a writable folder.

    Checks by creating it (and any missing parents) and a probe file in it; whatever the check
    created is removed again, so a later failure leaves nothing behind."""
    p = Path(os.fspath(path)).expanduser()
    if p.exists() and not p.is_dir():
        raise ValueError(f"{what} {p} exists and is not a folder")
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


def _run_folder_holding(p: Path) -> Path | None:
    """The innermost folder above the file p (symbolic links resolved) holding an nbvkit run's
    manifest (a JSON object listing "files", as nbvkit.runfolder writes it), or None."""
    from .runfolder import MANIFEST  # runfolder imports this module

    for folder in Path(os.path.realpath(p)).parents:
        try:
            m = check_input_file(folder / MANIFEST, "run manifest", MAX_TEXT_FILE_BYTES)
            manifest = json.loads(m.read_text())
        except (OSError, UnicodeDecodeError, ValueError):
            continue
        if isinstance(manifest, dict) and "files" in manifest:
            return folder
    return None
