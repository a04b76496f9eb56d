"""How close a mission's flight comes to the structure: the true distance (open3d's point
queries on the mesh as the mission placed it, not nbvkit's map) from every flown segment,
sampled every 2 cm, against the vehicle's collision radius; with --against-set, the same mission
again with other settings, and with --against DIR, another checkout's code.

    .venv/bin/python bench/flight_clearance.py --set start=1
    .venv/bin/python bench/flight_clearance.py --mesh M --against-set vehicle.keep_off_hits=false

Prints per mission: views, area coverage at 0.05 m, distance flown, the least clearance, and the
flown segments closer than the radius and than the radius less half a map cell's diagonal (the
map's quantization).
"""
from __future__ import annotations

from pathlib import Path

from _timing import checkouts, mesh_parser, run_snippet, table_header

SNIPPET = r"""
import csv, json, math, sys, tempfile
from pathlib import Path
import numpy as np, open3d as o3d
from nbvkit.config import load_config
from nbvkit.mission import Mission
from nbvkit.world import World
over = ["progress=false", "report.enabled=false", "observability.enabled=false", *sys.argv[2:]]
if sys.argv[1]:
    over.append(f"mesh.path={sys.argv[1]}")
cfg = load_config(overrides=over)
with tempfile.TemporaryDirectory() as tmp:
    s = Mission(cfg).run(Path(tmp) / "run")
    rows = list(csv.DictReader(open(Path(tmp) / "run" / "flight.csv")))
mesh = World(cfg).mesh
scene = o3d.t.geometry.RaycastingScene()
scene.add_triangles(o3d.core.Tensor(np.asarray(mesh.vertices, np.float32)),
                    o3d.core.Tensor(np.asarray(mesh.faces, np.uint32)))
P = np.array([[float(r[k]) for k in "xyz"] for r in rows])
least = []
for a, b in zip(P[:-1], P[1:]):
    pts = np.linspace(a, b, max(2, int(math.ceil(np.linalg.norm(b - a) / 0.02)) + 1))
    least.append(scene.compute_distance(o3d.core.Tensor(pts.astype(np.float32))).numpy().min())
least = np.array(least)
r, cell = cfg.vehicle.collision_radius, cfg.map.resolution
print(json.dumps({"views": s["views"], "coverage": s["area_coverage"]["0.05"],
                  "distance": s["distance_m"], "least": float(least.min()),
                  "below_r": int((least < r).sum()),
                  "below_r_cell": int((least < r - 0.5 * math.sqrt(3) * cell).sum()),
                  "segments": len(least), "radius": r}))
"""


def main() -> None:
    ap = mesh_parser(__doc__)
    ap.add_argument("--against", help="another checkout (or saved package) to fly as well")
    ap.add_argument("--against-set", nargs="*", default=[], help="or these overrides as well")
    ap.add_argument("--set", nargs="*", default=[], help="config overrides for every mission")
    a = ap.parse_args()
    arms = [(label, package, []) for label, package in checkouts(a.against)]
    if a.against_set:
        arms.append(("with " + " ".join(a.against_set), None, a.against_set))
    table_header(
        "views", "area cov. @0.05 m", "flown", "least clearance", "segments < radius",
        "< radius - half a cell diagonal", "segments",
    )  # fmt: skip
    for label, package, extra in arms:
        mesh = str(Path(a.mesh).resolve()) if a.mesh else ""
        r = run_snippet(SNIPPET, [mesh, *a.set, *extra], package)
        print(
            f"| {label} | {r['views']} | {100 * r['coverage']:.2f} % | {r['distance']:.1f} m | "
            f"{r['least']:.3f} m (radius {r['radius']:g}) | {r['below_r']} | "
            f"{r['below_r_cell']} | {r['segments']} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
