"""PointCloud (incremental voxel-grid filter, ground removal, crop) and PLY / PCD / NPY files."""
from __future__ import annotations

import os
import struct

import numpy as np
import pytest

import nbvkit
from nbvkit import PointCloud, read_points, write_points
from nbvkit.cloud import DEFAULT_MIN_Z, DEFAULT_VOXEL_SIZE, LASER_VOXEL_SIZE, NESTED_VOXEL_SIZE

NO_GROUND = float("-inf")  # min_z that disables ground removal


def voxel_reference(points, size, min_z=-np.inf):
    """What the filter must give: per voxel floor(p / size), the mean of its points, voxels in
    order of first appearance (plain numpy)."""
    p = np.asarray(points, float)
    p = p[p[:, 2] >= min_z]
    keys = np.floor(p / size).astype(np.int64)
    _, first, inv = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    inv = inv.ravel()
    sums = np.zeros((len(first), 3))
    np.add.at(sums, inv, p)
    counts = np.bincount(inv, minlength=len(first))
    order = np.argsort(first)
    return (sums / counts[:, None])[order], counts[order]


# ------------------------------------------------------------------------------ voxel filter


def test_defaults_are_the_authors():
    assert DEFAULT_VOXEL_SIZE == 0.02 and LASER_VOXEL_SIZE == 0.1 and DEFAULT_MIN_Z == 0.3
    c = PointCloud()
    assert c.voxel_size == 0.02 and c.min_z == 0.3 and not c.options.crop and len(c) == 0
    assert c.options == nbvkit.SurfaceCloudOptions()
    assert c.points.shape == (0, 3) and c.points.dtype == np.float64


def test_config_defaults_match_the_core():
    config = pytest.importorskip("nbvkit.config")
    if not hasattr(config, "CloudConfig"):
        pytest.skip("no CloudConfig in nbvkit.config")
    cc = config.CloudConfig()
    # the missions drop nothing as ground (their world has none); the paper's scenarios drop
    # what the authors did, the core's default
    assert (cc.camera_voxel, cc.laser_voxel, cc.min_z) == (
        NESTED_VOXEL_SIZE,
        LASER_VOXEL_SIZE,
        None,
    )
    assert config.load_config(overrides=["scenario=5"]).cloud.min_z == DEFAULT_MIN_Z == 0.3


@pytest.mark.parametrize("single", [False, True])
def test_the_missions_voxel_keeps_a_point_in_every_coverage_cell_a_hit_fell_in(single):
    # a tilted plane sampled densely: its raw hits fall in a set of 0.05 m cells; the cloud's
    # centroids at NESTED_VOXEL_SIZE fall in exactly those cells at every paper resolution
    # (coverage counts a cell with a point), while the authors' 0.02 m voxel, which straddles
    # 0.05 m cells, moves some centroids into a neighbouring cell: cells the camera hit are empty
    from nbvkit import Evaluator

    rng = np.random.default_rng(3)
    uv = rng.uniform(0, 4, size=(400_000, 2))
    raw = np.c_[uv[:, 0], uv[:, 1], 0.37 * uv[:, 0] + 0.21 * uv[:, 1] + 1.003] + [-3.1, 7.7, 0]
    ev = Evaluator(raw, resolutions=(0.05, 0.1, 0.5))  # the hits themselves are the truth

    def cells(points, r):
        return {tuple(k) for k in np.floor(points / r).astype(np.int64)}

    nested = PointCloud(raw, voxel_size=NESTED_VOXEL_SIZE, min_z=NO_GROUND, single_precision=single)
    for r in (0.05, 0.1, 0.5):
        assert cells(nested.points, r) == cells(raw, r), r
    authors = PointCloud(raw, voxel_size=DEFAULT_VOXEL_SIZE, min_z=NO_GROUND)
    assert cells(authors.points, 0.05) != cells(raw, 0.05)
    nested, authors = ev.evaluate(nested.points), ev.evaluate(authors.points)
    assert nested["coverage"] == {"0.05": 1.0, "0.1": 1.0, "0.5": 1.0}
    assert authors["coverage"]["0.05"] < 0.995


def test_one_point_per_voxel_at_the_centroid():
    c = PointCloud(voxel_size=0.1, min_z=NO_GROUND)
    pts = np.array(
        [
            [0.01, 0.02, 0.51],
            [0.09, 0.08, 0.59],  # voxel (0, 0, 5)
            [0.15, 0.02, 0.55],  # voxel (1, 0, 5)
            [0.05, 0.05, 0.55],
        ]
    )  # voxel (0, 0, 5) again
    assert c.add(pts) == 2
    np.testing.assert_allclose(c.points, [[0.05, 0.05, 0.55], [0.15, 0.02, 0.55]], atol=1e-15)
    np.testing.assert_array_equal(c.counts, [3, 1])
    assert len(c) == 2 and c.num_registered == 4


def test_floor_not_truncation_for_negative_coordinates():
    c = PointCloud(voxel_size=0.02, min_z=NO_GROUND)
    # -0.01 and +0.01 are in voxels -1 and 0; truncation toward zero would merge them.
    assert c.add([[-0.01, 0.5, 1.0], [0.01, 0.5, 1.0]]) == 2
    assert c.add([[-0.019, -0.001, -0.001]]) == 1  # voxel (-1, -1, -1)
    np.testing.assert_allclose(c.points[:, 0], [-0.01, 0.01, -0.019])


def test_incremental_equals_batch_and_numpy_reference():
    rng = np.random.default_rng(3)
    pts = rng.uniform(-1, 1, size=(20000, 3)) * [2, 2, 1] + [0, 0, 1]
    batch = PointCloud(pts, voxel_size=0.05, min_z=0.3)
    inc = PointCloud(voxel_size=0.05, min_z=0.3)
    created = sum(inc.add(chunk) for chunk in np.array_split(pts, 7))
    assert created == len(inc) == len(batch)
    np.testing.assert_array_equal(inc.points, batch.points)
    ref, counts = voxel_reference(pts, 0.05, min_z=0.3)
    np.testing.assert_allclose(batch.points, ref, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(batch.counts, counts)
    # every centroid lies inside its voxel
    keys = np.floor(batch.points / 0.05)
    assert len(np.unique(keys, axis=0)) == len(batch)


def test_voxelgrid_sampling_gives_the_cloud_filter_centroids_and_rejects_bad_input():
    rng = np.random.default_rng(4)
    pts = rng.uniform(-3, 3, size=(5000, 3))
    ref, _ = voxel_reference(pts, 0.4, min_z=-np.inf)
    np.testing.assert_allclose(nbvkit._core.voxelgrid_sampling(pts, 0.4), ref, rtol=0, atol=1e-12)
    for bad in (0.0, -1.0, float("nan"), 1e-300, 1e308):  # a unit's mistake: not one voxel key
        with pytest.raises(ValueError, match=r"voxel size must be within \[1e-06, 1000\] m"):
            nbvkit._core.voxelgrid_sampling(pts, bad)
        with pytest.raises(ValueError, match=r"voxel_size must be within \[1e-06, 1000\] m"):
            PointCloud(voxel_size=bad)  # (its first add blamed the points)
    with pytest.raises(ValueError, match="points"):
        nbvkit._core.voxelgrid_sampling(np.array([[0.0, np.nan, 0.0]]), 0.1)


def test_single_precision_sums_give_the_same_voxels_within_a_bound_of_the_exact_centroids():
    # sums of the offsets from each voxel's corner in single precision: the same voxels in the
    # same order, each centroid within 1e-7 of the voxel size here (a few points a voxel), inside
    # its voxel, in 12 bytes a voxel less
    rng = np.random.default_rng(5)
    pts = rng.uniform(-40, 40, size=(60000, 3)) + [1000.0, -2000.0, 300.0]
    exact = PointCloud(pts, voxel_size=0.5, min_z=float("-inf"))
    single = PointCloud(pts, voxel_size=0.5, min_z=float("-inf"), single_precision=True)
    assert single.options.single_precision and not exact.options.single_precision
    np.testing.assert_array_equal(single.counts, exact.counts)
    err = np.abs(single.points - exact.points).max()
    assert 0 < err < 1e-7 * 0.5
    np.testing.assert_array_equal(np.floor(single.points / 0.5), np.floor(exact.points / 0.5))
    assert exact.bytes - single.bytes >= 12 * len(exact)


def test_readding_creates_nothing():
    rng = np.random.default_rng(0)
    pts = rng.uniform(0.5, 2, size=(500, 3))
    c = PointCloud(pts, voxel_size=0.1)
    before = c.points
    assert c.add(pts) == 0
    np.testing.assert_allclose(c.points, before, atol=1e-12)  # same centroids (each voxel x2)
    assert c.num_registered == 1000


def test_ground_removal():
    pts = [[0, 0, 0.0], [0, 0, 0.29], [1, 0, 0.3], [2, 0, 5.0]]
    c = PointCloud(pts)  # default min_z 0.3: z < 0.3 dropped, z == 0.3 kept
    np.testing.assert_allclose(c.points[:, 2], [0.3, 5.0])
    assert PointCloud(pts, min_z=NO_GROUND).min_z == NO_GROUND
    assert len(PointCloud(pts, min_z=NO_GROUND)) == 4
    assert len(PointCloud(pts, min_z=None)) == 2  # a keyword set to None keeps the default
    assert len(PointCloud(pts, min_z=1.0)) == 1


def test_crop_box():
    pts = [[0, 0, 1], [5, 0, 1], [0, 5, 1], [0, 0, 9]]
    c = PointCloud(pts, crop=True, crop_min=[-1, -1, 0], crop_max=[1, 1, 2])
    np.testing.assert_allclose(c.points, [[0, 0, 1]])
    assert c.options.crop
    np.testing.assert_allclose([c.options.crop_min, c.options.crop_max], [[-1, -1, 0], [1, 1, 2]])
    with pytest.raises(ValueError, match="crop_min"):
        PointCloud(crop=True, crop_min=[1, 2])
    with pytest.raises(ValueError, match="max must be >= min"):
        PointCloud(crop=True, crop_min=[1, 1, 1], crop_max=[0, 0, 0])


def test_options_object_with_keyword_overrides():
    opts = nbvkit.SurfaceCloudOptions(voxel_size=0.1, min_z=NO_GROUND)
    c = PointCloud([[0, 0, 0.05]], opts, voxel_size=0.5)
    assert c.voxel_size == 0.5 and c.min_z == NO_GROUND and len(c) == 1
    assert c.options == opts.copy(voxel_size=0.5)
    assert PointCloud(options={"voxel_size": 0.2}).voxel_size == 0.2
    assert opts.voxel_size == 0.1  # the options passed in are not changed
    c.options.voxel_size = 1.0  # a copy: the cloud keeps its own
    assert c.voxel_size == 0.5
    with pytest.raises(ValueError, match="unknown SurfaceCloudOptions option 'bounds'"):
        PointCloud(bounds=[[0, 0, 0], [1, 1, 1]])


def test_clear_keeps_options():
    c = PointCloud([[0, 0, 1.0]], voxel_size=0.5)
    c.clear()
    assert len(c) == 0 and c.points.shape == (0, 3) and c.voxel_size == 0.5
    assert c.add([[0, 0, 1.0]]) == 1


def test_add_scan_and_cloud(wall):
    cam = nbvkit.DepthCamera(nbvkit.RaycastScene(wall), width=64, height=48)
    scan = cam.scan(np.eye(4))
    c = PointCloud(voxel_size=0.05, min_z=NO_GROUND)
    assert c.add(scan) > 0
    ref, _ = voxel_reference(scan.hits, 0.05)
    np.testing.assert_allclose(c.points, ref, atol=1e-12)
    assert np.allclose(c.points[:, 0], 5.0)
    c2 = PointCloud(c, voxel_size=0.05, min_z=NO_GROUND)
    np.testing.assert_allclose(c2.points, c.points, atol=1e-12)
    np.testing.assert_array_equal(np.asarray(c), c.points)


def test_bad_input_raises_and_registers_nothing():
    c = PointCloud([[0, 0, 1.0]])
    for bad in ([[np.nan, 0, 1]], [[0, np.inf, 1]], [[0, 0, 1], [0, 0, -np.inf]]):
        with pytest.raises(ValueError, match="NaN or infinite"):
            c.add(bad)
    assert len(c) == 1 and c.num_registered == 1
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        c.add(np.zeros((4, 2)))
    for size in (0, -0.1, float("nan"), float("inf"), "big"):
        with pytest.raises(ValueError, match="voxel_size"):
            PointCloud(voxel_size=size)
    with pytest.raises(ValueError, match="min_z"):
        PointCloud(min_z=float("nan"))
    with pytest.raises(ValueError, match="too far from the origin"):
        PointCloud([[1e9, 0, 1]], voxel_size=0.02)
    assert c.add(np.zeros((0, 3))) == 0


def test_save_and_load_round_trip(tmp_path):
    rng = np.random.default_rng(1)
    c = PointCloud(rng.uniform(0, 3, size=(5000, 3)), voxel_size=0.1)
    for name in ("c.ply", "c.pcd", "c.npy"):
        c.save(tmp_path / name)
        back = PointCloud.load(tmp_path / name, voxel_size=0.1)
        # centroids lie inside their voxels, so re-filtering keeps them (float32 PCD: close)
        np.testing.assert_allclose(back.points, c.points, atol=1e-5 if name.endswith("pcd") else 0)
    np.testing.assert_array_equal(c.to_numpy(), c.points)
    assert "PointCloud" in repr(c)


def test_open3d_conversion():
    o3d = pytest.importorskip("open3d")
    c = PointCloud([[0, 0, 1.0], [1, 2, 3.0]], min_z=NO_GROUND)
    pc = c.to_open3d()
    assert isinstance(pc, o3d.geometry.PointCloud)
    np.testing.assert_allclose(np.asarray(pc.points), c.points)
    back = PointCloud.from_open3d(pc, min_z=NO_GROUND)
    np.testing.assert_allclose(back.points, c.points)
    np.testing.assert_allclose(PointCloud.from_numpy(c.points, min_z=NO_GROUND).points, c.points)


# ------------------------------------------------------------------------------ files


def sample_points(n=1000, seed=0):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(n, 3)) * [10, 5, 2] + [1e3, -2e3, 0.5]  # far from the origin too


@pytest.mark.parametrize(
    "name,kw,exact",
    [
        ("a.ply", {}, True),
        ("a.ply", {"ascii": True}, True),
        ("a.pcd", {}, False),
        ("a.pcd", {"ascii": True}, False),
        ("a.pcd", {"dtype": np.float64}, True),
        ("a.pcd", {"dtype": np.float64, "ascii": True}, True),
        ("a.ply", {"dtype": np.float32}, False),
        ("a.npy", {}, True),
        ("A.PLY", {}, True),
        ("a.NPY", {}, True),
    ],
)
def test_round_trip(tmp_path, name, kw, exact):
    pts = sample_points()
    write_points(tmp_path / name, pts, **kw)
    back = read_points(tmp_path / name)
    assert back.shape == pts.shape and back.dtype == np.float64
    if exact:
        np.testing.assert_array_equal(back, pts)
    else:  # float32: ~1e-4 m at 2 km from the origin
        np.testing.assert_allclose(back, pts, rtol=1e-7, atol=0)
    assert [p.name for p in tmp_path.iterdir()] == [name]


def test_a_path_as_bytes_is_written_and_read_as_load_mesh_takes_it(tmp_path):
    """Paths as bytes (os.fsencode's, not UTF-8 too) are taken by load_mesh and read_points;
    write_points had refused them with a TypeError."""
    pts = sample_points()
    path = os.fsencode(tmp_path / "z.ply")
    write_points(path, pts)
    np.testing.assert_array_equal(read_points(path), pts)


@pytest.mark.parametrize("name", ["e.ply", "e.pcd", "e.npy"])
@pytest.mark.parametrize("ascii", [False, True])
def test_empty_files(tmp_path, name, ascii):
    write_points(tmp_path / name, np.zeros((0, 3)), ascii=ascii)
    back = read_points(tmp_path / name)
    assert back.shape == (0, 3) and back.dtype == np.float64


@pytest.mark.parametrize("name", ["s.ply", "s.pcd", "s.npy"])
@pytest.mark.parametrize("ascii", [False, True])
def test_a_list_of_clouds_is_written_a_part_at_a_time_as_its_stacked_points(
    tmp_path, monkeypatch, name, ascii
):
    import nbvkit.cloud

    monkeypatch.setattr(nbvkit.cloud, "_WRITE_PART", 7)  # parts across the clouds' boundary
    camera = PointCloud(sample_points(40), voxel_size=0.02, min_z=NO_GROUND)
    laser = PointCloud(sample_points(25, seed=1) + 3.0, voxel_size=0.1, min_z=NO_GROUND)
    stacked = np.vstack([camera.points, laser.points])
    write_points(tmp_path / name, [camera, laser], ascii=ascii, dtype=np.float64)
    write_points(tmp_path / ("ref" + name[1:]), stacked, ascii=ascii, dtype=np.float64)
    assert (tmp_path / name).read_bytes() == (tmp_path / ("ref" + name[1:])).read_bytes()
    np.testing.assert_array_equal(read_points(tmp_path / name), stacked)
    # numpy's own reader for .npy
    if name.endswith(".npy"):
        np.testing.assert_array_equal(np.load(tmp_path / name), stacked)
    assert np.array_equal(
        nbvkit._core.stack_points([camera, laser], 30, 50), stacked[30:50]
    ) and nbvkit._core.stack_points([camera, laser], 60, 1000).shape == (len(stacked) - 60, 3)
    with pytest.raises(ValueError, match="start and stop"):
        nbvkit._core.stack_points([camera], -1)


def test_points_float32_would_round_are_not_written_as_float32(tmp_path):
    """A .pcd (float32 by default) of a georeferenced cloud (5,000,000 m: float32 rounded it by
    0.2 m, silently) or of a coordinate float32 cannot hold (it wrote inf) is written as F 8 with
    a warning, read back exactly (an independent reader: the header's SIZE/TYPE); an explicit
    dtype=float32 is refused, nothing written."""
    for pts in (np.array([[5_000_000.3, 4_000_000.7, 300.11], [1, 2, 3]]),
                np.array([[1e300, 0, 0], [1, 2, 3]])):  # fmt: skip
        with pytest.warns(RuntimeWarning, match="written as F 8"):
            write_points(tmp_path / "far.pcd", pts)
        head = (tmp_path / "far.pcd").read_bytes().split(b"DATA")[0].decode()
        assert "SIZE 8 8 8" in head and "TYPE F F F" in head
        np.testing.assert_array_equal(read_points(tmp_path / "far.pcd"), pts)
        for name in ("far32.pcd", "far32.ply"):
            with pytest.raises(ValueError, match="float32 rounds by more than 1 mm"):
                write_points(tmp_path / name, pts, dtype=np.float32)
            assert not (tmp_path / name).exists()
    # a list of SurfaceClouds (what a run writes) is checked as an array is
    c = nbvkit._core.SurfaceCloud(voxel_size=0.5)
    c.add(np.array([[500000.3, 100.3, 5.1], [500001.3, 100.3, 5.1]]))  # above min_z
    with pytest.warns(RuntimeWarning, match="rounds by up to 15.6 mm: written as F 8"):
        write_points(tmp_path / "list.pcd", [c])
    np.testing.assert_array_equal(read_points(tmp_path / "list.pcd"), c.points)
    with pytest.raises(ValueError, match="float32 rounds by more than 1 mm"):
        write_points(tmp_path / "list32.pcd", [c], dtype=np.float32)
    near = np.array([[16383.0, 0.1, 0.2]])  # within 1 mm in float32: F 4 as before
    write_points(tmp_path / "near.pcd", near)
    assert "SIZE 4 4 4" in (tmp_path / "near.pcd").read_bytes().split(b"DATA")[0].decode()


def test_open3d_reads_our_files(tmp_path):
    o3d = pytest.importorskip("open3d")
    pts = sample_points()
    for name, kw, tol in (
        ("o.ply", {}, 0),
        ("oa.ply", {"ascii": True}, 1e-9),
        ("o.pcd", {}, 1e-3),
        ("oa.pcd", {"ascii": True}, 1e-3),
    ):
        write_points(tmp_path / name, pts, **kw)
        got = np.asarray(o3d.io.read_point_cloud(str(tmp_path / name)).points)
        np.testing.assert_allclose(got, pts, atol=tol, rtol=0)


@pytest.mark.parametrize(
    "name,kw",
    [
        ("w.ply", {"write_ascii": False}),
        ("w.ply", {"write_ascii": True}),
        ("w.pcd", {"write_ascii": False}),
        ("w.pcd", {"write_ascii": True}),
        ("w.pcd", {"write_ascii": False, "compressed": True}),
    ],
)
def test_reads_open3d_files_with_extra_attributes(tmp_path, name, kw):
    o3d = pytest.importorskip("open3d")
    pts = sample_points(seed=2)
    rng = np.random.default_rng(0)
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    pc.normals = o3d.utility.Vector3dVector(rng.normal(size=pts.shape))
    pc.colors = o3d.utility.Vector3dVector(rng.uniform(size=pts.shape))
    assert o3d.io.write_point_cloud(str(tmp_path / name), pc, **kw)
    expected = np.asarray(o3d.io.read_point_cloud(str(tmp_path / name)).points)
    back = read_points(tmp_path / name)
    np.testing.assert_allclose(back, expected, rtol=0, atol=1e-9)
    np.testing.assert_allclose(back, pts, rtol=1e-5)  # open3d's ASCII PLY keeps 6 digits


PLY_MESH_ASCII = """ply
format ascii 1.0
comment a mesh: vertices with normals, then faces
element vertex 3
property float x
property float y
property float z
property float nx
property float ny
property float nz
element face 1
property list uchar int vertex_indices
end_header
0 0 0 0 0 1
1 0 0 0 0 1
0 2.5 -1 0 0 1
3 0 1 2
"""


def test_ply_mesh_file_ascii(tmp_path):
    (tmp_path / "m.ply").write_text(PLY_MESH_ASCII)
    np.testing.assert_array_equal(
        read_points(tmp_path / "m.ply"), [[0, 0, 0], [1, 0, 0], [0, 2.5, -1]]
    )


def test_ply_binary_big_endian_with_elements_before_vertices(tmp_path):
    header = (
        "ply\nformat binary_big_endian 1.0\nelement camera 1\nproperty list uchar float k\n"
        "element vertex 2\nproperty uchar red\nproperty double z\nproperty float y\n"
        "property double x\nend_header\n"
    )
    body = struct.pack(">B2f", 2, 1.0, 2.0)  # the camera element: a 2-long list
    body += struct.pack(">Bdfd", 7, 3.0, 2.0, 1.0) + struct.pack(">Bdfd", 9, -3.0, -2.0, -1.0)
    (tmp_path / "b.ply").write_bytes(header.encode() + body)
    np.testing.assert_array_equal(read_points(tmp_path / "b.ply"), [[1, 2, 3], [-1, -2, -3]])


def test_pcd_with_other_fields_and_counts(tmp_path):
    n = 4
    pts = sample_points(n)
    header = (
        "# .PCD v0.7\nVERSION 0.7\nFIELDS intensity x y z hist _\nSIZE 2 4 4 8 4 1\n"
        "TYPE U F F F F U\nCOUNT 1 1 1 1 3 1\nWIDTH 2\nHEIGHT 2\n"
        "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 4\nDATA binary\n"
    )
    rec = np.zeros(
        n,
        dtype=[
            ("i", "<u2"),
            ("x", "<f4"),
            ("y", "<f4"),
            ("z", "<f8"),
            ("h", "<f4", (3,)),
            ("pad", "u1"),
        ],
    )
    rec["x"], rec["y"], rec["z"] = pts[:, 0], pts[:, 1], pts[:, 2]
    rec["h"] = 7
    (tmp_path / "f.pcd").write_bytes(header.encode() + rec.tobytes())
    back = read_points(tmp_path / "f.pcd")
    np.testing.assert_allclose(back[:, :2], pts[:, :2].astype(np.float32))
    np.testing.assert_array_equal(back[:, 2], pts[:, 2])
    lines = "".join(
        f"{int(a['i'])} {float(a['x'])!r} {float(a['y'])!r} {float(a['z'])!r} 7 7 7 0\n"
        for a in rec
    )
    asc = header.replace("binary", "ascii").encode() + lines.encode()
    (tmp_path / "fa.pcd").write_bytes(asc)
    np.testing.assert_allclose(read_points(tmp_path / "fa.pcd"), back)


def test_nonfinite_points_in_files_are_dropped(tmp_path):
    header = (
        "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 3\nHEIGHT 1\n"
        "POINTS 3\nDATA ascii\n1 2 3\nnan nan nan\n4 5 6\n"
    )
    (tmp_path / "n.pcd").write_text(header)
    with pytest.warns(RuntimeWarning, match="dropped 1 points"):
        pts = read_points(tmp_path / "n.pcd")
    np.testing.assert_array_equal(pts, [[1, 2, 3], [4, 5, 6]])
    assert read_points(tmp_path / "n.pcd", drop_nonfinite=False).shape == (3, 3)


def test_read_errors(tmp_path):
    missing = tmp_path / "nope.ply"
    with pytest.raises(FileNotFoundError, match="nope.ply"):
        read_points(missing)
    (tmp_path / "a.xyz").write_text("1 2 3\n")
    with pytest.raises(ValueError, match=r"a\.xyz.*unknown extension"):
        read_points(tmp_path / "a.xyz")
    (tmp_path / "garbage.ply").write_bytes(b"\x00\x01 not a ply")
    with pytest.raises(ValueError, match=r"garbage\.ply.*not a PLY"):
        read_points(tmp_path / "garbage.ply")
    (tmp_path / "empty.ply").write_bytes(b"")
    with pytest.raises(ValueError, match="empty.ply"):
        read_points(tmp_path / "empty.ply")
    (tmp_path / "noy.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
        "property float z\nend_header\n1 2\n"
    )
    with pytest.raises(ValueError, match="no 'y' property"):
        read_points(tmp_path / "noy.ply")
    write_points(tmp_path / "t.ply", sample_points(100))
    data = (tmp_path / "t.ply").read_bytes()
    (tmp_path / "t.ply").write_bytes(data[:-10])
    with pytest.raises(ValueError, match=r"t\.ply.*truncated"):
        read_points(tmp_path / "t.ply")
    write_points(tmp_path / "t.pcd", sample_points(100))
    data = (tmp_path / "t.pcd").read_bytes()
    (tmp_path / "t.pcd").write_bytes(data[:-10])
    with pytest.raises(ValueError, match=r"t\.pcd.*truncated"):
        read_points(tmp_path / "t.pcd")
    (tmp_path / "bad.pcd").write_text(
        "VERSION 0.7\nFIELDS x y\nSIZE 4 4\nTYPE F F\nCOUNT 1 1\n"
        "WIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n1 2\n"
    )
    with pytest.raises(ValueError, match="no 'z' field"):
        read_points(tmp_path / "bad.pcd")
    np.save(tmp_path / "bad.npy", np.zeros((3, 4)))
    with pytest.raises(ValueError, match=r"bad\.npy.*\(N, 3\)"):
        read_points(tmp_path / "bad.npy")
    (tmp_path / "dir.ply").mkdir()
    with pytest.raises(ValueError, match="directory"):
        read_points(tmp_path / "dir.ply")


def test_corrupt_compressed_pcd(tmp_path):
    header = (
        "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\n"
        "POINTS 2\nDATA binary_compressed\n"
    )
    body = struct.pack("<II", 4, 24) + b"\xff\xff\xff\xff"  # a back reference before any output
    (tmp_path / "c.pcd").write_bytes(header.encode() + body)
    with pytest.raises(ValueError, match=r"c\.pcd.*corrupt"):
        read_points(tmp_path / "c.pcd")


def test_write_errors(tmp_path):
    with pytest.raises(ValueError, match="unknown extension"):
        write_points(tmp_path / "a.txt", np.zeros((1, 3)))
    with pytest.raises(ValueError, match="NaN or infinite"):
        write_points(tmp_path / "a.ply", [[0, np.nan, 0]])
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        write_points(tmp_path / "a.ply", np.zeros((2, 2)))
    with pytest.raises(ValueError, match="dtype"):
        write_points(tmp_path / "a.ply", np.zeros((2, 3)), dtype=np.int32)
    with pytest.raises(FileNotFoundError):
        write_points(tmp_path / "no" / "such" / "dir.ply", np.zeros((2, 3)))
