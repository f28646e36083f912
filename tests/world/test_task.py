"""Task randomization: every sample inside its configured range, reachable, well conditioned,
reproducible; bad configs fail with one line; TrialSpec storage round trips."""

import math

import numpy as np
import pytest
from scipy import stats

from mjx_peg.world import constants, parts, task
from mjx_peg.world import kinematics as kin
from mjx_peg.world.rotations import rotvec_from_matrix, tool_down_rotation
from mjx_peg.world.task import HOLE_DEPTH, PEG_LENGTH, SHAPES, TaskConfig, TrialSpec, sample_trials

N = 10_000


@pytest.fixture(scope="module")
def default_specs():
    # Start jitter exercised here (the default is none), so the ranges it must obey are tested.
    config = TaskConfig(start_xy_jitter=0.01, start_tilt_jitter=np.deg2rad(5.0))
    return config, sample_trials(config, 0, N)


@pytest.fixture(scope="module")
def paper_specs():
    config = TaskConfig.from_mm_deg(("circle", "square"), 50, 8, 12).replace(
        start_xy_jitter=0.005, start_tilt_jitter=np.deg2rad(3.0)
    )
    return config, sample_trials(config, 1, 2000)


def _one_line_error(match: str, **changes) -> str:
    with pytest.raises(ValueError, match=match) as info:
        TaskConfig(**changes)
    message = str(info.value)
    assert "\n" not in message, message
    return message


@pytest.mark.parametrize("which", ["default_specs", "paper_specs"])
def test_samples_stay_inside_every_range(which, request):
    config, s = request.getfixturevalue(which)
    s.validate()
    eps = 1e-12
    radius = np.linalg.norm(s.board_pos, axis=1)
    angle = np.arctan2(s.board_pos[:, 1], s.board_pos[:, 0])
    assert np.all(
        (radius >= config.workspace_radius[0] - eps) & (radius <= config.workspace_radius[1] + eps)
    )
    assert np.all(
        (angle >= config.workspace_angle[0] - eps) & (angle <= config.workspace_angle[1] + eps)
    )
    assert np.all(
        (s.board_yaw >= config.board_yaw_range[0]) & (s.board_yaw <= config.board_yaw_range[1])
    )
    assert np.all(
        (s.friction >= config.friction_range[0]) & (s.friction <= config.friction_range[1])
    )
    lin, ang = config.linear_error, config.angular_error
    assert np.all(np.abs(s.loc_error) <= [lin, lin, ang])
    assert np.all(np.abs(s.grasp_error) <= [lin, ang, ang])
    assert np.all(np.abs(s.board_height) <= lin) and np.all(np.abs(s.board_tilt) <= ang)
    assert np.all(s.linear_range == lin) and np.all(s.angular_range == ang)
    np.testing.assert_allclose(s.hole_est_pos, s.board_pos + s.loc_error[:, :2], atol=1e-15)
    np.testing.assert_allclose(s.hole_est_yaw, s.board_yaw + s.loc_error[:, 2], atol=1e-15)
    assert set(np.unique(s.shape_id)) == {SHAPES.index(name) for name in config.shapes}
    assert np.all(np.isin(s.size, config.sizes))
    # Start: tip above the estimated hole, within the jitter, tool within the tilt of tool-down.
    height = s.tcp0_pos[:, 2] - HOLE_DEPTH
    assert np.all((height >= config.start_height[0]) & (height <= config.start_height[1]))
    offset = np.linalg.norm(s.tcp0_pos[:, :2] - s.hole_est_pos, axis=1)
    assert np.all(offset <= config.start_xy_jitter + eps)
    aligned = tool_down_rotation(s.hole_est_yaw)
    tilt = np.linalg.norm(rotvec_from_matrix(s.tcp0_rot @ np.swapaxes(aligned, 1, 2)), axis=1)
    assert np.all(tilt <= config.start_tilt_jitter + 1e-9)
    assert (
        offset.max() > 0.9 * config.start_xy_jitter and tilt.max() > 0.9 * config.start_tilt_jitter
    )


@pytest.mark.parametrize("which", ["default_specs", "paper_specs"])
def test_start_and_goal_configurations_are_exact_and_well_conditioned(which, request):
    config, s = request.getfixturevalue(which)
    pos_err, rot_err = kin.pose_error(s.q0, s.tcp0_pos, s.tcp0_rot, PEG_LENGTH)
    assert pos_err.max() < 1e-4 and pos_err.max() < 1e-9 and rot_err.max() < 1e-9
    assert np.all(np.abs(s.q0) <= np.pi)
    assert np.all(s.q0[:, 2] > 0) and np.all(s.q0[:, 4] < 0)  # elbow up, wrist down
    cond_start = kin.condition_number(s.q0, PEG_LENGTH, "full")
    q_goal, found = kin.ik_tcp_closest(*task.goal_pose(s.hole_est_pos, s.hole_est_yaw), PEG_LENGTH)
    assert found.all()
    cond_goal = kin.condition_number(q_goal, PEG_LENGTH, "full")
    print(
        f"condition numbers: start {cond_start.min():.2f}-{cond_start.max():.2f}, "
        f"goal {cond_goal.min():.2f}-{cond_goal.max():.2f} (bound {config.max_condition:g})"
    )
    assert cond_start.max() <= config.max_condition and cond_goal.max() <= config.max_condition


def test_same_seed_same_specs_other_seed_differs(default_specs):
    config, specs = default_specs
    again = sample_trials(config, 0, N)
    for name, value in specs.to_arrays().items():
        np.testing.assert_array_equal(value, again.to_arrays()[name], err_msg=name)
    gen = sample_trials(config, np.random.default_rng(0), N)
    np.testing.assert_array_equal(gen.q0, specs.q0)
    other = sample_trials(config, 1, 100)
    assert not np.allclose(other.board_pos, specs.board_pos[:100])
    assert not np.allclose(other.loc_error, specs.loc_error[:100])


def test_marginals_are_uniform(default_specs):
    config, s = default_specs
    lin, ang = config.linear_error, config.angular_error
    for values, half in (
        (s.loc_error[:, 0], lin),
        (s.board_tilt[:, 0], ang),  # the grasp tilt, on the board (the default model)
        (s.loc_error[:, 2], ang),
    ):
        assert stats.kstest(values, stats.uniform(-half, 2 * half).cdf).pvalue > 0.01
    assert stats.kstest(s.friction, stats.uniform(0.2, 0.7).cdf).pvalue > 0.01
    # Uniform in area: r^2 uniform between the squared radii.
    r0, r1 = config.workspace_radius
    r2 = np.sum(s.board_pos**2, axis=1)
    assert stats.kstest(r2, stats.uniform(r0**2, r1**2 - r0**2).cdf).pvalue > 0.01


def test_shape_and_size_combinations_are_uniform():
    config = TaskConfig(shapes=SHAPES, sizes=(0.025, 0.05, 0.06))
    s = sample_trials(config, 3, 9000)
    counts = np.array(
        [np.sum((s.shape_id == i) & (s.size == z)) for i in range(3) for z in config.sizes]
    )
    assert stats.chisquare(counts).pvalue > 0.01
    assert s.shape_id.dtype == np.int32


def test_rejection_keeps_only_well_conditioned_trials():
    """A tight bound with large errors, jitter and tilt rejects some start and some goal
    configurations; every accepted trial obeys the bound."""
    config = TaskConfig(
        max_condition=13.0, linear_error=0.05, start_xy_jitter=0.1, start_tilt_jitter=np.pi / 4
    )
    cand = task.candidate_trials(config, np.random.default_rng(0), 20_000)
    _, ok0 = task.feasible_configuration(cand["tcp0_pos"], cand["tcp0_rot"], config.max_condition)
    goal = task.goal_pose(cand["hole_est_pos"], cand["hole_est_yaw"])
    _, ok_goal = task.feasible_configuration(*goal, config.max_condition)
    rejected = 1.0 - np.mean(ok0 & ok_goal)
    print(
        f"rejection at max_condition 13: {rejected:.4f} "
        f"(start {1 - ok0.mean():.4f}, goal {1 - ok_goal.mean():.4f})"
    )
    assert 1 - ok0.mean() > 0.001 and 1 - ok_goal.mean() > 0.001
    s = sample_trials(config, 4, 3000)
    q_goal, _ = kin.ik_tcp_closest(*task.goal_pose(s.hole_est_pos, s.hole_est_yaw), PEG_LENGTH)
    assert kin.condition_number(s.q0, PEG_LENGTH).max() <= config.max_condition
    assert kin.condition_number(q_goal, PEG_LENGTH).max() <= config.max_condition


def test_endless_rejection_raises(monkeypatch):
    def nothing_fits(pos, rot, max_condition):
        return np.zeros(pos.shape[:-1] + (6,)), np.zeros(pos.shape[:-1], dtype=bool)

    monkeypatch.setattr(task, "feasible_configuration", nothing_fits)
    monkeypatch.setattr(task, "MAX_REJECTION_FACTOR", 5)
    with pytest.raises(ValueError, match="rejected") as info:
        sample_trials(TaskConfig(), 0, 10)
    assert "\n" not in str(info.value)


def test_bad_configs_fail_with_one_line():
    message = _one_line_error("unknown shape", shapes=("circle", "octagon"))
    assert message == (
        "unknown shape 'octagon': choose from circle, square, triangle, hexagon, rectangle"
    )
    _one_line_error("sizes must be positive", sizes=(0.05, 0.0))
    _one_line_error("sizes must be positive", sizes=(-0.01,))
    _one_line_error("linear_error", linear_error=-0.001)
    _one_line_error("angular_error", angular_error=-0.1)
    _one_line_error("friction_range", friction_range=(0.9, 0.2))
    _one_line_error("workspace_angle", workspace_angle=(0.5, -0.5))
    _one_line_error("start_height", start_height=(0.0, 0.05))
    _one_line_error("beyond the UR5e's tool-down reach", workspace_radius=(0.35, 1.0))
    _one_line_error("out of the UR5e's reach", workspace_radius=(0.05, 0.5))
    _one_line_error("near-singular", workspace_radius=(0.25, 0.65))
    _one_line_error("shapes is empty", shapes=())
    _one_line_error("max_condition", max_condition=0.5)
    _one_line_error("must be a number", linear_error="4 mm")
    with pytest.raises(ValueError, match="batch"):
        sample_trials(TaskConfig(), 0, -1)


def test_presets_and_replace():
    paper = TaskConfig.from_mm_deg(("circle", "square"), 50, 8, 12)
    assert paper.shapes == ("circle", "square") and paper.sizes == (0.05,)
    assert paper.linear_error == 0.008 and math.isclose(paper.angular_error, math.radians(12))
    changed = paper.replace(shapes=["triangle"], sizes=[0.025, 0.06])
    assert changed.shapes == ("triangle",) and changed.sizes == (0.025, 0.06)
    with pytest.raises(ValueError, match="unknown shape"):
        paper.replace(shapes=("octagon",))
    assert TaskConfig().time_limit_s == 60.0


def test_trial_spec_round_trip_take_concat(default_specs, tmp_path):
    _, specs = default_specs
    small = specs.take(np.arange(10))
    np.savez(tmp_path / "specs.npz", **small.to_arrays())
    with np.load(tmp_path / "specs.npz", allow_pickle=False) as data:
        loaded = TrialSpec.from_arrays(data).validate()
    for name, value in small.to_arrays().items():
        np.testing.assert_array_equal(getattr(loaded, name), value)
        assert getattr(loaded, name).dtype == value.dtype
    both = TrialSpec.concat([small.take(np.arange(4)), small.take(np.arange(4, 10))])
    assert len(both) == 10
    np.testing.assert_array_equal(both.q0, small.q0)
    assert len(small.take(small.shape_id == small.shape_id[0])) >= 1
    assert len(sample_trials(TaskConfig(), 0, 0).validate()) == 0


def test_validate_catches_bad_arrays(default_specs):
    _, specs = default_specs
    arrays = specs.take(np.arange(5)).to_arrays()

    def broken(**changes):
        spec = TrialSpec(**{**arrays, **changes})
        with pytest.raises(ValueError) as info:
            spec.validate()
        assert "\n" not in str(info.value)
        return str(info.value)

    assert "q0" in broken(q0=arrays["q0"][:, :5])
    assert "board_pos" in broken(board_pos=arrays["board_pos"][:4])
    nan = arrays["friction"].copy()
    nan[2] = np.nan
    assert "non-finite" in broken(friction=nan)
    assert "dtype" in broken(shape_id=arrays["shape_id"].astype(np.int64))
    assert "shape_id" in broken(shape_id=np.full(5, 7, dtype=np.int32))
    assert "rotation" in broken(tcp0_rot=2.0 * arrays["tcp0_rot"])
    with pytest.raises(ValueError, match="lack"):
        TrialSpec.from_arrays({"q0": arrays["q0"]})


def test_sensor_draws_are_per_trial_and_leave_the_rest_of_the_trial_alone():
    """The F/T sensor's key and randomization come from a child stream: the boards, errors and
    starts of a seed are the same with or without sensor randomization."""
    plain = sample_trials(TaskConfig(), 5, 400)
    assert np.all(plain.sensor_cutoff_scale == 1.0) and np.all(plain.sensor_noise_scale == 1.0)
    assert np.all(plain.sensor_delay_offset == 0) and plain.sensor_seed.dtype == np.uint32
    assert len(np.unique(plain.sensor_seed)) == 400
    config = TaskConfig(
        sensor_cutoff_scale=(0.5, 2.0), sensor_noise_scale=(0.25, 4.0), sensor_delay_offset=(-1, 2)
    )
    randomized = sample_trials(config, 5, 400)
    for name, value in plain.to_arrays().items():
        if not name.startswith("sensor_"):
            np.testing.assert_array_equal(getattr(randomized, name), value)
    np.testing.assert_array_equal(randomized.sensor_seed, plain.sensor_seed)
    cutoff, noise = randomized.sensor_cutoff_scale, randomized.sensor_noise_scale
    assert cutoff.min() >= 0.5 and cutoff.max() <= 2.0 and noise.min() >= 0.25
    # log-uniform: half the factors below the geometric middle
    assert abs((cutoff < 1.0).mean() - 0.5) < 0.1 and abs((noise < 1.0).mean() - 0.5) < 0.1
    assert set(randomized.sensor_delay_offset.tolist()) == {-1, 0, 1, 2}
    with pytest.raises(ValueError, match="sensor_delay_offset"):
        TaskConfig(sensor_delay_offset=(1, 0))
    with pytest.raises(ValueError, match="sensor_noise_scale"):
        TaskConfig(sensor_noise_scale=(0.0, 1.0))


def test_the_board_model_puts_the_grasp_errors_on_the_board():
    """Same seed, same draws: the flange model tilts the peg, the board model (the paper's, the
    default) raises and tilts the board by the same numbers; everything else is the same."""
    flange = sample_trials(TaskConfig(grasp_model="flange"), 4, 64)
    board = sample_trials(TaskConfig(), 4, 64)
    for name in ("board_pos", "board_yaw", "loc_error", "hole_est_pos", "tcp0_pos", "q0"):
        np.testing.assert_array_equal(getattr(board, name), getattr(flange, name), err_msg=name)
    np.testing.assert_array_equal(board.grasp_error, 0.0)
    np.testing.assert_array_equal(board.board_height, flange.grasp_error[:, 0])
    np.testing.assert_array_equal(board.board_tilt, flange.grasp_error[:, 1:])
    np.testing.assert_array_equal(flange.board_height, 0.0)
    origin, axis = task.hole_frame(flange)
    np.testing.assert_array_equal(origin[:, :2], flange.board_pos)
    np.testing.assert_array_equal(origin[:, 2], 0.0)
    np.testing.assert_array_equal(axis, np.broadcast_to([0.0, 0.0, 1.0], axis.shape))
    origin, axis = task.hole_frame(board)
    entrance = origin + HOLE_DEPTH * axis
    np.testing.assert_allclose(entrance[:, :2], board.board_pos, atol=1e-15)
    np.testing.assert_allclose(entrance[:, 2], HOLE_DEPTH + board.board_height, atol=1e-15)
    tilt = np.degrees(np.arccos(axis[:, 2]))
    assert 4.0 < tilt.max() <= math.degrees(math.hypot(*(2 * [math.radians(6.0)])))
    # Specs saved before the board model: a flat board.
    old = {k: v for k, v in flange.to_arrays().items() if not k.startswith("board_") or k in
           ("board_pos", "board_yaw")}  # fmt: skip
    again = TrialSpec.from_arrays(old)
    np.testing.assert_array_equal(again.board_tilt, 0.0)
    with pytest.raises(ValueError, match="unknown grasp model 'wrist'"):
        TaskConfig(grasp_model="wrist")


# --- the part's hole clearance ------------------------------------------------------------------


def test_hole_scale_forms_normalize_to_ranges_per_shape():
    assert TaskConfig().hole_scale == () and TaskConfig(hole_scale="paper").hole_scale == tuple(
        (s, constants.HOLE_SCALE[s], constants.HOLE_SCALE[s]) for s in SHAPES
    )
    tight = TaskConfig(hole_scale="tight")
    assert tight.hole_scale_range("circle") == (1.01, 1.01)
    assert tight.hole_scale_range("rectangle") == (1.02, 1.02)
    assert TaskConfig(hole_scale=1.05).hole_scale_range("triangle") == (1.05, 1.05)
    ranged = TaskConfig(hole_scale={"square": (1.02, 1.08)})
    assert ranged.hole_scale_range("square") == (1.02, 1.08)
    assert ranged.hole_scale_range("circle") == (1.03, 1.03)  # not named: the paper's fit
    assert TaskConfig(hole_scale=ranged.hole_scale) == ranged  # its own form reads back
    assert ranged.replace(shapes=("triangle",)).hole_scale_range("square") == (1.02, 1.08)


def test_bad_hole_scales_fail_with_one_line():
    _one_line_error("unknown hole fit 'loose'", hole_scale="loose")
    _one_line_error(r"hole_scale of the circle must lie in \[1.01, 1.25\]", hole_scale=1.005)
    _one_line_error("hole_scale of the square must lie", hole_scale={"square": (1.02, 1.5)})
    _one_line_error("names an unknown shape 'octagon'", hole_scale={"octagon": 1.05})
    _one_line_error("hole_scale must be finite with low <= high", hole_scale=(1.08, 1.02))


def test_fixed_clearances_leave_the_draws_alone_and_ranges_draw_their_values():
    """The paper's fits draw nothing: every array but hole_scale is what the same seed gave
    before the clearance was a parameter (the fingerprint's bit-identity); a range draws its
    evenly spaced values, both ends included, from a child stream that leaves the rest alone."""
    shapes = ("circle", "square", "hexagon", "rectangle")
    plain = sample_trials(TaskConfig(shapes=shapes), 6, 600)
    expected = np.array([constants.HOLE_SCALE[SHAPES[i]] for i in plain.shape_id])
    np.testing.assert_array_equal(plain.hole_scale, expected)
    ranged = sample_trials(
        TaskConfig(shapes=shapes, hole_scale={"square": (1.02, 1.08), "circle": (1.01, 1.03)}),
        6,
        600,
    )
    for name, value in plain.to_arrays().items():
        if name != "hole_scale":
            np.testing.assert_array_equal(getattr(ranged, name), value, err_msg=name)
    for shape, lo, hi in (("circle", 1.01, 1.03), ("square", 1.02, 1.08)):
        mine = ranged.hole_scale[ranged.shape_id == SHAPES.index(shape)]
        assert set(np.round(mine, 9)) == set(np.round(parts.hole_scale_values(lo, hi), 9))
    rest = ~np.isin(ranged.shape_id, [0, 1])
    np.testing.assert_array_equal(ranged.hole_scale[rest], plain.hole_scale[rest])


@pytest.mark.parametrize("shape", SHAPES)
def test_every_part_size_and_fit_samples_reachable_starts_above_its_hole(shape):
    config = TaskConfig(shapes=(shape,), sizes=(0.01, 0.05, 0.08), hole_scale={shape: (
        constants.TIGHT_HOLE_SCALE[shape], constants.HOLE_SCALE[shape])})  # fmt: skip
    specs = sample_trials(config, 2, 60).validate()
    assert set(np.round(specs.size, 9)) == {0.01, 0.05, 0.08}
    assert specs.hole_scale.min() >= constants.TIGHT_HOLE_SCALE[shape]
    assert specs.hole_scale.max() <= constants.HOLE_SCALE[shape]
    np.testing.assert_array_equal(specs.tcp0_pos[:, :2], specs.hole_est_pos)
    assert np.all(specs.tcp0_pos[:, 2] >= HOLE_DEPTH + config.start_height[0])


def test_specs_saved_before_the_clearance_have_the_paper_fits():
    specs = sample_trials(TaskConfig(shapes=("circle", "square", "triangle")), 3, 30)
    old = {k: v for k, v in specs.to_arrays().items() if k != "hole_scale"}
    again = TrialSpec.from_arrays(old).validate()
    np.testing.assert_array_equal(again.hole_scale, specs.hole_scale)
    np.testing.assert_array_equal(again.hole_scale, np.where(again.shape_id == 0, 1.03, 1.08))
    arrays = specs.to_arrays()
    with pytest.raises(ValueError, match="hole_scale must lie in"):
        TrialSpec(**{**arrays, "hole_scale": np.full(30, 1.0)}).validate()
