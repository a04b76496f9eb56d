"""View scoring speed: the 80 CGVS candidates of one iteration at 0.2 m with the default ray set
(47 x 34 rays each), walking the dense mirror with a 3D-DDA vs reading every cell through OctoMap's
search (the authors' way) over the same rays, in the same run; 1 thread and all threads. Also the
total-entropy query. The map is the state after a short Scenario 1 mission on the airliner (or
--mesh), so the views see a realistic mix of free, occupied and unknown cells.

Run: .venv/bin/python bench/bench_views.py [--mesh PATH] [--iterations N] [--repeat R]
"""
from __future__ import annotations


import numpy as np

import nbvkit
from _timing import flown_map_parser, flown_mission, median_time
from nbvkit import _core
from nbvkit.sampling import candidate_poses


def main():
    args = flown_map_parser(__doc__, 60).parse_args()
    m = flown_mission(args)
    pose = m.world.state.pose
    cands = candidate_poses(pose)
    # exactly what the mission's planner passes
    kw = dict(
        camera=m.world.view_camera, utility=m.planner.score.options, validity=m.world.validity()
    )
    threads = nbvkit.get_num_threads()
    print(f"map after {len(m.records)} iterations of scenario {args.scenario}: {m.map.counts()}")
    res = {}
    for nt in sorted({1, threads}):
        nbvkit.set_num_threads(nt)
        a = _core.evaluate_views(m.map, cands, pose, backend="grid", **kw)
        b = _core.evaluate_views(m.map, cands, pose, backend="octree", **kw)
        assert np.array_equal(a["status"], b["status"]) and np.allclose(
            a["gain"], b["gain"], rtol=1e-6
        )
        tm = median_time(
            lambda: _core.evaluate_views(m.map, cands, pose, backend="grid", **kw), args.repeat
        )
        to = median_time(
            lambda: _core.evaluate_views(m.map, cands, pose, backend="octree", **kw),
            max(1, args.repeat // 2),
        )
        res[nt] = (tm, to, int((a["status"] == 0).sum()), int(a["cells"].sum()))
    nbvkit.set_num_threads(0)
    print(
        f"{'threads':>7} {'grid DDA ms':>14} {'octree search ms':>17} "
        f"{'speed-up':>9} {'valid':>6} {'cells':>12}"
    )
    for nt, (tm, to, nv, cells) in res.items():
        print(f"{nt:>7} {tm * 1e3:>14.1f} {to * 1e3:>17.1f} {to / tm:>8.1f}x {nv:>6} {cells:>12,}")
    te = median_time(m.map.total_entropy, 1000)
    tr = median_time(m.map.recompute_total_entropy, 5)
    print(f"total entropy: incremental {te * 1e6:.2f} us, full sweep {tr * 1e3:.2f} ms")


if __name__ == "__main__":
    main()
