"""Writes large structures (100 m class) to fly the planners at scale (issue 37; docs/RESULTS.md,
"Large structures"). None of them is shipped or used by a test; each layout is drawn from a seed,
so a planner change can be measured on one seed and checked on others it was never tried on.

- plant: an industrial plant about 100 x 70 x 48 m: a turbine hall with a roof that overhangs
  its walls, a lower boiler house against it, a 48 m stack on a plinth, three to five tanks
  with domed tops, two pipe racks (posts, two levels of beams, pipes) running between them, and
  a cluttered middle of pumps, transformers and skids;
- bridge: a 150 m through-truss bridge: two trusses 9 m high (chords, verticals, diagonals),
  a deck slab, cross girders, two river piers and two abutments, turned and moved off the
  origin.

Parts are closed triangle meshes (bench/unseen_structures.Builder) overlapping where they join.

    .venv/bin/python bench/large_structures.py runs/large --seed 1   # runs/large/plant_s1.obj ...
    .venv/bin/nbvkit run --mesh runs/large/plant_s1.obj --out runs/plant
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _timing import run_each, run_snippet, table_header  # noqa: E402
from unseen_structures import Builder, selected  # noqa: E402


def plant(rng: np.random.Generator) -> Builder:
    m = Builder()
    u = rng.uniform
    hall_l, hall_w, hall_h = u(55, 65), u(26, 32), u(18, 22)
    m.box([0, 0, 0], [hall_l, hall_w, hall_h])  # turbine hall
    m.box([-1, -1, hall_h], [hall_l + 1, hall_w + 1, hall_h + 0.6])  # roof slab, overhanging
    for x in np.arange(6, hall_l - 3, 12):  # roof ventilators
        m.box([x, hall_w / 2 - 2, hall_h + 0.6], [x + 3, hall_w / 2 + 2, hall_h + 2.2])
    boiler_h = u(11, 15)
    m.box([hall_l, 4, 0], [hall_l + u(16, 22), hall_w - 2, boiler_h])  # boiler house
    sx, sy = hall_l + u(22, 28), hall_w + u(20, 26)
    m.box([sx - 4, sy - 4, 0], [sx + 4, sy + 4, 3])  # stack plinth
    m.cylinder([sx, sy, 3], [sx, sy, 48], 3.0, 2.0, n=32)  # stack
    m.cylinder([sx, sy, 40], [sx, sy, 40.8], 3.3, n=32)  # its gallery
    n_tanks = int(rng.integers(3, 6))
    for k in range(n_tanks):
        r, h = u(4, 6.5), u(9, 15)
        cx, cy = 6 + k * 15 + u(-1, 1), hall_w + u(28, 33)
        m.cylinder([cx, cy, 0], [cx, cy, h], r, n=40)
        m.sphere([cx, cy, h], r, n=16, upper_half=True)
    for y0 in (hall_w + 8, hall_w + 17):  # two pipe racks along x
        x0, x1 = -2, hall_l + 12
        for x in np.arange(x0, x1 + 0.1, 6.0):
            for y in (y0, y0 + 4):
                m.box([x - 0.2, y - 0.2, 0], [x + 0.2, y + 0.2, 8])  # posts
            for z in (5.0, 7.6):
                m.box([x - 0.15, y0, z], [x + 0.15, y0 + 4, z + 0.3])  # cross beams
        for z in (5.3, 7.9):
            for y in np.arange(y0 + 0.5, y0 + 4, 0.9):
                m.cylinder([x0, y, z + 0.25], [x1, y, z + 0.25], 0.22, n=10)  # pipes
    for _ in range(int(rng.integers(14, 20))):  # pumps, transformers, skids in the middle
        w, d, h = u(1.5, 4), u(1.5, 4), u(1.5, 4)
        x, y = u(0, hall_l + 10), hall_w + u(1.5, 6.5)
        m.box([x, y, 0], [x + w, y + d, h])
    for _ in range(int(rng.integers(4, 7))):  # vertical vessels
        x, y, r = u(0, hall_l), hall_w + u(21, 24), u(0.6, 1.2)
        m.cylinder([x, y, 0], [x, y, u(5, 10)], r, n=16)
    return m.place(float(u(0, 360)), (u(-50, 50), u(-50, 50), 0.0))


def bridge(rng: np.random.Generator) -> Builder:
    m, span, half_w, h, deck_z, panel = Builder(), 150.0, 5.0, 9.0, 8.0, 7.5
    xs = np.arange(0, span + 0.1, panel)
    n = len(xs) - 1  # panels
    for y in (-half_w, half_w):
        m.box([0, y - 0.4, deck_z], [span, y + 0.4, deck_z + 0.8])  # bottom chord
        m.box([panel, y - 0.4, deck_z + h], [span - panel, y + 0.4, deck_z + h + 0.8])  # top
        for i in range(1, n):
            x = xs[i]
            m.box([x - 0.3, y - 0.3, deck_z], [x + 0.3, y + 0.3, deck_z + h])  # verticals
        for i in range(n):  # end posts and diagonals, falling towards mid-span
            low, high = (xs[i], xs[i + 1]) if i < n // 2 else (xs[i + 1], xs[i])
            m.cylinder([low, y, deck_z + 0.8], [high, y, deck_z + h], 0.25, n=8)
    for x in xs:  # cross girders under the deck
        m.box([x - 0.3, -half_w, deck_z - 0.9], [x + 0.3, half_w, deck_z])
    m.box([0, -half_w + 0.4, deck_z], [span, half_w - 0.4, deck_z + 0.35])  # deck slab
    for x in xs[1:-1:2]:  # top bracing
        m.box([x - 0.2, -half_w, deck_z + h], [x + 0.2, half_w, deck_z + h + 0.6])
    for x in (span / 3, 2 * span / 3):  # river piers
        m.box([x - 1.5, -half_w - 1, 0], [x + 1.5, half_w + 1, deck_z - 0.9])
    for x in (-3.0, span):  # abutments
        m.box([x, -half_w - 2, 0], [x + 3, half_w + 2, deck_z])
    return m.place(float(rng.uniform(0, 360)), (rng.uniform(-80, 80), rng.uniform(-80, 80), 0.0))


STRUCTURES = {"plant": plant, "bridge": bridge}


def structure_parser(doc: str, seed: int) -> argparse.ArgumentParser:
    """A parser described by the first line of `doc` with --structure (default plant), --seed
    (default `seed`) and --against (another checkout, or a saved package, to compare with)."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--structure", default="plant", choices=list(STRUCTURES))
    ap.add_argument("--seed", type=int, default=seed)
    ap.add_argument("--against", help="another checkout (or a saved package) to compare with")
    return ap


def write_structure(name: str, seed: int, folder) -> Path:
    """The structure `name` of layout `seed`, written to folder/mesh.obj (returned)."""
    path = Path(folder) / "mesh.obj"
    STRUCTURES[name](np.random.default_rng(seed)).write(path)
    return path


def compare_on_structure(a, what: str, columns, snippet: str, args, row, baseline=()) -> list:
    """Writes the structure of `a` (structure_parser's arguments) into a temporary folder, prints
    a title (the structure, its seed and `what`) and a table header of `columns`, and runs
    `snippet` with the mesh's path and then `args`, in this checkout and in a.against's
    (run_each, printing row(label, result) for each); with `baseline` (more arguments), once more
    in this checkout with them after `args`: the results."""
    with tempfile.TemporaryDirectory() as tmp:
        path = write_structure(a.structure, a.seed, tmp)
        print(f"{a.structure} seed {a.seed}, {what}")
        table_header(*columns)
        results = run_each(snippet, [path, *args], a.against, row)
        if baseline:
            results.append(run_snippet(snippet, [path, *args, *baseline]))
            print(row("this checkout, " + " ".join(baseline), results[-1]), flush=True)
        return results


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path, help="folder to write NAME_sSEED.obj into")
    ap.add_argument("--seed", type=int, default=0, help="layout seed (default 0)")
    ap.add_argument("--only", default=",".join(STRUCTURES), help="comma-separated names")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    for name in selected(args.only, STRUCTURES):
        path = args.out / f"{name}_s{args.seed}.obj"
        mesh = STRUCTURES[name](np.random.default_rng(args.seed))
        mesh.write(path)
        v = np.asarray(mesh.v)
        print(path, "extent", np.round(v.max(0) - v.min(0), 1), f"{len(mesh.f)} faces")


if __name__ == "__main__":
    main()
