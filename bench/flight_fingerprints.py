"""The fingerprint of every planner's flight: sha256 of trajectory.csv and map.ot per (structure,
scenario), from short missions (profile + a few views). A refactor that claims "the same flights"
prints the same table; --compare FILE names every flight that changed.

    python bench/flight_fingerprints.py --out before.json
    python bench/flight_fingerprints.py --compare before.json
"""
from __future__ import annotations

import argparse
import hashlib
import json
import sys
import tempfile
from pathlib import Path

import nbvkit
from nbvkit.scenarios import SCENARIOS

ROOT = Path(__file__).resolve().parents[1]
STRUCTURES = {
    "airliner": ROOT / "meshes" / "airliner.obj",
    "mast": ROOT / "meshes" / "mast.obj",
    "twinjet": ROOT.parent / "shared" / "meshes" / "twinjet.obj",
}


def fingerprint(mesh: Path, scenario: str, views: int) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        cfg = nbvkit.load_config(
            overrides={
                "scenario": scenario,
                "mesh": {"path": str(mesh)},
                "max_iterations": views,
                "progress": False,
                "report": {"enabled": False},
                "observability": {"enabled": False},
            }
        )
        nbvkit.Mission(cfg).run(Path(tmp) / "run")
        run = Path(tmp) / "run"
        return {
            f: hashlib.sha256((run / f).read_bytes()).hexdigest()[:16]
            for f in ("trajectory.csv", "map.ot")
        }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--views", type=int, default=12, help="views after profiling (default 12)")
    ap.add_argument("--scenarios", nargs="*", default=list(SCENARIOS))
    ap.add_argument("--structures", nargs="*", default=list(STRUCTURES))
    ap.add_argument("--out", help="write the fingerprints to this JSON file")
    ap.add_argument("--compare", help="compare with fingerprints written by --out")
    a = ap.parse_args()
    before = json.loads(Path(a.compare).read_text()) if a.compare else {}
    out, changed = {}, 0
    for s in a.structures:
        if not STRUCTURES[s].exists():
            print(f"{s}: {STRUCTURES[s]} absent, skipped")
            continue
        for sc in a.scenarios:
            key = f"{s}/{sc}"
            out[key] = fingerprint(STRUCTURES[s], sc, a.views)
            same = "" if key not in before else (" same" if before[key] == out[key] else " CHANGED")
            changed += same == " CHANGED"
            print(f"{key:24s} {out[key]['trajectory.csv']} {out[key]['map.ot']}{same}", flush=True)
    if a.out:
        Path(a.out).write_text(json.dumps(out, indent=1))
    if a.compare:
        print(f"{changed} of {len(out)} flights changed")
    return 1 if changed else 0


if __name__ == "__main__":
    sys.exit(main())
