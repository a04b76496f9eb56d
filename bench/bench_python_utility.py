"""A view utility in Python vs in C++: the paper's information gain over the 80 CGVS candidates of
one iteration (47 x 34 rays each at 0.2 m), scored by evaluate_views' ig utility (the baseline, no
memo: every view walked) and by candidate_rays (the distinct cells each candidate's rays reach,
one C++ call) + the same gain in numpy (nbvkit.planning.utilities.information_gain), in the same
run, on the same candidates; 1 thread and all threads. The map is the state after a short
Scenario 1 mission on the airliner (or --mesh). The two agree (gain to 1e-6, cells exactly)
before anything is timed.

Run: .venv/bin/python bench/bench_python_utility.py [--mesh PATH] [--iterations N] [--repeat R]
"""
from __future__ import annotations

import time

import numpy as np

import nbvkit
from _timing import flown_map_parser, flown_mission
from nbvkit import _core
from nbvkit.planning.utilities import PythonUtility, information_gain
from nbvkit.sampling import candidate_poses


def timed(fn) -> float:
    """Wall time (s) of one call of fn."""
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def main():
    args = flown_map_parser(__doc__, 20).parse_args()
    m = flown_mission(args)
    world = m.world
    pose = world.state.pose
    cands = candidate_poses(pose)
    k = len(cands)
    ig_options = _core.UtilityOptions(name="ig")
    kw = dict(camera=world.view_camera, validity=world.validity(), surface=world.surface)
    util = PythonUtility(information_gain(world.map.options))

    def baseline():
        return _core.evaluate_views(world.map, cands, pose, utility=ig_options, **kw)

    def rays():
        return _core.candidate_rays(world.map, cands, pose, utility=util.options, **kw)

    def python_utility():
        return util.score_rays(rays())

    a, b, r = baseline(), python_utility(), rays()
    valid = a["status"] == 0
    assert np.array_equal(a["status"], b["status"]) and np.array_equal(a["cells"], b["cells"])
    assert np.allclose(a["gain"][valid], b["gain"][valid], rtol=1e-6, atol=0)
    nbytes = sum(getattr(r, f).nbytes for f in ("index", "centers", "probability", "logodds"))
    nbytes += sum(getattr(r, f).nbytes for f in ("state", "range", "incidence", "seen", "hits"))
    print(f"map after {len(m.records)} iterations of scenario {args.scenario}: {m.map.counts()}")
    print(
        f"{k} candidates, {int(valid.sum())} valid; candidate_rays: {r.num_cells:,} cells "
        f"({r.num_cells / max(1, int((np.diff(r.offsets) > 0).sum())):,.0f} per walked view, "
        f"{nbytes / 2**20:.1f} MiB), ig counts {int(a['cells'].sum()):,} of them"
    )

    threads = nbvkit.get_num_threads()
    res = {}
    for nt in sorted({1, threads}):
        nbvkit.set_num_threads(nt)
        rr = rays()
        parts = [baseline, rays, lambda: util.fn(rr), python_utility]
        # interleaved, one call of each per round, so that a slower spell of a shared machine
        # weighs on all four alike; medians over the rounds
        for f in parts:
            f()  # warm-up
        times = np.array([[timed(f) for f in parts] for _ in range(args.repeat)])
        res[nt] = np.median(times, axis=0)
    nbvkit.set_num_threads(0)
    print(
        f"{'threads':>7} {'ig (C++) ms':>12} {'rays ms':>9} {'numpy ms':>9} "
        f"{'rays+numpy ms':>14} {'ig ms/cand':>11} {'py ms/cand':>11} {'ratio':>7}"
    )
    for nt, (t_ig, t_rays, t_fn, t_py) in res.items():
        print(
            f"{nt:>7} {t_ig * 1e3:>12.1f} {t_rays * 1e3:>9.1f} {t_fn * 1e3:>9.1f} "
            f"{t_py * 1e3:>14.1f} {t_ig * 1e3 / k:>11.3f} {t_py * 1e3 / k:>11.3f} "
            f"{t_py / t_ig:>6.1f}x"
        )
    print("ratio: (candidate_rays + numpy utility) / evaluate_views(ig), same candidates and map")


if __name__ == "__main__":
    main()
