"""What a mission's mapping stage is made of: a mission flown under cProfile, and the time per
call of each core call that maps a scan - a camera frame into the occupancy map, the camera cloud
and the surface observations at once (integrate_frame, World.integrate's), and the laser's scans
into the map (OccupancyMap.integrate) and the laser cloud (SurfaceCloud.add), each counted where
it was called from. Prints figures; asserts nothing.

    .venv/bin/python bench/mapping_split.py                   # Scenario 5, start 0, airliner
    .venv/bin/python bench/mapping_split.py --scenario surface --mesh ../shared/meshes/twinjet.obj
"""
from __future__ import annotations

import argparse
import cProfile
import pstats

from nbvkit.config import load_config
from nbvkit.mission import Mission

CALLS = {
    "integrate_frame": "camera frame (all 3)",
    "integrate": "map integration",
    "add": "cloud",
    "add_scan": "surface observations",
}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="5")
    ap.add_argument("--mesh", default=None)
    ap.add_argument("--start", type=int, default=0)
    args = ap.parse_args()
    over = [f"scenario={args.scenario}", f"start={args.start}", "progress=false"]
    if args.mesh:
        over.append(f"mesh.path={args.mesh}")
    mission = Mission(load_config(overrides=over))
    prof = cProfile.Profile()
    s = prof.runcall(mission.run)
    stats = pstats.Stats(prof).stats  # (file, line, name) -> (cc, nc, tt, ct, callers)
    print(
        f"scenario {args.scenario}, start {args.start}: {s['iterations']} views, "
        f"{s['camera_frames']} camera frames in flight"
    )
    for (_, _, name), (_, _, _, _, callers) in stats.items():
        short = name.split(".")[-1].rstrip(">")
        if not (name.startswith("<built-in method nbvkit._core.") and short in CALLS):
            continue
        for (file, _, caller), (_, calls, _, total) in callers.items():
            where = "planner loop" if file.endswith("planner.py") else f"world.{caller}"
            per = f", {total / calls * 1e3:.2f} ms per call" if calls else ""
            print(f"  {CALLS[short]:22s} {where:28s} {calls:5d} calls, {total:6.2f} s{per}")


if __name__ == "__main__":
    main()
