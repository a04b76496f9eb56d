"""Benchmark of the coverage tour's exploration targets (exploration_targets: the unknown space a
view could open) on a flown map, with this checkout and (--against DIR) another one, each in a
process of its own, alternating, in the same run: the time of one call over the structure's
extent and over the whole workspace, the ratio, and whether both gave the same targets bit for
bit. Prints figures.

    .venv/bin/python bench/bench_exploration.py                    # the airliner, 60 views
    .venv/bin/python bench/bench_exploration.py --run RUN --against /tmp/before   # a run's map

--run RUN: the map of a finished mission (RUN/map.ot, its workspace from RUN/summary.json), e.g.
a 1,000-view flight of the plant of bench/large_structures.py.
"""
from __future__ import annotations

import json
import tempfile

from _timing import alternate, flown_map, flown_map_parser, print_best

TIME_SNIPPET = r"""
import hashlib, json, sys, time
import numpy as np
from nbvkit import _core
from nbvkit.planning.generators.exploration import exploration_targets
lo, hi = json.loads(sys.argv[2]), json.loads(sys.argv[3])
m = _core.OccupancyMap.load(sys.argv[1], lo, hi)
out, digest = {}, hashlib.sha1()
for name, box in (("extent", None), ("workspace", (lo, hi))):
    exploration_targets(m, box)  # warm-up
    ts = []
    for _ in range(int(sys.argv[4])):
        t = time.perf_counter()
        t_ = exploration_targets(m, box)
        ts.append(time.perf_counter() - t)
    out[name] = min(ts)
    # a SurfaceTargets, or (code before it) a dict of its arrays
    field = t_.__getitem__ if isinstance(t_, dict) else lambda k: getattr(t_, k)
    out[name + "_targets"] = len(field("weight"))
    for k in ("positions", "normals", "weight"):
        digest.update(np.ascontiguousarray(field(k)).tobytes())
out["time"] = out["extent"] + out["workspace"]
out["digest"] = digest.hexdigest()
print(json.dumps(out))
"""


def main():
    ap = flown_map_parser(__doc__, iterations=60)
    ap.add_argument("--run", help="a finished mission's folder: its map.ot and workspace")
    ap.add_argument("--against", help="another checkout (or a saved package) to compare with")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        flown = flown_map(args, tmp)
        path, lo, hi = flown["path"], flown["lo"], flown["hi"]
        snippet_args = [path, json.dumps(lo), json.dumps(hi), args.repeat]
        best, same = alternate(TIME_SNIPPET, snippet_args, args.against, rounds=2)
    print(f"map {path}")
    print_best(
        best, same, "(extent + whole workspace, least of the runs)", "the same targets bit for bit"
    )


if __name__ == "__main__":
    main()
