"""The observable share of each structure's surface with the fixed level camera and with the
camera on its gimbal (camera.gimbal_pitch_deg, 30 deg up to straight down), in the recommended
planner's workspace and in the flight envelope of surface_gimbal (workspace.margin_z null: up
to the camera's far stand-off above the top). Prints a table; asserts nothing.

    .venv/bin/python bench/observable_gimbal.py                       # shipped and shared meshes
    .venv/bin/python bench/observable_gimbal.py --meshes meshes/mast.obj
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from nbvkit.config import load_config
from nbvkit.evaluation import Evaluator
from nbvkit.mesh import load_mesh
from nbvkit.observability import observable_surface

ROOT = Path(__file__).resolve().parent.parent
SHARED = ROOT.parent / "shared" / "meshes"
MESHES = [ROOT / "meshes" / "airliner.obj", ROOT / "meshes" / "mast.obj"]
MESHES += [SHARED / f for f in ("twinjet.obj", "cessna.obj", "truss_bridge.obj")]
SETTINGS = {
    "level": ["scenario=surface", "camera.gimbal_pitch_deg=[0,0]"],
    "gimbal": ["scenario=surface"],
    "gimbal + envelope": ["scenario=surface_gimbal"],
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", nargs="*", type=Path, default=[m for m in MESHES if m.exists()])
    args = ap.parse_args()
    print("| structure | " + " | ".join(SETTINGS) + " |")
    print("|---|" + "---|" * len(SETTINGS))
    for path in args.meshes:
        mesh = load_mesh(path)
        cells = []
        for over in SETTINGS.values():
            cfg = load_config(overrides=over)
            ev = Evaluator(mesh, gt_density=cfg.evaluation.gt_density, seed=cfg.seed)
            t0 = time.perf_counter()
            obs = observable_surface(mesh, cfg, evaluator=ev)
            ev.set_observable(obs.observable)
            share = ev.coverage([])["observable_area_fraction"]
            cells.append(f"{share:.1%} ({time.perf_counter() - t0:.0f} s)")
        print(f"| {path.stem} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
