"""Output paths checked before any work (a mission or a sweep must not run for minutes and then
fail to write its results), and the check of a run folder read back: the paths a command writes
or reads. The checks live in nbvkit.output_paths and nbvkit.runfolder (which uses them)."""
from __future__ import annotations

from .output_paths import check_experiment_dir, check_output_dir, check_output_file

# Run folders: whole or marked incomplete (nbvkit.runfolder). Commands that read a run folder
# (evaluate, export, sweep resume, ...) call require_complete_run first.
from .runfolder import require_complete_run

__all__ = [
    "check_experiment_dir",
    "check_output_dir",
    "check_output_file",
    "require_complete_run",
]
