r"""Coverage along the profiling flight: how much of a structure a planner's profile has covered
after each given distance flown (docs/RESULTS.md, the office building).

    .venv/bin/python bench/coverage_along_profile.py --mesh ../shared/meshes/office_building.obj \
        --distances 100,147 --starts 5
    .venv/bin/python bench/coverage_along_profile.py --scenario profile \
        --set profiling.camera_step=1

Flies the profiling stage of the scenario (default: surface, the recommended planner) from each
start, recording every laser scan and camera frame with the distance flown when it was taken. The
mission's clouds are then rebuilt scan by scan (the same voxel filters and height cut), up to each
distance, and evaluated as the mission evaluates its clouds: area coverage at 0.05 m of the whole
surface. The last column is the profile's end (the return into the navigation space included);
its figure equals the mission's `profile.area_coverage`. Prints one row per start and their mean.
"""
from __future__ import annotations

import argparse

import numpy as np

from nbvkit.config import Config
from nbvkit.mission import Mission
from nbvkit.world import World, surface_clouds


class _Recorder:
    """Wraps World.integrate to log (distance flown, sensor, hits) per scan."""

    def __init__(self):
        self.log: list[tuple[float, str, np.ndarray]] = []
        self._integrate = World.integrate

    def __enter__(self):
        rec = self

        def integrate(world, scan, kind="view"):
            sensor = World.SENSOR_OF[kind]
            rec.log.append((world.state.distance_m, sensor, np.asarray(scan.hits, float)))
            return rec._integrate(world, scan, kind)

        World.integrate = integrate
        return self

    def __exit__(self, *exc):
        World.integrate = self._integrate


def coverage_along(mission: Mission, log, distances) -> list[float]:
    """Area coverage at 0.05 m of the clouds built from the scans taken within each distance
    (the log is in flight order, so each scan is added once, before the first distance past it)."""
    clouds = dict(
        zip(("camera", "laser"), surface_clouds(mission.config, mission.world.mesh.bounds))
    )
    out = [0.0] * len(distances)
    k = 0
    for i in np.argsort(distances, kind="stable"):
        while k < len(log) and log[k][0] <= distances[i] + 1e-9:
            clouds[log[k][1]].add(log[k][2])
            k += 1
        cam, las = clouds["camera"].points, clouds["laser"].points
        pts = np.vstack([cam, las]) if len(las) else cam
        out[i] = mission.evaluator(pts)["area_coverage"]["0.05"] if len(pts) else 0.0
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mesh", default=None, help="structure mesh (default: the shipped airliner)")
    ap.add_argument("--scenario", default="surface")
    ap.add_argument("--starts", type=int, default=5)
    ap.add_argument("--distances", default="100,147", help="comma-separated, m")
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE")
    args = ap.parse_args()
    distances = [float(x) for x in args.distances.split(",")]
    rows = []
    print(
        f"{'start':>5} {'profile m':>10} "
        + " ".join(f"{f'@{d:g} m':>9}" for d in distances)
        + f" {'end':>16}"
    )
    for k in range(args.starts):
        keys = [f"scenario={args.scenario}", f"start={k}", "max_iterations=0", "progress=false"]
        keys += [f"mesh.path={args.mesh}"] if args.mesh else []
        mission = Mission(Config().with_overrides(keys + list(args.set)))
        with _Recorder() as rec:
            summary = mission.run()
        if not summary.get("profiling"):
            raise SystemExit(f"scenario {args.scenario!r} flies no profile")
        end = max(flown for flown, _, _ in rec.log)
        cov = coverage_along(mission, rec.log, distances + [end])
        rows.append(cov)
        cells = " ".join(f"{100 * c:8.2f}%" for c in cov[:-1])
        print(
            f"{k:>5} {summary['profile']['distance_m']:10.1f} {cells} "
            f"{100 * cov[-1]:6.2f}% @{end:5.1f} m"
        )
    mean = np.mean(rows, axis=0)
    print(f"{'mean':>5} {'':>10} " + " ".join(f"{100 * c:8.2f}%" for c in mean[:-1]))


if __name__ == "__main__":
    main()
