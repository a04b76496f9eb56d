"""Helpers shared by the benchmark scripts (imported from the scripts' own folder): timing, the
common command line and the structure to time."""
import argparse
import time

import numpy as np

import nbvkit


def mesh_parser(doc: str, repeat: int | None = None) -> argparse.ArgumentParser:
    """A parser described by the first line of `doc`, with --mesh (default: the shipped
    airliner) and, given a default count, --repeat."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--mesh", default=None, help="structure mesh (default: the shipped airliner)")
    if repeat is not None:
        ap.add_argument("--repeat", type=int, default=repeat)
    return ap


def bench_mesh(path=None):
    """(mesh, lo, hi, centre): the structure at `path` (default: the shipped airliner), its
    bounding box corners and centre."""
    mesh = nbvkit.load_mesh(path or nbvkit.default_mesh_path())
    lo, hi = mesh.bounds
    return mesh, lo, hi, (lo + hi) / 2


def median_time(fn, repeat: int) -> float:
    """Median wall time (s) of `repeat` calls of fn, after one warm-up call."""
    fn()
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return float(np.median(ts))
