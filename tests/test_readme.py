"""The README runs: its Python blocks execute, and the commands it names exist; so do those of
docs/USAGE.md, where the README's reference moved."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
README = (ROOT / "README.md").read_text()
USAGE = (ROOT / "docs" / "USAGE.md").read_text()


def python_blocks(text=README + USAGE):
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


def test_readme_has_python_blocks():
    assert python_blocks(README)


@pytest.mark.parametrize("i", range(len(python_blocks())))
def test_readme_python_block_runs(i, tmp_path):
    code = python_blocks()[i]
    r = subprocess.run(
        [sys.executable, "-c", code],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
        env={"MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin"},
    )
    assert r.returncode == 0, r.stderr


def test_readme_commands_exist():
    from nbvkit.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    for cmd in set(re.findall(r"nbvkit (\w+) ", README + USAGE)):
        assert cmd in sub.choices, f"README names `nbvkit {cmd}`, which does not exist"
    make = (ROOT / "Makefile").read_text()
    for target in ("test:", "install:", "deps:"):
        assert target in make
