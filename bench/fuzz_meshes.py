"""Mutation fuzz of the mesh loader (nbvkit.load_mesh): no crash, no hang, no memory blow-up.

Seeds are small valid cubes written here in every format a user is likely to pass: OBJ, binary
and ASCII STL, binary (little and big endian) and ASCII PLY, glTF (embedded buffer) and Collada
DAE. Each mutant (bit flips, byte overwrites with boundary values, truncation, chunk deletion /
duplication / insertion, numbers replaced by huge, negative or non-numeric text) is loaded in a
worker process under a memory cap (RLIMIT_AS) and a per-file timeout. Outcomes:

  ok      loaded (a mutant may still be a valid mesh)
  error   a clean ValueError / FileNotFoundError naming the problem
  memory  MemoryError (the cap was hit: a blow-up the loader should have refused)
  other   any other Python exception (unclean)
  crash   the worker died by a signal (segfault, abort)
  hang    no answer within the timeout

Run: .venv/bin/python bench/fuzz_meshes.py [--per-format N] [--seed S] [--timeout T] [--mem-mb M]
Exit status 1 if anything but ok/error happened; the offending inputs are kept in --keep DIR.
tests/test_hostile.py runs a bounded smoke of it.
"""
from __future__ import annotations

import argparse
import base64
import json
import math
import os
import random
import re
import select
import shutil
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# ------------------------------------------------------------------------------------ seeds

V = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
F = [
    (0, 2, 1),
    (0, 3, 2),
    (4, 5, 6),
    (4, 6, 7),
    (0, 1, 5),
    (0, 5, 4),
    (3, 6, 2),
    (3, 7, 6),
    (0, 4, 7),
    (0, 7, 3),
    (1, 2, 6),
    (1, 6, 5),
]


# The builders below write the seed cube (V, F) by default; tests/test_mesh.py,
# tests/test_hostile.py and bench/hostile_battery.py write their own vertices (numbers or numpy
# scalars, NaN and inf too) and faces (0-based) with them.


def _plain(verts) -> list:
    """`verts` as lists of Python numbers (numpy scalars converted; ints stay ints)."""
    return [[c.item() if hasattr(c, "item") else c for c in v] for v in verts]


def obj_file(verts=V, faces=F) -> bytes:
    lines = ["o cube"] + [f"v {x} {y} {z}" for x, y, z in _plain(verts)]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    return ("\n".join(lines) + "\n").encode()


def stl_binary_file(verts=V, faces=F) -> bytes:
    out = b"nbvkit fuzz cube".ljust(80, b" ") + struct.pack("<I", len(faces))
    for f in faces:
        out += struct.pack("<3f", 0, 0, 0)
        for i in f:
            out += struct.pack("<3f", *verts[i])
        out += b"\0\0"
    return out


def stl_ascii_file(verts=V, faces=F) -> bytes:
    verts = _plain(verts)
    s = "solid cube\n"
    for f in faces:
        s += " facet normal 0 0 0\n  outer loop\n"
        for i in f:
            s += "   vertex {} {} {}\n".format(*verts[i])
        s += "  endloop\n endfacet\n"
    return (s + "endsolid cube\n").encode()


def cube_ply(fmt: str = "binary_little_endian", nv: int | None = None, faces=F) -> bytes:
    """The seed cube as a PLY file in `fmt`; `nv` overrides the declared vertex count and
    `faces` the faces (tests/test_hostile.py builds broken files with them)."""
    head = (
        f"ply\nformat {fmt} 1.0\ncomment nbvkit fuzz cube\nelement vertex {nv or len(V)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    ).encode()
    if fmt == "ascii":
        body = "".join(f"{x} {y} {z}\n" for x, y, z in V)
        body += "".join(f"3 {a} {b} {c}\n" for a, b, c in faces)
        return head + body.encode()
    e = "<" if fmt == "binary_little_endian" else ">"
    body = b"".join(struct.pack(e + "3f", *v) for v in V)
    body += b"".join(struct.pack(e + "B3i", 3, *f) for f in faces)
    return head + body


def gltf_buffer(verts=V, faces=F) -> bytes:
    """The binary buffer of gltf_file: float32 positions, then uint16 indices padded to 4."""
    ib = b"".join(struct.pack("<3H", *f) for f in faces)
    return b"".join(struct.pack("<3f", *v) for v in verts) + ib + b"\0" * (-len(ib) % 4)


def gltf_file(verts=V, faces=F, uri=None) -> bytes:
    """A glTF of one mesh; its buffer (gltf_buffer) embedded, or in the file `uri` names."""
    buf, nvb = gltf_buffer(verts, faces), 12 * len(verts)
    if uri is None:
        uri = "data:application/octet-stream;base64," + base64.b64encode(buf).decode()
    finite = [v for v in _plain(verts) if all(math.isfinite(c) for c in v)]  # JSON has no NaN
    doc = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"byteLength": len(buf), "uri": uri}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": nvb, "target": 34962},
            {"buffer": 0, "byteOffset": nvb, "byteLength": 3 * 2 * len(faces), "target": 34963},
        ],
        "accessors": [
            {
                "bufferView": 0,
                "componentType": 5126,
                "count": len(verts),
                "type": "VEC3",
                "min": [min(v[a] for v in finite) for a in range(3)],
                "max": [max(v[a] for v in finite) for a in range(3)],
            },
            {"bufferView": 1, "componentType": 5123, "count": 3 * len(faces), "type": "SCALAR"},
        ],
    }
    return json.dumps(doc, indent=1).encode()


def dae_file(verts=V, faces=F) -> bytes:
    pos = " ".join(f"{c}" for v in _plain(verts) for c in v)
    idx = " ".join(str(i) for f in faces for i in f)
    return f"""<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="meter" meter="1"/><up_axis>Z_UP</up_axis></asset>
  <library_geometries>
    <geometry id="cube" name="cube">
      <mesh>
        <source id="cube-pos">
          <float_array id="cube-pos-array" count="{3 * len(verts)}">{pos}</float_array>
          <technique_common>
            <accessor source="#cube-pos-array" count="{len(verts)}" stride="3">
              <param name="X" type="float"/><param name="Y" type="float"/>
              <param name="Z" type="float"/>
            </accessor>
          </technique_common>
        </source>
        <vertices id="cube-vtx"><input semantic="POSITION" source="#cube-pos"/></vertices>
        <triangles count="{len(faces)}">
          <input semantic="VERTEX" source="#cube-vtx" offset="0"/>
          <p>{idx}</p>
        </triangles>
      </mesh>
    </geometry>
  </library_geometries>
  <library_visual_scenes>
    <visual_scene id="scene">
      <node id="n"><instance_geometry url="#cube"/></node>
    </visual_scene>
  </library_visual_scenes>
  <scene><instance_visual_scene url="#scene"/></scene>
</COLLADA>
""".encode()


SEEDS = {
    "obj": (".obj", obj_file),
    "stl_binary": (".stl", stl_binary_file),
    "stl_ascii": (".stl", stl_ascii_file),
    "ply_binary": (".ply", lambda: cube_ply("binary_little_endian")),
    "ply_binary_be": (".ply", lambda: cube_ply("binary_big_endian")),
    "ply_ascii": (".ply", lambda: cube_ply("ascii")),
    "gltf": (".gltf", gltf_file),
    "dae": (".dae", dae_file),
}

# ------------------------------------------------------------------------------------ mutation

_BOUNDARY = [b"\x00", b"\xff", b"\x7f", b"\x80", b"\xff\xff\xff\x7f", b"\x00\x00\x80\x7f"]
_NUMBERS = [
    "0",
    "-1",
    "1e9",
    "1e300",
    "-1e300",
    "nan",
    "inf",
    "4294967295",
    "2147483648",
    "99999999999999999999",
    "-2147483649",
    "x",
    "",
    "1e-320",
    "3.4e38",
]
_NUM_RE = re.compile(rb"-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")


def mutate(data: bytes, rng: random.Random) -> bytes:
    b = bytearray(data)
    for _ in range(rng.choice((1, 1, 1, 2, 3, 5))):
        op = rng.randrange(8)
        n = len(b)
        if n == 0:
            b += bytes([rng.randrange(256)])
            continue
        i = rng.randrange(n)
        if op == 0:  # bit flip
            b[i] ^= 1 << rng.randrange(8)
        elif op == 1:  # random byte
            b[i] = rng.randrange(256)
        elif op == 2:  # boundary value
            v = rng.choice(_BOUNDARY)
            b[i : i + len(v)] = v
        elif op == 3:  # truncate
            del b[rng.randrange(n) :]
        elif op == 4:  # delete a chunk
            del b[i : i + rng.randrange(1, 64)]
        elif op == 5:  # duplicate a chunk
            b[i:i] = b[i : i + rng.randrange(1, 64)]
        elif op == 6:  # insert random bytes
            b[i:i] = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 16)))
        else:  # a number in the text replaced
            nums = list(_NUM_RE.finditer(bytes(b)))
            if nums:
                m = rng.choice(nums)
                b[m.start() : m.end()] = rng.choice(_NUMBERS).encode()
            else:
                b[i] ^= 0x10
    return bytes(b)


# ------------------------------------------------------------------------------------ worker

_WORKER = r"""
import resource, sys
mem = int(sys.argv[1])
if mem > 0:
    resource.setrlimit(resource.RLIMIT_AS, (mem, mem))
import nbvkit
print("READY", flush=True)
for line in sys.stdin:
    path = line.rstrip("\n")
    try:
        m = nbvkit.load_mesh(path)
        out = "ok"
    except (ValueError, FileNotFoundError) as e:
        out = "error" if str(e) else "other"
    except MemoryError:
        out = "memory"
    except Exception as e:
        out = "other:" + type(e).__name__
    print("DONE " + out, flush=True)
"""


class Worker:
    def __init__(self, mem_bytes: int):
        env = dict(os.environ, OMP_NUM_THREADS="1")
        self.p = subprocess.Popen(
            [sys.executable, "-c", _WORKER, str(mem_bytes)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
            bufsize=1,
            env=env,
        )
        if self._read(120) != "READY":
            raise RuntimeError("fuzz worker did not start")

    def _read(self, timeout):
        r, _, _ = select.select([self.p.stdout], [], [], timeout)
        if not r:
            return None
        return self.p.stdout.readline().strip()

    def load(self, path: str, timeout: float) -> str:
        try:
            self.p.stdin.write(path + "\n")
            self.p.stdin.flush()
        except BrokenPipeError:
            pass
        line = self._read(timeout)
        if line is None:  # no answer: hung (or still allocating)
            self.kill()
            return "hang"
        if line == "":  # EOF: the worker died
            self.p.wait()
            return "crash" if self.p.returncode < 0 else f"exit{self.p.returncode}"
        return line.split(" ", 1)[1].split(":")[0]

    def alive(self) -> bool:
        return self.p.poll() is None

    def kill(self):
        if self.p.poll() is None:
            self.p.kill()
        self.p.wait()

    def close(self):
        try:
            self.p.stdin.close()
        except OSError:
            pass
        try:
            self.p.wait(10)
        except subprocess.TimeoutExpired:
            self.kill()


def fuzz(
    formats=tuple(SEEDS),
    per_format: int = 100,
    seed: int = 0,
    timeout: float = 10.0,
    mem_mb: int = 2048,
    keep: str | None = None,
    progress: bool = False,
) -> dict:
    """{format: {outcome: count}} over per_format mutants of each seed format. Inputs whose
    outcome is not ok/error are copied to `keep` (if given)."""
    rng = random.Random(seed)
    results: dict = {}
    tmp = Path(tempfile.mkdtemp(prefix="nbvkit-fuzz-"))
    worker = None
    try:
        for name in formats:
            ext, make = SEEDS[name]
            base = make()
            counts: dict = {}
            for k in range(per_format):
                data = mutate(base, rng)
                path = tmp / f"{name}_{k}{ext}"
                path.write_bytes(data)
                if worker is None or not worker.alive():
                    worker = Worker(mem_mb << 20)
                outcome = worker.load(str(path), timeout)
                counts[outcome] = counts.get(outcome, 0) + 1
                if outcome not in ("ok", "error") and keep:
                    Path(keep).mkdir(parents=True, exist_ok=True)
                    shutil.copy(path, Path(keep) / f"{outcome}_{path.name}")
                path.unlink()
            results[name] = counts
            if progress:
                print(f"{name:14s} {per_format:6d} inputs  {_fmt(counts)}", flush=True)
    finally:
        if worker is not None:
            worker.close()
        shutil.rmtree(tmp, ignore_errors=True)
    return results


def _fmt(counts: dict) -> str:
    keys = ["ok", "error", "memory", "other", "crash", "hang"]
    keys += sorted(k for k in counts if k not in keys)
    return "  ".join(f"{k} {counts.get(k, 0)}" for k in keys)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--per-format", type=int, default=1250, help="mutants per seed format")
    ap.add_argument("--formats", default=",".join(SEEDS), help="comma-separated seed formats")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--timeout", type=float, default=10.0, help="seconds per input")
    ap.add_argument("--mem-mb", type=int, default=2048, help="address-space cap per worker")
    ap.add_argument("--keep", default="fuzz-failures", help="folder for failing inputs")
    args = ap.parse_args()
    t0 = time.perf_counter()
    res = fuzz(
        [f for f in args.formats.split(",") if f],
        args.per_format,
        args.seed,
        args.timeout,
        args.mem_mb,
        args.keep,
        progress=True,
    )
    total: dict = {}
    for c in res.values():
        for k, v in c.items():
            total[k] = total.get(k, 0) + v
    n = sum(total.values())
    print(f"{'all':14s} {n:6d} inputs  {_fmt(total)}  ({time.perf_counter() - t0:.0f} s)")
    return 0 if set(total) <= {"ok", "error"} else 1


if __name__ == "__main__":
    sys.exit(main())
