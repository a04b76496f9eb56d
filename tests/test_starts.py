"""The predefined starts (workspace.start_poses, World) where the workspace is unusual: a flight
envelope far above or below the structure, and a start that cannot be placed at all."""
from __future__ import annotations

import numpy as np
import pytest

import nbvkit
from conftest import box_mesh
from nbvkit.config import Config
from nbvkit.mission import MissionError
from nbvkit.world import World

FAST = ["map.resolution=0.4", "progress=false", "evaluation.gt_density=100"]


def boxes(*spans) -> nbvkit.Mesh:
    """One mesh of several axis-aligned boxes, each (lo, hi)."""
    parts = [box_mesh(lo, hi) for lo, hi in spans]
    v = np.vstack([p.vertices for p in parts])
    offsets = np.cumsum([0] + [len(p.vertices) for p in parts[:-1]])
    f = np.vstack([p.faces + o for p, o in zip(parts, offsets)]).astype(np.int32)
    return nbvkit.Mesh(v, f)


def sees(world, pose) -> bool:
    """Whether the camera at `pose` hits the structure in at least 5 % of its pixels."""
    return len(world.camera.scan_pose(pose).hits) >= 0.05 * 640 * 480


@pytest.mark.parametrize(
    "bounds",
    [
        ["workspace.margin_z=15"],  # the navigation box's mid height 5 m above the roof
        ["workspace.bounds_min=[-5,-5,-100]", "workspace.bounds_max=[25,25,7]"],  # deep below
    ],
)
def test_starts_stay_apart_and_see_a_structure_far_below_the_boxs_mid_height(bounds):
    """At the navigation box's mid height no place on a start's bearing saw the box: every
    start walked to the centre, five copies of one spot (10, 10, 10) seeing nothing, or 46 m
    underground. They are placed at the structure's mid height instead."""
    world = World(Config().with_overrides(FAST + bounds), mesh=box_mesh([0, 0, 0], [20, 20, 5]))
    s = world.starts
    assert np.all(np.isfinite(s))
    gaps = np.linalg.norm(s[:, None, :2] - s[None, :, :2], axis=-1)[np.triu_indices(5, 1)]
    assert gaps.min() > 5.0, s  # apart, not one spot
    for k, pose in enumerate(s):
        assert 0.0 <= pose[2] <= 5.0, (k, pose)  # within the box's height
        assert world.workspace.contains(pose) and not world._collides(pose), (k, pose)
        assert sees(world, pose), (k, pose)


def test_a_start_that_cannot_be_placed_does_not_stop_another_or_a_given_pose():
    """A courtyard 30 m square filling its workspace: the starts whose bearing runs into a wall
    have no clear place inside the navigation bounds. That refused every mission on this
    structure, a given start_pose in the open courtyard too; now only those starts are
    refused, by number, naming the keys to change."""
    ring = boxes(
        ([0, 0, 0], [30, 1, 6]), ([0, 29, 0], [30, 30, 6]),
        ([0, 1, 0], [1, 29, 6]), ([29, 1, 0], [30, 29, 6]),
    )  # fmt: skip
    tight = FAST + ["workspace.margin_xy=0"]
    world = World(Config().with_overrides(tight + ["start_pose=[15,15,3,0]"]), mesh=ring)
    assert np.allclose(world.start_pose, [15, 15, 3, 0])
    unplaced = [k for k in range(5) if not np.all(np.isfinite(world.starts[k]))]
    placed = [k for k in range(5) if k not in unplaced]
    assert unplaced and placed  # the case this guards against
    for k in placed:
        w = World(Config().with_overrides(tight + [f"start={k}"]), mesh=ring)
        assert np.allclose(w.start_pose, world.starts[k])
    with pytest.raises(MissionError, match=rf"start {unplaced[0]}: .*workspace\.margin_xy"):
        World(Config().with_overrides(tight + [f"start={unplaced[0]}"]), mesh=ring)
    # a flight envelope above the structure (margin_z null): the starts keep below its top,
    # and the message gives those bounds and the one key that moves them
    with pytest.raises(MissionError) as e:
        World(Config().with_overrides(tight + ["workspace.margin_z=null", "start=0"]), mesh=ring)
    msg = str(e.value)
    assert "(workspace.margin_xy)" in msg and "margin_z" not in msg, msg
    top = float(msg.split("] - [")[1].split("]")[0].split(",")[2])
    assert top < 8.5, msg  # the starts' box, not the envelope's
    explicit = ["workspace.bounds_min=[0,0,0]", "workspace.bounds_max=[30,30,8.5]"]
    with pytest.raises(MissionError, match=r"workspace\.bounds_min, workspace\.bounds_max"):
        World(Config().with_overrides(FAST + explicit + [f"start={unplaced[0]}"]), mesh=ring)
