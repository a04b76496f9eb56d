"""CGVS lattice (Eq. 2), AGVS alpha rule, termination (Eq. 4-6) and C_view (Eq. 5)."""
from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

import nbvkit
from nbvkit.sampling import LATTICE, AdaptiveScale, candidate_poses, lattice_offsets, wrap_angle
from nbvkit.termination import viewable_cells


def test_lattice_has_80_offsets_with_the_paper_values():
    off = lattice_offsets(delta_d=1.0, delta_theta=math.pi / 4)
    assert off.shape == (80, 4)
    assert len({tuple(r) for r in LATTICE}) == 80 and not np.any(np.all(LATTICE == 0, axis=1))
    expect = {
        (i * 1.0, j * 1.0, k * 1.0, m * math.pi / 4)
        for i, j, k, m in itertools.product((-1, 0, 1), repeat=4)
        if (i, j, k, m) != (0, 0, 0, 0)
    }
    assert {tuple(np.round(r, 12)) for r in off} == {tuple(np.round(e, 12)) for e in expect}
    scaled = lattice_offsets(2.0, 0.1, scale=1.5**2)
    np.testing.assert_allclose(np.abs(scaled[:, :3]).max(), 2.0 * 2.25)
    np.testing.assert_allclose(np.abs(scaled[:, 3]).max(), 0.1)  # yaw is not scaled


def test_candidates_are_in_the_body_frame():
    pose = np.array([10.0, -5.0, 3.0, math.pi / 2])  # facing +y
    c = candidate_poses(pose)
    # the offset (i=1, 0, 0, 0) is one metre forward: +y in the world
    k = int(np.flatnonzero(np.all(LATTICE == [1, 0, 0, 0], axis=1))[0])
    np.testing.assert_allclose(c[k], [10.0, -4.0, 3.0, math.pi / 2], atol=1e-12)
    k = int(np.flatnonzero(np.all(LATTICE == [0, 1, 0, 0], axis=1))[0])  # body left = world -x
    np.testing.assert_allclose(c[k, :3], [9.0, -5.0, 3.0], atol=1e-12)
    k = int(np.flatnonzero(np.all(LATTICE == [0, 0, 0, 1], axis=1))[0])
    np.testing.assert_allclose(c[k], [10, -5, 3, wrap_angle(math.pi / 2 + math.pi / 4)], atol=1e-12)
    d = np.linalg.norm(c[:, :3] - pose[:3], axis=1)
    assert set(np.round(d, 9)) == {0.0, 1.0, round(math.sqrt(2), 9), round(math.sqrt(3), 9)}
    assert np.all((c[:, 3] >= -math.pi) & (c[:, 3] < math.pi))
    with pytest.raises(ValueError):
        candidate_poses([0, 0, np.nan, 0])


def test_alpha_follows_the_rule_on_a_scripted_sequence():
    a = AdaptiveScale(sigma=1.5, alpha_max=5, threshold=0.005, window=3)
    q, n = 0.001, 0.01  # quiet, not quiet
    seq = [n, q, q, q, q, q, n, q, q, q, q, q, q, q, q, q, q]
    alphas = [a.update(d) for d in seq]
    assert alphas == [0, 0, 0, 1, 2, 3, 0, 0, 0, 1, 2, 3, 4, 5, 5, 5, 5]
    assert a.scale == pytest.approx(1.5**5)
    assert AdaptiveScale(cap=7.5).scale == 1.0
    capped = AdaptiveScale(cap=7.5)
    for _ in range(8):
        capped.update(0.0)
    assert capped.alpha == 5 and capped.scale == 7.5
    off = AdaptiveScale(enabled=False)
    assert [off.update(0.0) for _ in range(6)] == [0] * 6 and off.scale == 1.0
    # negative entropy changes count by magnitude
    b = AdaptiveScale()
    assert [b.update(-0.001) for _ in range(3)][-1] == 1


def test_oscillation_counts_as_stuck_when_asked():
    a = AdaptiveScale(oscillation_is_stuck=True, window=3)
    A, B = (0.0, 0.0, 5.0), (1.0, 0.0, 5.0)
    loud = 1.0  # large entropy changes: only the oscillation makes it stuck
    alphas = [a.update(loud, p) for p in (A, B, A, B, A, B)]
    assert alphas == [0, 0, 0, 0, 0, 1]  # stuck at iterations 4, 5, 6 -> window of 3 at 6
    plain = AdaptiveScale(oscillation_is_stuck=False)
    assert [plain.update(loud, p) for p in (A, B, A, B, A, B)][-1] == 0


def test_termination_fires_exactly_after_n_quiet_iterations():
    """The mission's `entropy` termination: done at the window-th |dE_v| < threshold in a row;
    a loud iteration restarts the count, whichever the sign of the change (entropy may rise)."""
    from types import SimpleNamespace

    from nbvkit.planning.terminations.entropy import EntropyChange, EntropyConfig

    def run(entropies, c_view=1000.0, window=5):
        t = EntropyChange(EntropyConfig(threshold=0.001, window=window))
        steps = [
            SimpleNamespace(delta_ev=(a - b) / c_view) for a, b in itertools.pairwise(entropies)
        ]
        return [t.check(None, s) == "entropy_converged" for s in steps]

    E = [100.0, 90.0, 89.9995, 89.999, 89.9985, 89.998, 89.9975]  # dE_v 0.01, then 5e-7 each
    assert run(E) == [False, False, False, False, False, True]
    assert run(E, window=6) == [False] * 6
    e = list(itertools.accumulate([1000.0] + [-0.0] * 4 + [-5.0] + [-0.0] * 5))  # a loud fall at 5
    assert run(e).index(True) == 9
    rise = [1000.0, 1000.0, 1000.0, 1002.0, 1002.0]  # entropy rose by 2 (|dE_v| 0.002): loud
    assert run(rise, window=2) == [False, True, False, False]


def test_c_view_matches_the_closed_form_frustum():
    cam = nbvkit.DepthCamera(nbvkit.Mesh([[9, 0, 0], [9, 1, 0], [9, 0, 1]], [[0, 1, 2]]))
    th, tv = math.tan(math.radians(30)), math.tan(math.radians(22.5))
    V = 4 * th * tv / 3 * (8**3 - 0.5**3)
    assert cam.frustum_volume() == pytest.approx(V, rel=1e-12)
    assert viewable_cells(60, 45, 0.5, 8, 0.2, count_partial=False) == pytest.approx(V / 0.008)
    assert V / 0.008 == pytest.approx(20400, rel=0.001)


def test_c_view_with_partial_cells_matches_a_voxelisation():
    # Cells touched by the axis-aligned frustum, counted by brute force over random grid offsets.
    rng = np.random.default_rng(0)
    s, n_, f_ = 0.5, 0.5, 4.0
    th, tv = math.tan(math.radians(30)), math.tan(math.radians(22.5))
    counts = []
    for _ in range(6):
        off = rng.uniform(0, s, 3)
        i = np.arange(math.floor((0 - off[0]) / s) - 1, math.ceil((f_ - off[0]) / s) + 1)
        j = np.arange(
            math.floor((-f_ * th - off[1]) / s) - 1, math.ceil((f_ * th - off[1]) / s) + 1
        )
        k = np.arange(
            math.floor((-f_ * tv - off[2]) / s) - 1, math.ceil((f_ * tv - off[2]) / s) + 1
        )
        I, J, K = np.meshgrid(i, j, k, indexing="ij")
        lo = np.stack([I, J, K], -1).reshape(-1, 3) * s + off
        # a cell touches the convex frustum iff some point of it is inside: test a dense lattice
        g = np.linspace(0, s, 7)
        sub = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
        pts = lo[:, None, :] + sub[None]
        x, y, z = pts[..., 0], pts[..., 1], pts[..., 2]
        inside = (x >= n_) & (x <= f_) & (np.abs(y) <= x * th) & (np.abs(z) <= x * tv)
        counts.append(inside.any(axis=1).sum())
    expect = viewable_cells(60, 45, n_, f_, s, count_partial=True)
    assert np.mean(counts) == pytest.approx(expect, rel=0.04)
    assert expect > viewable_cells(60, 45, n_, f_, s, count_partial=False)
