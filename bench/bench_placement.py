"""Placing candidate views at surface patches (``placement.place_views``: along each patch's
normal at the stand-offs, moved into the navigation space), the step of every coverage-tour plan,
on the patches of a flown map, with this checkout and (--against DIR) another one, each in a
process of its own, alternating; the views must be the same to the last bit.

    .venv/bin/python bench/bench_placement.py --against /tmp/before
    .venv/bin/python bench/bench_placement.py --mesh ../shared/meshes/office_building.obj --gimbal
"""
from __future__ import annotations

import json
import tempfile
from pathlib import Path

import numpy as np

from _timing import alternate, flown_map_parser, flown_mission, print_best
from nbvkit import _core
from nbvkit.planning.parts import PlanningContext
from nbvkit.planning.placement import target_patches

TIME_SNIPPET = r"""
import hashlib, json, sys, time
import numpy as np
from nbvkit.config import load_config
from nbvkit.planning.placement import Patches, place_views
cfg = load_config(overrides=json.loads(sys.argv[2]))
d, repeat = np.load(sys.argv[1]), int(sys.argv[3])
patches = Patches(d["centers"], d["normals"], d["weights"])
bounds = (d["lo"], d["hi"])
times = []
for _ in range(repeat):
    t = time.perf_counter()
    views, owner = place_views(patches, cfg.camera, cfg.placement, bounds)
    times.append(time.perf_counter() - t)
digest = hashlib.sha256(np.ascontiguousarray(views).tobytes() + owner.tobytes()).hexdigest()
print(json.dumps({"time": min(times), "views": len(views), "digest": digest}))
"""


def main():
    ap = flown_map_parser(__doc__, iterations=60)
    ap.set_defaults(scenario="surface")
    ap.add_argument("--against", help="another checkout (or a saved package) to compare with")
    ap.add_argument("--gimbal", action="store_true", help="placement.gimbal (pitched views)")
    args = ap.parse_args()
    m = flown_mission(args)
    w, ctx = m.world, PlanningContext.of(m.config)
    targets = _core.surface_targets(w.map, w.surface, ctx.targets)
    p = target_patches(targets, ctx.placement.cluster(ctx.camera))
    over = [f"scenario={args.scenario}"] + (["placement.gimbal=true"] if args.gimbal else [])
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "patches.npz"
        np.savez(path, centers=p.centers, normals=p.normals, weights=p.weights,
                 lo=w.workspace.nav_min, hi=w.workspace.nav_max)  # fmt: skip
        best, same = alternate(TIME_SNIPPET, [path, json.dumps(over), args.repeat], args.against, 2)
    print(f"{len(p.weights)} patches after {args.iterations} views ({args.scenario}), {over}")
    print_best(best, same, f"a call (least of {args.repeat} x 2)", "the same views to the last bit")


if __name__ == "__main__":
    main()
