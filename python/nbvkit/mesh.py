"""Mesh loading (PLY and OBJ by nbvkit's own readers in double precision, the rest by assimp),
conversion to and from open3d, the shipped default structure, and rays through a structure's
surface (its crossings)."""
from __future__ import annotations

import hashlib
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from . import _core
from ._core import Mesh
from ._open3d import open3d
from .limits import MAX_DATA_FILE_BYTES, check_input_file, is_number, require_type
from .settings import choice, positive, triple

_UP = {"z": "z", "y": "y", "Z": "z", "Y": "y", "auto": "auto"}
#: Collada's up axis, in the root's <asset> (the first, at the head of the file; comments out)
_DAE_UP = re.compile(rb"<up_axis>\s*([A-Za-z_]+)\s*</up_axis>")
_DAE_ASSET = re.compile(rb"<asset[\s>].*?</asset>", re.S)
_XML_COMMENT = re.compile(rb"<!--.*?-->", re.S)


@dataclass(frozen=True)
class MeshConfig:
    """The structure's mesh file."""

    path: Optional[str] = None  # None: the shipped generated airliner
    scale: float = positive(1.0)
    up: str = choice("auto", ("auto", "y", "z"))  # file's up axis; auto: glTF y, DAE its, else z
    shift: tuple = triple((0.0, 0.0, 0.0))  # m added after scale and up: results in that frame


def mesh_overrides(path=None, scale=None, up=None) -> list[str]:
    """The configuration overrides ("mesh.path=...", ...) of the mesh keys given (not None): what
    --mesh, --mesh-scale and --mesh-up add, for one run or each run of an experiment."""
    import json

    over = [] if path is None else [f"mesh.path={json.dumps(str(path))}"]
    if scale is not None:
        over.append(f"mesh.scale={float(scale)!r}")
    if up is not None:
        over.append(f"mesh.up={json.dumps(str(up))}")
    return over


def load_mesh(path: str | os.PathLike, scale: float = 1.0, up: str = "auto", shift=None) -> Mesh:
    """Load a mesh file (OBJ, STL, PLY, DAE, glTF/GLB, ...) as one triangle soup: PLY, OBJ and
    STL with nbvkit's own strict readers, in double precision (PLY: declared counts and face
    indices checked; OBJ: ``v``/``f`` geometry only, polygons triangulated, materials never
    opened; STL: binary or ASCII told by the file's size, facets of more vertices
    triangulated), the rest with assimp.

    All parts of the file are merged, each node's transform applied (in double precision; a
    mirroring one reverses its triangles' winding). ``up`` is the file's up axis:
    ``"z"`` keeps coordinates, ``"y"`` rotates file +y onto +z ((x, y, z) -> (x, -z, y)),
    ``"auto"`` takes the one its format defines (``file_up_axis``: glTF y, DAE its own). ``scale``
    multiplies coordinates (e.g. 0.001 for a millimetre file). ``shift`` (x, y, z), in metres,
    is then added to every vertex, in double precision: a georeferenced mesh (UTM coordinates)
    is flown near the origin, where OctoMap can address it (+-6.5 km at 0.2 m) and Embree's
    float32 keeps millimetres. A georeferenced PLY, OBJ or ASCII STL keeps every digit of its
    file. Binary STL stores float32 and formats read through assimp arrive in float32 (assimp's
    ``ai_real``; glTF stores float32 anyway): a file whose coordinates float32 would round by
    more than 1 mm (after ``scale``: from 32,768 m at scale 1) is refused with a ValueError
    saying how far off it would be and how to fix it (coordinates near the origin in the file
    plus ``shift``, or PLY/OBJ).
    ``path``: any path the OS accepts (str, bytes, os.PathLike; also not UTF-8). Raises
    FileNotFoundError for a missing path and ValueError naming the file for anything but a
    regular file of at most 2 GiB (a directory, a FIFO, a device), also for any file the mesh
    file refers to that assimp would open (a glTF's buffer, a material library), for unreadable
    or malformed files, a vertex of a face with a NaN or infinite coordinate, no triangle with an
    area, or naming a bad scale, up axis or shift (docs/USAGE.md, "Errors").
    """
    if up not in _UP:
        raise ValueError(f"mesh up axis must be 'auto', 'y' or 'z', got {up!r}")
    if not is_number(scale):  # (a string's '2' was read as 2)
        raise ValueError(f"mesh scale must be a number, got {scale!r}")
    scale = float(scale)
    if shift is not None:
        try:
            shift = np.asarray(shift, dtype=float).reshape(3)
        except (TypeError, ValueError):
            raise ValueError(f"mesh shift must be 3 numbers (x, y, z) in metres, got {shift!r}")
        if not np.isfinite(shift).all():
            raise ValueError(f"mesh shift must be finite, got {shift.tolist()}")
    p = check_input_file(path, "mesh file", MAX_DATA_FILE_BYTES)
    if _format_of(p) == "gltf":
        _check_gltf_extensions(p)
    mesh = _core._load_mesh(os.fsencode(p), scale, file_up_axis(p, up))
    if shift is not None and shift.any():
        v = np.asarray(mesh.vertices)
        moved = v + shift
        lost = float(np.max(np.abs((moved - shift) - v), initial=0.0))  # float64's rounding
        if lost > SHIFT_TOLERANCE_M:
            raise ValueError(
                f"mesh shift {shift.tolist()} moves the structure so far that float64 rounds its "
                f"coordinates by up to {lost:.3g} m (more than {SHIFT_TOLERANCE_M * 1e3:g} mm): "
                "shift it nearer the origin"
            )
        mesh = Mesh(moved, mesh.faces)
    reach = float(np.max(np.abs(np.asarray(mesh.vertices)), initial=0.0))
    if reach > MAX_COORDINATE_M:  # (the ray caster refused it later, naming no argument)
        raise ValueError(
            f"mesh coordinates reach {reach:.3g} m after scale {scale:g} and shift, beyond "
            f"{MAX_COORDINATE_M:g} m: a wrong scale (0.001 reads millimetres as metres)?"
        )
    return mesh


#: the most a mesh shift may round a vertex by (float64 at the shifted coordinates), m
SHIFT_TOLERANCE_M = 1e-3
#: the farthest a loaded mesh's vertex may lie from the origin (the core's kMaxCoordinate), m
MAX_COORDINATE_M = _core.MAX_COORDINATE


#: glTF extensions that change only a structure's appearance (materials, textures, lights):
#: assimp may ignore them, required or not, with the geometry intact; Draco it decodes
_GLTF_READ = re.compile(r"^((KHR|EXT|MSFT|ADOBE)_(materials?|texture|lights)_|KHR_draco_mesh_)")
#: a glTF's JSON is parsed for its required extensions up to this size (larger: not checked)
_GLTF_JSON_MAX = 512 << 20


#: suffixes nbvkit's own readers take, whatever the file holds (a binary STL's free 80-byte
#: header may begin "glTF")
_OWN_READERS = (".ply", ".obj", ".stl")


def _format_of(p: Path) -> str:
    """ "gltf", "collada" or "" (any other) for the mesh file `p` (a regular file), told as the
    loader tells it: by its suffix, else its head (a GLB's magic, a JSON object naming its
    "asset", ``<COLLADA``). PLY, OBJ and STL are nbvkit's own readers' whatever they hold."""
    suffix = p.suffix.lower()
    if suffix in _OWN_READERS:
        return ""
    if suffix in (".gltf", ".glb"):
        return "gltf"
    if suffix in (".dae", ".xml"):
        return "collada"
    with open(p, "rb") as f:
        head = f.read(4096)
    if head[:4] == b"glTF" or (head.lstrip()[:1] == b"{" and b'"asset"' in head):
        return "gltf"
    return "collada" if b"<COLLADA" in head else ""


def _gltf_json(p: Path) -> dict | None:
    """The JSON of a glTF file (a .gltf's text, a GLB's first chunk); None for one too large or
    malformed to tell."""
    import json
    import struct

    with open(p, "rb") as f:
        head = f.read(20)
        if head[:4] == b"glTF" and len(head) == 20:  # GLB: header, then the JSON chunk's
            n, kind = struct.unpack("<I4s", head[12:20])
            text = f.read(n) if kind == b"JSON" and n <= _GLTF_JSON_MAX else b""
        elif head.lstrip()[:1] == b"{" and os.fstat(f.fileno()).st_size <= _GLTF_JSON_MAX:
            text = head + f.read()
        else:
            return None
    try:
        doc = json.loads(text)
    except ValueError:
        return None  # the loader names what is wrong with it
    return doc if isinstance(doc, dict) and "asset" in doc else None


def _check_gltf_extensions(p: Path) -> None:
    """ValueError for a glTF or GLB file whose top-level extensionsRequired names an extension
    assimp does not read (but for its look's): the glTF specification has a loader refuse what
    it cannot read, and assimp 5.2 reads quantized (KHR_mesh_quantization), meshopt-compressed
    and instanced meshes wrongly or not at all, without a word."""
    doc = _gltf_json(p)
    required = doc.get("extensionsRequired") if doc else None
    for name in required if isinstance(required, list) else ():
        if isinstance(name, str) and not _GLTF_READ.match(name):
            raise ValueError(
                f"cannot read mesh '{p}': it requires the glTF extension {name[:60]}, which "
                "nbvkit's glTF reader (assimp) does not read: its geometry would come out wrong. "
                "Write the file without it (e.g. gltf-transform dequantize, or a decoder of the "
                "compression)"
            )


def file_up_axis(path, up: str = "auto") -> str:
    """The up axis ("y" or "z") the mesh file `path` is loaded with: `up` itself unless it is
    "auto"; then the one the file's format defines (told as the loader tells it: _format_of):
    glTF and GLB y (the glTF 2.0 specification: +Y is up), Collada its root
    ``<asset><up_axis>`` (Y_UP where it gives none, as the Collada specification has it), any
    other format z: OBJ, STL and PLY record none, and FBX, 3DS and the rest
    assimp reads are taken as they are. A Collada file whose up axis is X_UP is a ValueError
    naming it (set mesh.up to load it)."""
    if _UP.get(up) is None:
        raise ValueError(f"mesh up axis must be 'auto', 'y' or 'z', got {up!r}")
    if _UP[up] != "auto":
        return _UP[up]
    if Path(os.fsdecode(path)).suffix.lower() in _OWN_READERS:
        return "z"  # nbvkit's own readers, whatever the file holds: nothing to read
    p = check_input_file(path, "mesh file", MAX_DATA_FILE_BYTES)  # not a FIFO, a device, ...
    kind = _format_of(p)
    if kind != "collada":
        return "y" if kind == "gltf" else "z"
    with open(p, "rb") as f:
        head = f.read(1 << 20)
    asset = _DAE_ASSET.search(_XML_COMMENT.sub(b"", head))  # the root's: the first one
    found = _DAE_UP.search(asset.group(0)) if asset else None
    axis = found.group(1).upper() if found else b"Y_UP"
    if axis in (b"Y_UP", b"Z_UP"):
        return axis[:1].decode().lower()
    raise ValueError(
        f"mesh file {os.fsdecode(path)}: its <up_axis> is {axis.decode(errors='replace')[:20]}, "
        "and nbvkit turns y-up and z-up files only: set mesh.up (--mesh-up) y or z to load it"
    )


def mesh_from_open3d(o3d_mesh) -> Mesh:
    """Build a Mesh from an ``open3d.geometry.TriangleMesh``."""
    if not (hasattr(o3d_mesh, "vertices") and hasattr(o3d_mesh, "triangles")):
        raise TypeError(
            f"o3d_mesh must be an open3d.geometry.TriangleMesh, got {type(o3d_mesh).__name__}"
        )
    v = np.asarray(o3d_mesh.vertices, dtype=np.float64)
    f = np.asarray(o3d_mesh.triangles, dtype=np.int32)
    return Mesh(v, f)


def mesh_to_open3d(mesh: Mesh):
    """An ``open3d.geometry.TriangleMesh`` of a Mesh (with vertex normals, for viewing)."""
    require_type(mesh, Mesh, "mesh", "an nbvkit.Mesh")
    o3d = open3d()

    m = o3d.geometry.TriangleMesh(  # (open3d takes writeable arrays only: copies)
        o3d.utility.Vector3dVector(np.array(mesh.vertices)),
        o3d.utility.Vector3iVector(np.array(mesh.faces)),
    )
    m.compute_vertex_normals()
    return m


Mesh.from_open3d = staticmethod(mesh_from_open3d)
Mesh.to_open3d = mesh_to_open3d


def mesh_file_sha1(path) -> str | None:
    """SHA-1 of the mesh file at `path` (its own bytes: a .gltf's buffer files are not read),
    or None where it cannot be read."""
    try:
        p = check_input_file(path, "mesh file")  # a FIFO would block open() forever
        with open(p, "rb") as f:
            return hashlib.file_digest(f, "sha1").hexdigest()
    except (OSError, ValueError):
        return None


#: World.mesh_path (and a summary's "mesh") of a mesh given in memory, not read from a file
IN_MEMORY_MESH = "<in-memory mesh>"


def flown_mesh(config, summary: dict):
    """(the Mesh a run flew, as it flew it, or None; why not) from its config and summary.json:
    the config's mesh.path (the default airliner where none), scale, up and shift, where the file
    is found from here and is the one flown (summary.json's mesh_sha1, where recorded)."""
    if summary.get("mesh") == IN_MEMORY_MESH:
        return None, "the run flew a mesh given in memory, which its folder does not hold"
    m = config.mesh
    try:
        path = default_mesh_path() if m.path is None else Path(os.fspath(m.path)).expanduser()
    except OSError as e:  # (the default airliner not installed)
        return None, e.strerror or str(e)
    if not path.is_file():
        return None, f"its mesh '{path}' is not found from here ({Path.cwd()})"
    flown = summary.get("mesh_sha1")
    if flown is not None and mesh_file_sha1(path) != flown:
        return None, f"its mesh '{path}' has changed since the run (summary.json's mesh_sha1)"
    try:
        return load_mesh(path, scale=m.scale, up=m.up, shift=m.shift), ""
    except (OSError, ValueError) as e:
        return None, f"its mesh '{path}' could not be read: {e}"


def default_mesh_path() -> Path:
    """Path of the shipped default structure: the generated airliner (meshes/airliner.obj)."""
    here = Path(__file__).resolve().parent
    for cand in (here / "data" / "airliner.obj", here.parent.parent / "meshes" / "airliner.obj"):
        if cand.exists():
            return cand
    raise FileNotFoundError(
        2, "The default airliner mesh is not installed", str(here / "data" / "airliner.obj")
    )


def fibonacci_sphere(n: int) -> np.ndarray:
    """(n, 3) unit vectors spread evenly over the sphere (a Fibonacci lattice)."""
    i = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * i / n)
    th = math.pi * (1 + 5**0.5) * i
    return np.stack([np.cos(th) * np.sin(phi), np.sin(th) * np.sin(phi), np.cos(phi)], axis=1)


def check_path_clear(scene, pts, what: str = "path") -> None:
    """ValueError when a leg of the path `pts` (P, 3) meets the surface of `scene` (a
    RaycastScene): a flight through the structure. Names the leg and where it meets it; a path
    that is not (P, 3) finite points is a ValueError too."""
    pts = np.asarray(pts, float)
    if pts.ndim != 2 or pts.shape[1] != 3 or not np.isfinite(pts).all():
        raise ValueError(f"{what} must be (P, 3) finite points, got shape {pts.shape}")
    a, b = pts[:-1], pts[1:]
    length = np.linalg.norm(b - a, axis=1)
    legs = np.flatnonzero(length > 0)
    if not len(legs):
        return
    dirs = (b - a)[legs] / length[legs, None]
    t, prim = scene.intersect(a[legs], dirs, 0.0, np.inf)
    through = np.flatnonzero((prim >= 0) & (t <= length[legs]))
    if len(through):
        i, leg = through[0], legs[through[0]]
        raise ValueError(
            f"{what} passes through the structure: its leg {leg} from "
            f"{np.round(a[leg], 3).tolist()} to {np.round(b[leg], 3).tolist()} meets its surface "
            f"at {np.round(a[leg] + t[i] * dirs[i], 3).tolist()}; the vehicle did not move"
        )


def surface_crossings(scene, bounds, origin, dirs, max_crossings: int = 64):
    """(count, first): (N,) times each ray from `origin` (3,) along `dirs` (N, 3) crosses the
    surface of `scene` (a RaycastScene over a mesh whose `bounds` are (lo, hi)), and (N,) the
    distance to its first crossing (inf: none). Faces met at the same point (a shared edge,
    coincident faces) count once: the next search starts 1e-6 of the structure's size past each
    hit."""
    lo, hi = np.asarray(bounds, float)
    eps = 1e-6 * max(float(np.max(hi - lo)), 1e-3)
    count = np.zeros(len(dirs), int)
    o = np.repeat(np.asarray(origin, float).reshape(1, 3), len(dirs), axis=0)
    live = np.arange(len(dirs))
    first = None
    for _ in range(max_crossings):
        t, prim = scene.intersect(o[live], dirs[live], 0.0, np.inf)
        if first is None:
            first = t
        hit = prim >= 0
        live = live[hit]
        if len(live) == 0:
            break
        count[live] += 1
        o[live] += (t[hit] + eps)[:, None] * dirs[live]
    return count, first
