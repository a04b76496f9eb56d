"""_core.place_patch_views against the Python loop it replaced (kept here as the reference):
the same views, in the same order, to the last bit, over random patches, normals straight up
and down and near the thresholds, with and without a gimbal and a mount pitch."""
from __future__ import annotations

import math

import numpy as np
import pytest

from nbvkit import _core


def reference_views(centers, normals, reach, half, mount, mount_yaw, spread, gimbal, lo_p, hi_p):
    """The loop place_views ran in Python floats before it moved to C++: (rows, owner, bands)."""
    rows, owner, bands = [], [], []
    for i, (c, n) in enumerate(zip(centers.tolist(), normals.tolist())):
        h = math.hypot(n[0], n[1])
        el_n = math.atan2(n[2], h)
        pitches = [0.0]
        if gimbal and abs(-el_n + mount) > half:
            pitch = min(max(el_n - mount, lo_p), hi_p)
            if pitch != 0.0:  # clamped to level: the level view is there already
                pitches.append(pitch)
        for pitch in pitches:
            axis_el = -(mount + pitch)
            el = -min(max(-el_n, axis_el - half), axis_el + half)
            head_on = abs(el - el_n) < 1e-9
            if h > 0.3 or (head_on and h > 1e-9):
                az0 = math.atan2(n[1], n[0])
                azimuths = [az0] if spread == 0 else [az0, az0 - spread, az0 + spread]
            elif head_on:
                azimuths = [0.0]
            else:
                azimuths = [k * math.pi / 3 for k in range(6)]
            band = (axis_el - half, axis_el + half)
            for az in azimuths:
                ux = math.cos(el) * math.cos(az)
                uy = math.cos(el) * math.sin(az)
                uz = math.sin(el)
                yaw = az + math.pi - mount_yaw
                if abs(ux) + abs(uy) > 1e-12:
                    yaw = math.atan2(-uy, -ux) - mount_yaw
                yaw = math.remainder(yaw, 2 * math.pi)
                for d in reach:
                    rows.append((c[0] + d * ux, c[1] + d * uy, c[2] + d * uz, yaw, pitch))
                    owner.append(i)
                    bands.append(band)
    return np.asarray(rows, float).reshape(-1, 5), np.asarray(owner, int), np.asarray(bands)


def _normals(rng, n):
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    special = np.array(
        [[0, 0, 1.0], [0, 0, -1.0], [1.0, 0, 0], [0, -1.0, 0], [0.3, 0, math.sqrt(0.91)]]
    )
    tilt = rng.uniform(0.25, 0.35, size=(n // 4, 1))  # horizontal parts about the 0.3 threshold
    near = np.column_stack([tilt, np.zeros_like(tilt), np.sqrt(1 - tilt**2)])
    return np.vstack([special, v, near, -near])


@pytest.mark.parametrize(
    "gimbal, mount_deg, spread_deg, limits_deg",
    [
        (False, 0.0, 30.0, (0.0, 0.0)),
        (True, 0.0, 30.0, (-30.0, 90.0)),
        (True, 10.0, 0.0, (-30.0, 60.0)),
        (False, -5.0, 45.0, (0.0, 0.0)),
        (True, 0.0, 30.0, (0.0, 90.0)),  # looking down only (placement.explore_gimbal)
    ],
)
def test_views_match_the_python_loop_bit_for_bit(gimbal, mount_deg, spread_deg, limits_deg):
    rng = np.random.default_rng(7)
    normals = _normals(rng, 4000)
    centers = rng.uniform(-50, 50, size=(len(normals), 3))
    args = dict(
        reach=[3.6, 5.6],
        half=math.radians(45 / 2 - 4.0),
        mount=math.radians(mount_deg),
        mount_yaw=math.radians(3.0),
        spread=math.radians(spread_deg),
        gimbal=gimbal,
        lo_pitch=math.radians(limits_deg[0]),
        hi_pitch=math.radians(limits_deg[1]),
    )
    h = [math.hypot(x, y) for x, y in normals[:, :2].tolist()]
    poses, owner, bands = _core.place_patch_views(centers, normals, h, **args)
    ref = reference_views(centers, normals, *args.values())
    assert len(poses) > 2 * len(normals)  # side views, six azimuths, pitched views
    assert np.array_equal(poses, ref[0]) and np.array_equal(owner, ref[1])
    assert np.array_equal(bands, ref[2])
    if gimbal:
        assert np.any(poses[:, 4] != 0)  # roofs and undersides faced by the gimbal
    # no view twice: a pitch clamped to level is the level view
    assert len(np.unique(np.column_stack([poses, owner]), axis=0)) == len(poses)


def test_bad_patch_arrays_are_refused_with_a_message():
    c = np.zeros((3, 3))
    geometry = dict(half=0.3, mount=0.0, mount_yaw=0.0, spread=0.5, gimbal=False)
    with pytest.raises(ValueError, match="differ in length"):
        _core.place_patch_views(c, c[:2], [0.0] * 3, [1.0], lo_pitch=0, hi_pitch=0, **geometry)
    with pytest.raises(ValueError, match="patch normals"):
        _core.place_patch_views(c, np.zeros((3, 2)), [0.0] * 3, [1.0], 0.3, 0, 0, 0.5, False, 0, 0)
