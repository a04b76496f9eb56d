"""Mesh loading through assimp (formats, merging, up axis, scale), sampling, and bad input."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

import nbvkit
from conftest import box_mesh, shared_mesh

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "bench"))

from fuzz_meshes import (  # noqa: E402  (the fuzz's file builders)
    F as CUBE_F,
    V as CUBE_V,
    cube_ply,
    dae_file,
    gltf_buffer,
    gltf_file,
    obj_file,
    stl_binary_file,
)

TRI_OBJ = """# two parts
o first
v 0 0 0
v 1 0 0
v 0 1 0
f 1 2 3
o second
v 0 0 2
v 2 0 2
v 0 2 2
v 2 2 2
f 4 5 6
f 5 7 6
"""

# A Collada file with two instanced nodes: the same triangle translated by +10 m in x in the second.
DAE = """<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="meter" meter="1"/><up_axis>Z_UP</up_axis></asset>
  <library_geometries>
    <geometry id="tri" name="tri"><mesh>
      <source id="tri-pos"><float_array id="tri-pos-array" count="9">0 0 0 1 0 0 0 1 0</float_array>
        <technique_common><accessor source="#tri-pos-array" count="3" stride="3">
          <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
        </accessor></technique_common></source>
      <vertices id="tri-verts"><input semantic="POSITION" source="#tri-pos"/></vertices>
      <triangles count="1"><input semantic="VERTEX" source="#tri-verts" offset="0"/>
        <p>0 1 2</p></triangles>
    </mesh></geometry>
  </library_geometries>
  <library_visual_scenes><visual_scene id="Scene">
    <node id="a"><instance_geometry url="#tri"/></node>
    <node id="b"><matrix>1 0 0 10 0 1 0 0 0 0 1 0 0 0 0 1</matrix>
      <instance_geometry url="#tri"/></node>
  </visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#Scene"/></scene>
</COLLADA>
"""


def test_obj_parts_are_merged(tmp_path):
    p = tmp_path / "parts.obj"
    p.write_text(TRI_OBJ)
    m = nbvkit.load_mesh(p)
    assert m.num_triangles == 3
    assert m.vertices.dtype == np.float64 and m.vertices.shape[1] == 3
    assert m.faces.dtype == np.int32 and m.faces.shape == (3, 3)
    assert m.area == pytest.approx(0.5 + 4.0)


def test_collada_node_transforms_are_applied(tmp_path):
    p = tmp_path / "two.dae"
    p.write_text(DAE)
    m = nbvkit.load_mesh(p)
    assert m.num_triangles == 2
    xs = np.sort(m.vertices[:, 0])
    assert xs.min() == pytest.approx(0.0) and xs.max() == pytest.approx(11.0)


def _outward(m, centres) -> bool:
    """Whether every triangle of `m` faces away from the nearest of `centres` (convex parts)."""
    v, f = m.vertices, m.faces
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    mid = (a + b + c) / 3
    near = centres[np.argmin(np.linalg.norm(mid[:, None] - centres[None], axis=2), axis=1)]
    return bool(np.all(np.einsum("ij,ij->i", np.cross(b - a, c - a), mid - near) > 0))


def test_mirroring_node_transforms_keep_parts_outside_out(tmp_path):
    """Nested glTF nodes (a parent's translation, a child mirrored in x, another rotated) and a
    Collada <matrix> of determinant -1 place their parts where the transforms, composed here in
    numpy, put them; every part's triangles still face outwards (the seed cube's do)."""

    cube = np.array(CUBE_V, float)
    assert _outward(nbvkit.Mesh(cube, np.array(CUBE_F, np.int32)), np.array([[0.5] * 3]))
    doc = json.loads(gltf_file(CUBE_V, CUBE_F))
    doc["scenes"] = [{"nodes": [0]}]
    s = np.sqrt(0.5)  # a quarter turn about x: (x, y, z) -> (x, -z, y)
    doc["nodes"] = [
        {"translation": [5, 0, 0], "children": [1, 2]},
        {"mesh": 0, "scale": [-1, 1, 1]},
        {"mesh": 0, "rotation": [s, 0, 0, s], "translation": [0, 3, 0]},
    ]
    p = tmp_path / "mirrored.gltf"
    p.write_text(json.dumps(doc))
    mirrored = cube * [-1, 1, 1] + [5, 0, 0]
    turned = cube[:, [0, 2, 1]] * [1, -1, 1] + [5, 3, 0]
    m = nbvkit.load_mesh(p, up="z")
    assert m.num_triangles == 24
    np.testing.assert_allclose(m.bounds, [[4, 0, 0], [6, 3, 1]], atol=1e-6)
    centres = np.array([mirrored.mean(axis=0), turned.mean(axis=0)])
    for part in (mirrored, turned):  # every vertex of each placed cube is a vertex of the mesh
        assert np.min(np.linalg.norm(m.vertices[None] - part[:, None], axis=2), axis=1).max() < 1e-6
    assert _outward(m, centres)
    assert m.area == pytest.approx(12.0)

    # a mesh placed by more nodes than nbvkit takes from instancing: refused before placing
    n = 224  # a 224 x 224 grid: 99,458 triangles, placed 202 times (20.09 M)
    grid = np.stack(np.meshgrid(np.arange(n), np.arange(n), indexing="ij"), -1).reshape(-1, 2)
    q = np.arange(n * n).reshape(n, n)[:-1, :-1].ravel()
    tris = np.vstack([np.stack([q, q + n, q + 1], 1), np.stack([q + 1, q + n, q + n + 1], 1)])
    many = json.loads(gltf_file(np.hstack([grid, np.zeros((n * n, 1))]).astype(np.float32), tris))
    many["scenes"] = [{"nodes": list(range(202))}]
    many["nodes"] = [{"mesh": 0, "translation": [0, 0, k]} for k in range(202)]
    p.write_text(json.dumps(many))
    with pytest.raises(
        ValueError, match="nodes place 202 copies of its meshes, more than 20000000"
    ):
        nbvkit.load_mesh(p)

    dae = tmp_path / "mirrored.dae"
    matrix = "<matrix>-1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1</matrix>"
    dae.write_bytes(dae_file().replace(b'<node id="n">', f'<node id="n">{matrix}'.encode()))
    m = nbvkit.load_mesh(dae)
    np.testing.assert_allclose(m.bounds, [[-1, 0, 0], [0, 1, 1]], atol=1e-6)
    assert _outward(m, np.array([[-0.5, 0.5, 0.5]]))


# (.glb written by open3d 0.16 is rejected by assimp 5.2.5: "buffer view out of range")
@pytest.mark.parametrize("ext", [".stl", ".ply", ".obj", ".gltf", ".off"])
def test_formats_written_by_open3d(tmp_path, ext):
    o3d = pytest.importorskip("open3d")
    box = box_mesh((1, 2, 3), (2, 4, 7))
    om = o3d.geometry.TriangleMesh(  # a Mesh's arrays are read-only: open3d wants copies
        o3d.utility.Vector3dVector(np.array(box.vertices)),
        o3d.utility.Vector3iVector(np.array(box.faces)),
    )
    om.compute_vertex_normals()
    p = tmp_path / f"box{ext}"
    assert o3d.io.write_triangle_mesh(str(p), om)
    # open3d writes its coordinates as they are; a glTF is y-up by its specification, which
    # mesh.up=auto (the default) follows: the box as written needs up="z"
    m = nbvkit.load_mesh(p, up="z")
    assert m.num_triangles == 12
    assert m.area == pytest.approx(box.area, rel=1e-5)
    np.testing.assert_allclose(m.bounds, [[1, 2, 3], [2, 4, 7]], atol=1e-5)
    auto = [[1, -7, 2], [2, -3, 4]] if ext == ".gltf" else [[1, 2, 3], [2, 4, 7]]
    np.testing.assert_allclose(nbvkit.load_mesh(p).bounds, auto, atol=1e-5)


def _dae_up(verts, up_axis) -> bytes:
    """A Collada cube giving `up_axis` (None: no <up_axis>, which the specification reads Y_UP)."""
    text = dae_file(verts, CUBE_F).decode()
    tag = "" if up_axis is None else f"<up_axis>{up_axis}</up_axis>"
    return text.replace("<up_axis>Z_UP</up_axis>", tag).encode()


def _glb(verts) -> bytes:
    """The glTF of gltf_file as a binary GLB (JSON chunk, then its buffer as the BIN chunk)."""

    return _glb_of(json.loads(gltf_file(verts, CUBE_F)))


def _glb_of(doc: dict) -> bytes:
    """The glTF `doc` (gltf_file's, its buffer embedded) as a GLB: its buffer as the BIN chunk."""
    import base64
    import struct

    doc = json.loads(json.dumps(doc))
    buf = base64.b64decode(doc["buffers"][0].pop("uri").split(",", 1)[1])

    def chunk(data: bytes, kind: bytes, pad: bytes) -> bytes:
        data += pad * (-len(data) % 4)
        return struct.pack("<I", len(data)) + kind + data

    body = chunk(json.dumps(doc).encode(), b"JSON", b" ") + chunk(buf, b"BIN\0", b"\0")
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


def test_off_index_out_of_range_is_refused_naming_the_file(tmp_path):
    # assimp's OFF reader clamped index 9 to the last vertex and read -7 as 0: no error
    for bad in ("9", "-7"):
        p = tmp_path / "x.off"
        p.write_text(f"OFF\n3 1 0\n0 0 0\n1 0 1\n0 1 1\n3 0 1 {bad}\n")
        with pytest.raises(ValueError, match=f"x.off': line 6: face vertex index {bad} is out of"):
            nbvkit.load_mesh(p)


def test_a_gltf_assimp_reads_only_in_part_is_refused_naming_what_it_dropped(tmp_path):
    """assimp drops a glTF face that indexes past the vertices, and the rest of an index count
    that is no multiple of 3, with only a log line: the mesh flew with half its faces."""
    import json

    doc = json.loads(gltf_file(CUBE_V, CUBE_F))
    good = tmp_path / "cube.gltf"
    good.write_text(json.dumps(doc))
    assert nbvkit.load_mesh(good).num_triangles == len(CUBE_F)
    bad_index = [f if i != 3 else (0, 2, 9) for i, f in enumerate(CUBE_F)]  # 8 vertices
    oor = tmp_path / "oor.gltf"
    oor.write_bytes(gltf_file(CUBE_V, bad_index))
    with pytest.raises(ValueError, match=r"oor.gltf' is damaged: .*out-of-range indices"):
        nbvkit.load_mesh(oor)
    short = dict(doc)
    short["accessors"] = [dict(a) for a in doc["accessors"]]
    short["accessors"][1]["count"] -= 1  # 35 indices
    five = tmp_path / "short.gltf"
    five.write_text(json.dumps(short))
    with pytest.raises(ValueError, match=r"short.gltf' is damaged: .*vertices were dropped"):
        nbvkit.load_mesh(five)
    assert nbvkit.load_mesh(good).num_triangles == len(CUBE_F)  # the next read is not refused


def test_a_mesh_file_named_for_another_format_says_which_it_looks_like(tmp_path):
    """A PLY or a glTF named .obj read as OBJ found no faces: "contains no triangles", and no
    word of what the file is."""
    for body, name, words in (
        (cube_ply("ascii"), "a.obj", "looks like a PLY file: name it .ply"),
        (gltf_file(CUBE_V, CUBE_F), "b.obj", "looks like a glTF file: name it .gltf"),
    ):
        p = tmp_path / name
        p.write_bytes(body)
        with pytest.raises(ValueError, match=f"{name}' contains no triangles \\(it {words}"):
            nbvkit.load_mesh(p)
        right = p.with_suffix(words.rsplit(" ", 1)[1])
        p.rename(right)
        assert nbvkit.load_mesh(right).num_triangles == len(CUBE_F)


def test_an_auto_up_axis_is_the_one_the_files_format_defines(tmp_path):
    """mesh.up=auto (the default): a glTF (y-up by its specification) and a Collada file saying
    Y_UP, or nothing, are turned z-up; a Collada Z_UP file and formats that record no up axis
    (OBJ, STL, PLY) keep their coordinates; an explicit y or z wins. X_UP is named."""
    tall = [(x, 5.0 * y, z) for x, y, z in CUBE_V]  # 1 x 5 x 1: tall along +y (up when y-up)
    turned, kept = [[0, -1, 0], [1, 0, 5]], [[0, 0, 0], [1, 5, 1]]
    files = {
        "y.gltf": (gltf_file(tall, CUBE_F), "y"),
        "y_up.dae": (_dae_up(tall, "Y_UP"), "y"),
        "none.dae": (_dae_up(tall, None), "y"),
        "z_up.dae": (_dae_up(tall, "Z_UP"), "z"),
        "z.obj": (obj_file(tall, CUBE_F), "z"),
    }
    for name, (data, axis) in files.items():
        p = tmp_path / name
        p.write_bytes(data)
        assert nbvkit.file_up_axis(p) == axis, name
        np.testing.assert_allclose(
            nbvkit.load_mesh(p).bounds, turned if axis == "y" else kept, atol=1e-6, err_msg=name
        )
        for given, bounds in (("z", kept), ("y", turned)):
            np.testing.assert_allclose(nbvkit.load_mesh(p, up=given).bounds, bounds, atol=1e-6)
    # the root's <asset> alone: not a comment's, not a nested asset's; Collada as the loader
    # tells it (.xml, or <COLLADA in its head); a binary glTF (GLB)
    z_up = _dae_up(tall, "Z_UP")
    odd = {
        "commented.dae": z_up.replace(b"<asset>", b"<!-- <up_axis>Y_UP</up_axis> --><asset>", 1),
        "nested.dae": _dae_up(tall, None).replace(
            b"<mesh>", b"<asset><up_axis>X_UP</up_axis></asset><mesh>", 1
        ),
        "collada.xml": _dae_up(tall, None),
        "collada.model": _dae_up(tall, None),
        "binary.glb": _glb(tall),
        "gltf.json": gltf_file(tall, CUBE_F),  # a glTF by its content, as assimp reads it
    }
    for name, data in odd.items():
        (tmp_path / name).write_bytes(data)
    assert [nbvkit.file_up_axis(tmp_path / n) for n in odd] == ["z", "y", "y", "y", "y", "y"]
    np.testing.assert_allclose(nbvkit.load_mesh(tmp_path / "gltf.json").bounds, turned, atol=1e-6)
    np.testing.assert_allclose(nbvkit.load_mesh(tmp_path / "binary.glb").bounds, turned, atol=1e-6)
    x_up = tmp_path / "x_up.dae"
    x_up.write_bytes(_dae_up(tall, "X_UP"))
    with pytest.raises(ValueError, match=r"x_up.dae: its <up_axis> is X_UP.*set mesh.up"):
        nbvkit.load_mesh(x_up)
    assert nbvkit.load_mesh(x_up, up="z").num_triangles == 12
    with pytest.raises(ValueError, match="mesh up axis must be 'auto', 'y' or 'z', got 'x'"):
        nbvkit.load_mesh(x_up, up="x")


def test_up_axis_and_scale(tmp_path):
    p = tmp_path / "tri.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 3 0\nf 1 2 3\n")  # extends along +y (up in a y-up file)
    m = nbvkit.load_mesh(p, scale=2.0, up="y")
    np.testing.assert_allclose(m.bounds, [[0, 0, 0], [2, 0, 6]], atol=1e-12)
    m = nbvkit.load_mesh(p, up="z")
    np.testing.assert_allclose(m.bounds, [[0, 0, 0], [1, 3, 0]], atol=1e-12)
    # a scale that shrinks every triangle's area to nothing is named as the likely cause
    with pytest.raises(ValueError, match=r"no area .* at mesh scale 1e-300: is the scale right"):
        nbvkit.load_mesh(p, scale=1e-300)


def test_boat_is_y_up():
    p = shared_mesh("boat_yup.obj")
    m = nbvkit.load_mesh(p, up="y", scale=4.5)
    size = m.bounds[1] - m.bounds[0]
    # the file is 1.84 (x) x 1.99 (y, up) x 8.38 (z) m; z-up after conversion, scaled 4.5
    np.testing.assert_allclose(size, np.array([1.84, 8.38, 1.99]) * 4.5, rtol=0.01)


def test_from_arrays_and_open3d_round_trip():
    pytest.importorskip("open3d")
    box = box_mesh((0, 0, 0), (1, 2, 3))
    om = box.to_open3d()
    back = nbvkit.Mesh.from_open3d(om)
    np.testing.assert_array_equal(back.faces, box.faces)
    np.testing.assert_allclose(back.vertices, box.vertices)
    assert nbvkit.mesh_from_open3d(om).area == pytest.approx(22.0)


def test_sampling_is_seeded_uniform_and_on_surface():
    # Two triangles of area 1 and 3 (at z = 0 and z = 1): samples split 1:3.
    v = np.array([[0, 0, 0], [2, 0, 0], [0, 1, 0], [0, 0, 1], [3, 0, 1], [0, 2, 1]], float)
    f = np.array([[0, 1, 2], [3, 4, 5]], np.int32)
    m = nbvkit.Mesh(v, f)
    a = m.sample_surface(40000, seed=7)
    b = m.sample_surface(40000, seed=7)
    c = m.sample_surface(40000, seed=8)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    frac_top = np.mean(a[:, 2] > 0.5)
    assert frac_top == pytest.approx(0.75, abs=0.01)
    low = a[a[:, 2] < 0.5]
    assert np.all(low[:, 0] / 2 + low[:, 1] <= 1 + 1e-9) and np.all(low >= -1e-12)
    pts, faces = m.sample_surface(1000, seed=1, return_faces=True)
    assert faces.shape == (1000,) and set(np.unique(faces)) <= {0, 1}
    np.testing.assert_allclose(pts[faces == 1, 2], 1.0)


def test_missing_file_names_the_path(tmp_path):
    p = tmp_path / "nope.obj"
    with pytest.raises(FileNotFoundError) as e:
        nbvkit.load_mesh(p)
    assert str(p) in str(e.value)
    with pytest.raises(FileNotFoundError):
        nbvkit._core._load_mesh(str(p))  # the C++ path raises the same Python type


def test_unreadable_and_triangle_less_files(tmp_path):
    junk = tmp_path / "junk.stl"
    junk.write_bytes(b"\x00\x01garbage" * 3)
    with pytest.raises(ValueError, match="junk.stl"):
        nbvkit.load_mesh(junk)
    pts = tmp_path / "points.obj"
    pts.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(ValueError, match="points.obj"):
        nbvkit.load_mesh(pts)
    empty = tmp_path / "empty.obj"
    empty.write_text("")
    with pytest.raises(ValueError, match="empty.obj"):
        nbvkit.load_mesh(empty)
    with pytest.raises(ValueError, match="directory"):
        nbvkit.load_mesh(tmp_path)
    # lines only (assimp's own words were "No meshes remaining")
    doc = json.loads(gltf_file(CUBE_V, CUBE_F))
    doc["meshes"][0]["primitives"][0]["mode"] = 1  # LINES
    (tmp_path / "lines.gltf").write_text(json.dumps(doc))
    dae = dae_file().replace(b'<triangles count="12">', b'<lines count="18">')
    (tmp_path / "lines.dae").write_bytes(dae.replace(b"</triangles>", b"</lines>"))
    for name in ("lines.gltf", "lines.dae"):
        with pytest.raises(
            ValueError, match=f"{name}' contains no triangles .only points or lines"
        ):
            nbvkit.load_mesh(tmp_path / name)


def test_bad_arrays_and_arguments(tmp_path):
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    with pytest.raises(ValueError, match="NaN"):
        nbvkit.Mesh(np.where(v == 1, np.nan, v), [[0, 1, 2]])
    with pytest.raises(ValueError, match="out of range"):
        nbvkit.Mesh(v, [[0, 1, 3]])
    with pytest.raises(ValueError, match="out of range"):
        nbvkit.Mesh(v, [[0, -1, 2]])
    with pytest.raises(ValueError, match="no triangles"):
        nbvkit.Mesh(v, np.zeros((0, 3), np.int32))
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        nbvkit.Mesh(v[:, :2], [[0, 1, 2]])
    p = tmp_path / "t.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(ValueError, match="up axis"):
        nbvkit.load_mesh(p, up="x")
    for s in (0, -1, float("nan"), float("inf"), "2", True):  # (a string's '2' was read as 2)
        with pytest.raises(ValueError, match="scale"):
            nbvkit.load_mesh(p, scale=s)
    with pytest.raises(ValueError, match=">= 0"):
        nbvkit.Mesh(v, [[0, 1, 2]]).sample_surface(-1)


def test_default_airliner_matches_spec():
    m = nbvkit.load_mesh(nbvkit.default_mesh_path())
    lo, hi = m.bounds
    size = hi - lo
    assert 33 <= size[0] <= 37 and 28 <= size[1] <= 32 and 7 <= size[2] <= 8
    assert 0 < lo[2] < 0.1  # lowest point just above the ground
    assert 10_000 <= m.num_triangles <= 200_000
    # mirror-symmetric about its fuselage plane y = 0: every mirrored vertex is a vertex
    from scipy.spatial import cKDTree

    v = m.vertices
    d, _ = cKDTree(v).query(v * np.array([1, -1, 1]))
    assert d.max() < 1e-5


# ------------------------------------------------------------ georeferenced coordinates (float64)

UTM = np.array([500_000.3, 5_000_000.3, 100.7])  # an offset float32 cannot hold (0.5 m spacing)
TRI = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)  # one triangle, TRI_F
TRI_F = [(0, 1, 2)]


def test_georeferenced_obj_keeps_its_digits_and_shifts_exactly(tmp_path):
    local = np.array([[0, 0, 0], [1.25, 0, 0], [0, 2.5, 0], [0.001, 0.002, 3.0]])
    p = tmp_path / "utm.obj"
    p.write_bytes(obj_file(local + UTM, [(0, 1, 2), (0, 1, 3)]))
    raw = nbvkit.load_mesh(p)
    # the file's digits, not float32's (5,000,000.3 had come out 5,000,000.5)
    np.testing.assert_array_equal(np.sort(raw.vertices[:, 1]), np.sort((local + UTM)[:, 1]))
    m = nbvkit.load_mesh(p, shift=-UTM)
    np.testing.assert_allclose(m.vertices, local, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(m.faces, [[0, 1, 2], [0, 1, 3]])
    # scale and up apply to the double coordinates too
    m = nbvkit.load_mesh(p, scale=1000.0, up="y", shift=-1000.0 * UTM[[0, 2, 1]] * [1, -1, 1])
    np.testing.assert_allclose(m.vertices, 1000.0 * local[:, [0, 2, 1]] * [1, -1, 1], atol=1e-6)


def test_a_shift_too_far_for_float64_is_refused_by_its_precision(tmp_path):
    """A shift of 1e17 m rounds every coordinate by metres (the mesh collapsed, and the error
    came later as workspace bounds beyond the map): refused naming the shift and the rounding;
    a shift to a far but exact place is kept to the micrometre."""
    p = tmp_path / "tri.obj"
    p.write_bytes(obj_file(0.3 * TRI, TRI_F))
    with pytest.raises(ValueError, match=r"mesh shift \[1e\+17, 0.0, 0.0\].*rounds .* by up to"):
        nbvkit.load_mesh(p, shift=[1e17, 0, 0])
    with pytest.raises(ValueError, match="nearer the origin"):
        nbvkit.load_mesh(p, shift=[-3e14, 0, 0])  # float64 spacing there: 6 cm
    m = nbvkit.load_mesh(p, shift=UTM)
    np.testing.assert_allclose(m.vertices - UTM, 0.3 * TRI, rtol=0, atol=1e-6)
    for kwargs in ({"scale": 1e30}, {"shift": [0, 2e9, 0]}):  # exact, but beyond the core's
        with pytest.raises(ValueError, match=r"mesh coordinates reach .* beyond 1e\+09 m"):
            nbvkit.load_mesh(p, **kwargs)


# The parser's cases (statements, index forms, polygons, every bad line) are GoogleTests
# (cpp/tests/test_obj.cpp); here: what a user reads, the file named.
@pytest.mark.parametrize(
    "text, needle",
    [
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n",
            "cannot read OBJ '{}': line 4: face vertex index 4 is out of range",
        ),
        (
            # named by its number in the file (OBJ counts from 1; the unused first is dropped)
            "v 9 9 9\nv 0 0 0\nv nan 0 0\nv 0 1 0\nf 2 3 4\n",
            "mesh file '{}': 1 vertices of its faces have a NaN or infinite coordinate "
            "(vertex 3 is (nan, 0, 0))",
        ),
    ],
)
def test_obj_errors_name_the_file_and_the_problem(tmp_path, text, needle):
    p = tmp_path / "bad.obj"
    p.write_text(text)
    with pytest.raises(ValueError) as e:
        nbvkit.load_mesh(p)
    assert needle.format(p) in str(e.value)


def test_obj_unused_nan_vertex_is_ignored(tmp_path):
    p = tmp_path / "t.obj"
    p.write_text("v nan 0 0\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 2 3 4\n")
    assert nbvkit.load_mesh(p).vertices.shape == (3, 3)


def _gltf_triangle(tmp_path, offset, uri=None):
    """A one-triangle glTF (tri.gltf) whose positions (float32) lie at `offset`; its buffer in
    `uri` (a file beside it) or embedded."""
    p = tmp_path / "tri.gltf"
    p.write_bytes(gltf_file(TRI.astype(np.float32) + np.float32(offset), TRI_F, uri=uri))
    return p


def _binary_stl(path, offset):
    path.write_bytes(stl_binary_file(TRI.astype(np.float32) + np.float32(offset), TRI_F))


def test_float32_formats_at_georeferenced_coordinates_are_refused(tmp_path):
    """DAE, STL and glTF arrive in float32 (assimp's ai_real); at 5,000,000 m float32 numbers are
    0.5 m apart. Refused, saying why and what to do, rather than loaded 0.25 m off."""
    dae = tmp_path / "utm.dae"
    dae.write_bytes(dae_file(TRI + UTM, TRI_F))
    with pytest.raises(ValueError) as e:
        nbvkit.load_mesh(dae, shift=-UTM)
    msg = str(e.value)
    for needle in (
        "utm.dae",
        "reach 5000001.5",
        "0.5 m apart",
        "0.25 m",
        "float32",
        "mesh.shift",
        "PLY or OBJ",
    ):
        assert needle in msg, (needle, msg)
    stl = tmp_path / "utm.stl"
    _binary_stl(stl, UTM)
    with pytest.raises(ValueError, match="binary STL stores float32.*already lost"):
        nbvkit.load_mesh(stl)
    gltf = _gltf_triangle(tmp_path, UTM)
    with pytest.raises(ValueError, match="tri.gltf.*glTF stores positions in float32"):
        nbvkit.load_mesh(gltf)
    # the threshold is the rounding in metres: coordinates from 32768 m (2^15) at scale 1 (the
    # triangle reaches x + 1); 5,000,000 mm (5 km) at scale 0.001 is fine
    for x, ok in ((32766.0, True), (32767.0, False)):
        _binary_stl(stl, (x, 0, 0))
        if ok:
            assert nbvkit.load_mesh(stl).bounds[1][0] == x + 1
        else:
            with pytest.raises(ValueError, match="0.00195"):
                nbvkit.load_mesh(stl)
    _binary_stl(stl, (5e6, 0, 0))
    assert nbvkit.load_mesh(stl, scale=0.001).bounds[0][0] == pytest.approx(5000.0)
    # near the origin these formats load as before
    dae.write_bytes(dae_file(TRI + (1000.0, 2000.0, 3.0), TRI_F))
    np.testing.assert_allclose(nbvkit.load_mesh(dae).bounds[0], [1000, 2000, 3], atol=1e-4)


# ------------------------------------------------------------ files a mesh file refers to

_LOAD = """
import sys, nbvkit
try:
    nbvkit.load_mesh(sys.argv[1])
    print("LOADED")
except ValueError as e:
    print("VALUEERROR", e)
"""


def _load_in_subprocess(path, timeout=60):
    """load_mesh(path) in a child process: a hang fails the test instead of the suite."""
    import subprocess
    import sys

    try:
        r = subprocess.run(
            [sys.executable, "-c", _LOAD, str(path)],
            capture_output=True,
            text=True,
            timeout=timeout,
        )
    except subprocess.TimeoutExpired:
        pytest.fail(f"load_mesh({path}) hung for {timeout} s")
    assert r.returncode == 0, r.stderr
    return r.stdout.strip()


@pytest.mark.parametrize("kind", ["fifo", "dev_zero", "directory"])
def test_referenced_files_that_are_not_regular_are_refused_without_hanging(tmp_path, kind):
    import os

    target = tmp_path / "ref.bin"
    if kind == "fifo":
        os.mkfifo(target)
    elif kind == "dev_zero":
        target.symlink_to("/dev/zero")
    else:
        target.mkdir()
    # a glTF whose buffer is that file: refused naming it
    gltf = _gltf_triangle(tmp_path, (0, 0, 0), uri="ref.bin")
    out = _load_in_subprocess(gltf)
    why = {"fifo": "a FIFO", "dev_zero": "a character device", "directory": "a directory"}[kind]
    assert out.startswith("VALUEERROR") and "tri.gltf" in out and "ref.bin" in out, out
    assert why in out, out
    # an OBJ whose material library is that file: read without opening it (geometry only)
    obj = tmp_path / "tri.obj"
    obj.write_text("mtllib ref.bin\nusemtl m\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    assert _load_in_subprocess(obj) == "LOADED"


def test_gltf_with_a_regular_buffer_file_loads(tmp_path):
    gltf = _gltf_triangle(tmp_path, (0, 0, 0), uri="ref.bin")
    (tmp_path / "ref.bin").write_bytes(gltf_buffer(TRI.astype(np.float32), TRI_F))
    assert nbvkit.load_mesh(gltf).num_triangles == 1


def test_a_gltf_requiring_an_extension_its_reader_lacks_is_refused(tmp_path):
    """glTF's rule: a loader refuses a file whose required extensions it cannot read. assimp 5.2
    read KHR_mesh_quantization's integer positions as floats (a 10 m box came out 1e-26 m across,
    without a word); extensions of the look alone (materials, textures, lights) are no matter."""

    cases = {"KHR_mesh_quantization": False, "EXT_meshopt_compression": False,
             "KHR_materials_unlit": True, "KHR_texture_transform": True,
             "KHR_draco_mesh_compression": True}  # fmt: skip
    for required, ok in cases.items():
        doc = json.loads(gltf_file(CUBE_V, CUBE_F))
        doc["extensionsUsed"] = doc["extensionsRequired"] = [required]
        # an extras block's key of the same name is no requirement, nor does it hide the real one
        doc["extras"] = {"extensionsRequired": ["MY_APP_thing"]}
        doc = {"extras": doc.pop("extras"), **doc}
        text = json.dumps(doc).encode()
        for name, data in (("q.gltf", text), ("q.glb", _glb_of(doc)), ("q.json", text)):
            p = tmp_path / name
            p.write_bytes(data)
            if ok:
                assert nbvkit.load_mesh(p).num_triangles == 12
            else:
                with pytest.raises(
                    ValueError, match=f"{name}.*requires the glTF extension {required}"
                ):
                    nbvkit.load_mesh(p)


def test_zipped_collada_is_refused_and_unused_non_finite_ply_vertices_are_dropped(tmp_path):
    """A zip went past the Collada guard into assimp (a missing count crashed the process); a
    PLY's unused NaN vertex (as PCL's organized meshes write) was refused, where OBJ drops it."""
    import zipfile

    zae = tmp_path / "m.zae"
    with zipfile.ZipFile(zae, "w") as z:
        z.writestr("m.dae", dae_file(CUBE_V, CUBE_F))
    for name in ("m.zae", "m.bin"):  # a zip, whatever its name
        p = tmp_path / name
        p.write_bytes(zae.read_bytes())
        with pytest.raises(ValueError, match=rf"{name}.*a zip archive .*unzip it"):
            nbvkit.load_mesh(p)
    verts = [(float("nan"),) * 3, *CUBE_V]
    faces = [(a + 1, b + 1, c + 1) for a, b, c in CUBE_F]
    head = ("ply\nformat ascii 1.0\nelement vertex 9\nproperty float x\nproperty float y\n"
            "property float z\nelement face 12\nproperty list uchar int vertex_indices\n"
            "end_header\n")  # fmt: skip
    body = "".join(f"{x} {y} {z}\n" for x, y, z in verts)
    p = tmp_path / "organized.ply"
    p.write_text(head + body + "".join(f"3 {a} {b} {c}\n" for a, b, c in faces))
    m = nbvkit.load_mesh(p)
    assert m.vertices.shape == (8, 3) and np.isfinite(m.vertices).all()
    np.testing.assert_allclose(m.bounds, [[0, 0, 0], [1, 1, 1]])
    used = tmp_path / "used.ply"
    used.write_text(
        head + body + "3 0 1 2\n" + "".join(f"3 {a} {b} {c}\n" for a, b, c in faces[1:])
    )
    with pytest.raises(ValueError, match="NaN or infinite"):
        nbvkit.load_mesh(used)


# ------------------------------------------------------------ STL (nbvkit's own reader)
# The parser's cases are GoogleTests (cpp/tests/test_stl.cpp); here: files as exporters write
# them, through load_mesh, with the file named in every refusal.


def _ascii_stl(facets, case=str.lower, eol="\n", lead="") -> bytes:
    """An ASCII STL of `facets` (lists of vertices), keywords in `case`."""
    k = case
    s = lead + k("solid") + " part" + eol
    for f in facets:
        s += f" {k('facet normal')} 0 0 0{eol}  {k('outer loop')}{eol}"
        s += "".join(f"   {k('vertex')} {x!r} {y!r} {z!r}{eol}" for x, y, z in f)
        s += f"  {k('endloop')}{eol} {k('endfacet')}{eol}"
    return (s + k("endsolid") + " part" + eol).encode()


def test_stl_files_as_exporters_write_them(tmp_path):
    cube = [[CUBE_V[i] for i in f] for f in CUBE_F]
    p = tmp_path / "cube.stl"
    for case, eol, lead in (
        (str.lower, "\n", ""),
        (str.upper, "\r\n", ""),  # upper case (older CAD exporters), Windows line ends
        (str.lower, "\r", "\n\n"),  # blank lines first, old Mac line ends
        (str.lower, "\n", "\ufeff"),  # a UTF-8 byte order mark
    ):
        p.write_bytes(_ascii_stl(cube, case, eol, lead))
        m = nbvkit.load_mesh(p)
        assert (m.num_triangles, m.vertices.shape[0]) == (12, 8), (case, eol, lead)
        assert m.area == pytest.approx(6.0) and _outward(m, np.array([[0.5] * 3]))
    # a binary file whose 80-byte header begins with "solid", as many exporters write it, or
    # "glTF" (an STL whatever its header holds: z up, not turned as a glTF)
    for magic in (b"solid ", b"glTF"):
        p.write_bytes(magic + stl_binary_file(CUBE_V, CUBE_F)[len(magic) :])
        m = nbvkit.load_mesh(p)
        assert m.num_triangles == 12 and m.area == pytest.approx(6.0)
        assert _outward(m, np.array([[0.5] * 3]))
        np.testing.assert_array_equal(m.bounds, [[0, 0, 0], [1, 1, 1]])
    # a facet of four vertices, an L-shaped six: cut keeping their area (the fourth was dropped)
    dart = [(0.0, 0.0, 0.0), (2.0, 1.0, 0.0), (0.0, 2.0, 0.0), (1.0, 1.0, 0.0)]  # area 1
    ell = [(0.0, 0.0, 1.0), (3.0, 0.0, 1.0), (3.0, 1.0, 1.0), (1.0, 1.0, 1.0), (1.0, 3.0, 1.0)]
    ell.append((0.0, 3.0, 1.0))  # area 5
    p.write_bytes(_ascii_stl([dart, ell]))
    m = nbvkit.load_mesh(p)
    assert m.num_triangles == 2 + 4 and m.area == pytest.approx(6.0)
    assert np.all(np.cross(*np.diff(m.vertices[m.faces], axis=1).transpose(1, 0, 2))[:, 2] > 0)


def test_ascii_stl_keeps_its_digits_and_binary_stl_counts_are_checked(tmp_path):
    p = tmp_path / "utm.stl"
    p.write_bytes(_ascii_stl([list(map(tuple, TRI + UTM))]))
    np.testing.assert_array_equal(nbvkit.load_mesh(p).vertices[:, 1], (TRI + UTM)[:, 1])
    np.testing.assert_allclose(nbvkit.load_mesh(p, shift=-UTM).vertices, TRI, rtol=0, atol=1e-9)
    good = stl_binary_file(CUBE_V, CUBE_F)
    for name, data, needle in (
        ("short.stl", good[:-50], "truncated"),
        ("long.stl", good + b"\0" * 50, "more bytes"),
        ("junk.stl", good[:84] + b"x" * 7, "12 facets"),
    ):
        (tmp_path / name).write_bytes(data)
        with pytest.raises(ValueError, match=f"{name}.*{needle}|{needle}.*{name}"):
            nbvkit.load_mesh(tmp_path / name)
