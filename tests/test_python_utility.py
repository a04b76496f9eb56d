"""View utilities in Python: candidate_rays (what each candidate's rays reach, one C++ call) and
the PythonUtility adapter, checked against evaluate_views' ig utility on the same candidates."""
from __future__ import annotations

import math

import numpy as np
import pytest

import nbvkit
from conftest import seen_box_world
from nbvkit import _core
from nbvkit.config import Config
from nbvkit.planning import PythonUtility
from nbvkit.planning.utilities import candidate_of_cells, information_gain, per_candidate
from nbvkit.sampling import candidate_poses


@pytest.fixture(scope="module")
def world():
    """A 6 x 6 x 5 m box seen once by the camera and the laser from the start, at 0.4 m."""
    return seen_box_world()


def candidates(world):
    """The 80 CGVS candidates around the vehicle, half of them pitched (K, 5), plus two views
    that cannot be valid: inside the box and far outside the bounds."""
    level = candidate_poses(world.state.pose)
    pitch = np.where(np.arange(len(level)) % 2, 0.0, 0.3)
    poses = np.column_stack([level, pitch])
    bad = [[0.0, 0.0, 2.5, 0.0, 0.0], [500.0, 0.0, 2.5, 0.0, 0.0]]
    return np.vstack([poses, bad])


def ig_scores(world, poses):
    return _core.evaluate_views(
        world.map,
        poses,
        world.state.pose,
        camera=world.view_camera,
        utility=_core.UtilityOptions(name="ig"),
        validity=world.validity(),
        surface=world.surface,
    )


def test_the_rays_come_as_numpy_arrays_of_the_documented_shapes(world):
    poses = candidates(world)
    k = len(poses)
    r = nbvkit.candidate_rays(
        world.map, poses, world.state.pose, world.view_camera, world.validity(), world.surface
    )
    assert isinstance(r, nbvkit.CandidateRays) and len(r) == k
    n = r.num_cells
    assert n > 1000
    expect = {
        "offsets": ((k + 1,), np.int64),
        "status": ((k,), np.int8),
        "occupied_seen": ((k,), np.int32),
        "index": ((n,), np.int64),
        "centers": ((n, 3), np.float64),
        "probability": ((n,), np.float64),
        "logodds": ((n,), np.float32),
        "state": ((n,), np.int8),
        "range": ((n,), np.float64),
        "incidence": ((n,), np.float64),
        "seen": ((n,), np.uint32),
        "hits": ((n,), np.uint16),
    }
    for name, (shape, dtype) in expect.items():
        a = getattr(r, name)
        assert a.shape == shape and a.dtype == dtype, name
        assert not a.flags.writeable, name
    off = r.offsets
    assert off[0] == 0 and off[-1] == n and np.all(np.diff(off) >= 0)
    # the cells: in the workspace, where index_of puts them, each once per candidate
    np.testing.assert_array_equal(world.map.index_of(r.centers), r.index)
    owner = candidate_of_cells(r)
    assert len(np.unique(owner * world.map.num_cells + r.index)) == n
    np.testing.assert_allclose(r.probability, 1 / (1 + np.exp(-r.logodds.astype(float))))
    assert np.all(r.probability[r.state == -1] == 0.5)
    np.testing.assert_array_equal(r.state, world.map.state(r.centers))
    assert np.all(r.range >= 0) and np.all(r.range <= world.view_camera.max_range / math.cos(1))
    inc = r.incidence
    # only the camera's own cell has none: one per walked view (a camera on a face between
    # cells also enters the next one at range 0, through that face)
    assert np.all(r.range[np.isnan(inc)] == 0) and not np.signbit(r.range).any()
    walked = np.diff(r.offsets) > 0
    np.testing.assert_array_equal(per_candidate(r, np.isnan(inc))[walked], 1)
    assert np.all((inc[~np.isnan(inc)] >= 0) & (inc[~np.isnan(inc)] <= math.pi / 2 + 1e-12))
    # a candidate's view: its rows, as their own arrays
    j = int(np.argmax(np.diff(off)))
    v = r.view(j)
    assert len(v) == off[j + 1] - off[j] and v.status == r.status[j] and v.k == j
    np.testing.assert_array_equal(v.centers, r.centers[off[j] : off[j + 1]])
    np.testing.assert_array_equal(v.range, r.range[off[j] : off[j + 1]])
    assert r.view(-1).k == k - 1
    with pytest.raises(IndexError):
        r.view(k)
    # the arrays outlive the object they view
    c = r.view(j).centers
    del r, v
    assert c.shape == (off[j + 1] - off[j], 3) and np.isfinite(c).all()
    # without camera observations there are no seen / hits
    assert nbvkit.candidate_rays(world.map, poses[:3], world.state.pose).seen is None


def test_invalid_candidates_get_the_status_of_evaluate_views(world):
    poses = candidates(world)
    ig = ig_scores(world, poses)
    r = PythonUtility(information_gain(world.map.options)).rays(world, poses)
    np.testing.assert_array_equal(r.status, ig["status"])
    np.testing.assert_array_equal(r.occupied_seen, ig["occupied_seen"])
    assert r.status[-2] == 2 and r.status[-1] == 1  # inside the box; out of bounds
    cells = np.diff(r.offsets)
    assert np.all(cells[np.isin(r.status, [1, 2, 3])] == 0)  # not walked
    assert (r.status == 0).sum() >= 20


def test_the_python_information_gain_is_the_ig_utility(world):
    """The map's entropy rule applied in numpy to the cells the rays reach gives evaluate_views'
    ig gain to 1e-6 and its cells exactly; the plain binary entropy of the probability counts
    the clamped cells too, so it is never lower, and counts exactly the distinct cells reached
    where no reached cell is clamped."""
    poses = candidates(world)
    ig = ig_scores(world, poses)
    scores = PythonUtility(information_gain(world.map.options)).score(world, poses)
    assert set(scores) == set(ig)
    for key in ("status", "occupied_seen", "cells"):
        np.testing.assert_array_equal(scores[key], ig[key], err_msg=key)
    valid = ig["status"] == 0
    assert valid.sum() >= 20 and np.all(ig["gain"][valid] > 0)
    np.testing.assert_allclose(scores["gain"][valid], ig["gain"][valid], rtol=1e-6)
    np.testing.assert_array_equal(scores["utility"][~valid], -np.inf)
    np.testing.assert_allclose(scores["utility"][valid], ig["utility"][valid], rtol=1e-6)
    assert scores["gain"].dtype == np.float64 and scores["cells"].dtype == np.int32

    def entropy_gain(rays):  # the module docstring's example
        p = np.clip(rays.probability, 1e-12, 1 - 1e-12)
        return per_candidate(rays, -(p * np.log(p) + (1 - p) * np.log1p(-p)))

    plain = PythonUtility(entropy_gain).score(world, poses)
    assert np.all(plain["gain"][valid] >= ig["gain"][valid] * (1 - 1e-6))
    np.testing.assert_array_equal(plain["status"], ig["status"])
    assert np.all(plain["cells"] >= ig["cells"])  # every distinct cell reached
    # it ranks the views as ig does, nearly: the best ig view is among its best few
    order = np.argsort(-plain["utility"])
    assert np.argmax(ig["utility"]) in order[:5]


@pytest.mark.parametrize(
    "rule", [{}, {"entropy_unit": "bits"}, {"clamped_entropy_zero": False}], ids=str
)
def test_the_python_information_gain_follows_the_maps_entropy_rule(rule):
    """A wall scanned 4 times (its free cells in front clamped): the ig gain and cells under each
    entropy rule of the map."""
    from conftest import wall_mesh

    m = nbvkit.OccupancyMap(0.2, (-10, -10, 0), (20, 10, 10), options=rule)
    m.mark_free_segment((5, 0, 5), (5, 0, 5), 1.5)
    cam = nbvkit.DepthCamera(wall_mesh(x=11.0), max_range=12.0)
    for _ in range(4):
        m.integrate(cam.scan_pose([5.0, 0, 5, 0]))
    views = [[5, 0, 5, 0.0], [5, 0, 5, 0.5], [5, 0.3, 5, -0.3], [5.5, 0, 5, 0.1]]
    ig = _core.evaluate_views(m, views, (5, 0, 5, 0))
    assert np.all(ig["status"] == 0)
    rays = nbvkit.candidate_rays(m, views, (5, 0, 5, 0))
    gain, cells = information_gain(m.options)(rays)
    np.testing.assert_allclose(gain, ig["gain"], rtol=1e-6)
    np.testing.assert_array_equal(cells, ig["cells"])
    clamped = (rays.state == 0) & (rays.logodds < -1.9)
    assert clamped.any()  # the rule matters here
    assert np.all(cells < np.diff(rays.offsets)) == rule.get("clamped_entropy_zero", True)


def test_score_python_is_the_entry_of_a_planner_for_a_registered_utility(world):
    """score_python(fn, world, poses): what a planner's scoring calls for a utility registered
    from Python, with the configured options' occupied constraint."""
    from nbvkit.planning.utilities import score_python

    poses = candidates(world)
    fn = information_gain(world.map.options)
    ig = ig_scores(world, poses)
    s = score_python(lambda rays: fn(rays)[0], world, poses)
    np.testing.assert_array_equal(s["status"], ig["status"])
    valid = ig["status"] == 0
    np.testing.assert_allclose(s["utility"][valid], ig["utility"][valid], rtol=1e-6)
    strict = score_python(fn, world, poses, _core.UtilityOptions(require_occupied_probability=0.75))
    loose = score_python(fn, world, poses, _core.UtilityOptions(require_occupied=False))
    assert np.any(strict["status"] == 4) and not np.any(loose["status"] == 4)


def test_the_distance_weight_and_the_occupied_constraint_follow_the_utility_options(world):
    poses = candidates(world)
    here = world.state.pose
    kw = dict(camera=world.view_camera, validity=world.validity(), surface=world.surface)
    ig = _core.evaluate_views(
        world.map,
        poses,
        here,
        utility=dict(name="ig_distance", require_occupied_probability=0.75),
        **kw,
    )
    u = PythonUtility(
        information_gain(world.map.options),
        distance_lambda=0.5,
        require_occupied_probability=0.75,
    )
    s = u.score(world, poses)
    np.testing.assert_array_equal(s["status"], ig["status"])
    valid = ig["status"] == 0
    assert valid.sum() > 20 and np.any(s["status"] == 4)  # some views see only p < 0.75
    np.testing.assert_allclose(s["utility"][valid], ig["utility"][valid], rtol=1e-6)
    off = PythonUtility(lambda r: per_candidate(r, np.ones(r.num_cells)), require_occupied=False)
    assert not np.any(off.score(world, poses)["status"] == 4)


def test_bad_input_raises_value_error_naming_the_problem(world):
    m, here = world.map, world.state.pose
    with pytest.raises(ValueError, match=r"\(K, 4\)"):
        nbvkit.candidate_rays(m, [[5, 0, 5]], here)
    with pytest.raises(ValueError, match="NaN"):
        nbvkit.candidate_rays(m, [[5, 0, np.nan, 0]], here)
    with pytest.raises(ValueError, match="NaN|infinite"):
        nbvkit.candidate_rays(m, [[5, 0, np.inf, 0]], here)
    with pytest.raises(ValueError, match="pitch"):
        nbvkit.candidate_rays(m, [[5, 0, 5, 0, 2.0]], here)
    with pytest.raises(ValueError, match="current pose"):
        nbvkit.candidate_rays(m, [[5, 0, 5, 0]], (0, 0, 0))
    with pytest.raises(ValueError, match="max_range"):
        nbvkit.candidate_rays(m, [[5, 0, 5, 0]], here, camera={"max_range": -1.0})
    with pytest.raises(TypeError, match="unknown ValidityOptions option 'nope'"):
        nbvkit.candidate_rays(m, [[5, 0, 5, 0]], here, validity={"nope": 1})
    empty = nbvkit.candidate_rays(m, np.zeros((0, 4)), here)
    assert len(empty) == 0 and empty.offsets.tolist() == [0] and empty.centers.shape == (0, 3)
    assert not empty.centers.flags.writeable and empty.status.shape == (0,)
    poses = candidates(world)
    with pytest.raises(ValueError, match=rf"shape \(3,\), not \({len(poses)},\)"):
        PythonUtility(lambda r: np.zeros(3)).score(world, poses)
    with pytest.raises(ValueError, match="non-finite gain"):
        PythonUtility(lambda r: np.full(len(r), np.nan)).score(world, poses)
    # used directly, not registered: checked as a registered utility is, by its name
    with pytest.raises(ValueError, match="'mine' returned a negative gain"):
        PythonUtility(lambda r: -np.ones(len(r)), name="mine").score(world, poses)
    with pytest.raises(TypeError, match="'mine' returned NoneType gains"):
        PythonUtility(lambda r: None, name="mine").score(world, poses)
    with pytest.raises(TypeError, match="'mine' returned str gains"):
        PythonUtility(lambda r: "high", name="mine").score(world, poses)
    with pytest.raises(ValueError, match="distance_lambda"):
        PythonUtility(lambda r: 0, distance_lambda=-1)
    with pytest.raises(ValueError, match="require_occupied_probability"):
        PythonUtility(lambda r: 0, require_occupied_probability=1.5)
    with pytest.raises(ValueError, match=r"per-cell values must have shape"):
        per_candidate(nbvkit.candidate_rays(m, poses, here), np.zeros(2))


def test_a_mission_flies_on_a_registered_python_utility_as_on_the_ig_utility():
    """Scenario 1 with its utility the Python information gain, registered by name
    (register_utility, utility.name): every call the planner makes scores as evaluate_views' ig
    utility would, and the mission flies."""
    from conftest import TINY_RUN
    from nbvkit.mission import Mission
    from nbvkit.planning import registry

    maps = []  # the mission's map options, known once it is built
    registry.register_utility("python_ig", lambda rays: information_gain(maps[0])(rays)[0])
    try:
        m = Mission(
            Config().with_overrides(
                list(TINY_RUN) + ["scenario=1", "progress=false", "utility.name=python_ig"]
            )
        )
        maps.append(m.map.options)
        scorer, calls = m.planner.score, []
        assert scorer.python is not None

        class Checked:
            """The planner's scorer, each call also scored by evaluate_views' ig utility."""

            def __call__(self, world, poses):
                ours = scorer(world, poses)
                theirs = ig_scores(world, poses)
                calls.append((ours, theirs))
                return ours

            def __getattr__(self, name):
                return getattr(scorer, name)

        m.planner.score = Checked()
        m.run()
    finally:
        registry.UTILITIES.pop("python_ig")
    assert len(m.records) == 2 and len(calls) >= 2
    for ours, theirs in calls:
        np.testing.assert_array_equal(ours["status"], theirs["status"])
        valid = theirs["status"] == 0
        assert valid.any()
        np.testing.assert_allclose(ours["utility"][valid], theirs["utility"][valid], rtol=1e-6)


@pytest.mark.parametrize(
    "out, error, match",
    [
        (lambda r: np.full(len(r), np.nan), ValueError, "non-finite gain"),
        (lambda r: np.full(len(r), np.inf), ValueError, "non-finite gain"),
        (lambda r: -np.ones(len(r)), ValueError, r"negative gain \(-1.0\) for valid candidate"),
        (lambda r: np.ones(len(r) + 1), ValueError, r"gains of shape \(\d+,\), not"),
        (lambda r: np.ones((len(r), 1)), ValueError, r"gains of shape \(\d+, 1\), not"),
        (lambda r: 1.0, ValueError, r"gains of shape \(\), not"),
        (lambda r: None, TypeError, "returned NoneType gains"),
        (lambda r: "abc", TypeError, "returned str gains"),
        (lambda r: ["a"] * len(r), TypeError, "returned list of dtype <U1 gains"),  # not floats
        (lambda r: (np.ones(len(r)),) * 3, TypeError, "returned a tuple of 3"),
        (lambda r: (np.ones(len(r)), np.ones(2)), ValueError, r"cells of shape \(2,\)"),
    ],
    ids=["nan", "inf", "negative", "long", "2d", "scalar", "none", "str", "str-list",
         "3-tuple", "cells-short"],
)  # fmt: skip
def test_a_registered_utility_returning_nonsense_is_an_error_naming_it(world, out, error, match):
    from nbvkit.planning import registry
    from nbvkit.planning.scoring import Scorer

    registry.register_utility("hostile_u", out)
    assert registry.UTILITIES["hostile_u"] is out  # registered as it is, checked where called
    try:
        scorer = Scorer(Config().with_overrides(["utility.name=hostile_u"]).utility)
        with pytest.raises(error, match=match) as e:
            scorer(world, candidates(world))
    finally:
        registry.UTILITIES.pop("hostile_u")
    assert "utility 'hostile_u'" in str(e.value)


def test_a_registered_utility_is_free_on_invalid_candidates_and_named_when_it_raises(world):
    """Gains of invalid candidates (status != 0) are not read: NaN there is no error; an
    exception of the utility's own propagates as it is, noted with its name."""
    import sys

    from nbvkit.planning import registry
    from nbvkit.planning.scoring import Scorer

    def nan_where_invalid(rays):
        return np.where(rays.status == 0, 1.0, np.nan)

    def raising(rays):
        raise KeyError("cell")

    registry.register_utility("nan_invalid", nan_where_invalid)
    registry.register_utility("raising", raising)
    try:
        poses = candidates(world)
        s = Scorer(Config().with_overrides(["utility.name=nan_invalid"]).utility)(world, poses)
        valid = s["status"] == 0
        assert valid.any() and (~valid).any()
        np.testing.assert_array_equal(s["utility"][valid], 1.0)
        assert np.all(s["utility"][~valid] == -np.inf)
        scorer = Scorer(Config().with_overrides(["utility.name=raising"]).utility)
        with pytest.raises(KeyError, match="cell") as e:
            scorer(world, poses)
        if sys.version_info >= (3, 11):
            assert f"by the utility 'raising' (registered from {__file__})" in e.value.__notes__[0]
    finally:
        registry.UTILITIES.pop("nan_invalid")
        registry.UTILITIES.pop("raising")
