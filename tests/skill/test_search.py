"""The contact search (skill/search.py): the centre of pressure of a pressed face, the gate, the
goal offsets, the alignment's integral, the paper's skill untouched, NumPy and JAX alike, a peg
freed from the rim and pegs through tilted holes."""

import math

import numpy as np
import pytest

from mjx_peg.errors import UsageError
from mjx_peg.skill import search
from mjx_peg.skill.search import SkillConfig

RNG = np.random.default_rng(4)


def _pressed_face(r_xy, n):
    """(..., 6) goal-frame wrench of an axial force n (N) pushing the tip up (goal z is down)
    at the point r_xy (..., 2) of its face (m from the tcp): moment r x F about the tcp."""
    r = np.concatenate([r_xy, np.zeros((*r_xy.shape[:-1], 1))], axis=-1)
    f = np.zeros_like(r)
    f[..., 2] = -n
    return np.concatenate([f, np.cross(r, f)], axis=-1)


def test_centre_of_pressure_is_where_the_face_is_pressed():
    r = RNG.uniform(-0.025, 0.025, (50, 2))
    n = RNG.uniform(5.0, 80.0, 50)
    wrench = _pressed_face(r, n)
    np.testing.assert_allclose(search.centre_of_pressure(wrench, 1.0), r, atol=1e-12)
    # below min_force the division is by min_force: finite in free motion
    light = _pressed_face(r, np.full(50, 0.5))
    np.testing.assert_allclose(search.centre_of_pressure(light, 2.0), r * 0.25, atol=1e-12)


def test_gate_opens_with_the_axial_press_only():
    config = SkillConfig(force_on=10.0, force_full=20.0)
    n = np.array([-50.0, 0.0, 10.0, 15.0, 20.0, 80.0])  # negative: pulling the peg down
    wrench = _pressed_face(np.zeros((6, 2)), n)
    np.testing.assert_allclose(search.resting_gate(config, wrench), [0, 0, 0, 0.5, 1, 1])


def test_centring_moves_the_goal_away_from_the_pressed_side():
    config = SkillConfig(centre_gain=0.8)
    r = np.array([[0.012, -0.005], [0.012, -0.005]])
    wrench = _pressed_face(r, np.array([40.0, 3.0]))  # resting firmly; a touch under f_on
    dy = RNG.normal(0.0, 1e-3, (2, 6))
    out = search.searched_offset(config, dy, wrench)
    np.testing.assert_allclose(out[0, :2], dy[0, :2] - 0.8 * r[0], atol=1e-12)
    np.testing.assert_array_equal(out[1], dy[1])  # the gate is shut: the paper's offset
    np.testing.assert_array_equal(out[:, 2:], dy[:, 2:])


def test_lateral_scale_and_press_bound():
    config = SkillConfig(lateral_scale=0.25, press_accel=2.0)
    dy = RNG.normal(0.0, 1e-3, (1, 6))
    wrench = _pressed_face(np.zeros((1, 2)), np.array([30.0]))
    out = search.searched_offset(config, dy, wrench)
    np.testing.assert_allclose(out[0, :2], 0.25 * dy[0, :2])
    ydd = np.array([[1.0, -2.0, 9.0, 0.1, 0.2, 0.3], [1.0, -2.0, -9.0, 0.1, 0.2, 0.3]])
    bounded = search.bounded_press(config, ydd)
    np.testing.assert_array_equal(bounded[:, 2], [2.0, -9.0])  # into the hole only
    np.testing.assert_array_equal(np.delete(bounded, 2, axis=1), np.delete(ydd, 2, axis=1))


def _over_goal(height):
    """(tcp_pos, goal_pos, goal_rot): tcps `height` (...,) m over a tool-down goal at the origin
    (the goal's z points down)."""
    height = np.asarray(height, dtype=np.float64)
    tcp = np.zeros((*height.shape, 3))
    tcp[..., 2] = height
    rot = np.broadcast_to(np.diag([1.0, -1.0, -1.0]), (*height.shape, 3, 3))
    return tcp, np.zeros_like(tcp), rot


def test_alignment_integrates_the_moment_its_tilt_once_the_tcp_is_in_the_hole():
    config = SkillConfig(align_rate=2.0, align_max=0.3, align_depth=0.01)
    wrench = _pressed_face(np.array([[0.01, -0.02]] * 4), np.array([40.0, 40.0, 15.0, 5.0]))
    wrench[:, 5] = 0.4  # a yaw moment: the hole's edges turning the peg
    m = wrench[:, 3:]
    inside = 0.08 - 0.011  # 11 mm below the estimated entrance, 80 mm over the goal
    height = np.array([inside, 0.08 - 0.009, inside, inside])
    got = search.aligned_rotation(config, np.zeros((4, 3)), wrench, *_over_goal(height), 0.002)
    np.testing.assert_allclose(got[0], 0.002 * 2.0 * m[0], atol=1e-15)  # pressed, inside
    # 9 mm in: over the hole's edge, the tilt waits; the yaw does not
    np.testing.assert_allclose(got[1], [0.0, 0.0, 0.002 * 2.0 * 0.4], atol=1e-15)
    np.testing.assert_allclose(got[2], 0.5 * 0.002 * 2.0 * m[2], atol=1e-15)  # gate half open
    np.testing.assert_array_equal(got[3], 0.0)  # under f_on
    # it keeps what it found (an integral), the tilt and the yaw each within align_max
    start = np.array([[0.29, 0.0, 0.29]] * 4)
    far = search.aligned_rotation(config, start, wrench, *_over_goal(height), 1.0)
    assert np.linalg.norm(far[0, :2]) == pytest.approx(0.3) and far[0, 2] == pytest.approx(0.3)
    np.testing.assert_array_equal(far[3], start[3])
    # the offset: the rotation adds to the goal's rotation, nothing else
    dy = RNG.normal(0.0, 1e-3, (4, 6))
    off = search.searched_offset(config, dy, np.zeros((4, 6)), far)
    np.testing.assert_allclose(off[:, 3:], dy[:, 3:] + far, atol=1e-15)
    np.testing.assert_array_equal(off[:, :3], dy[:, :3])
    # zero rate: no rotation, whatever is carried
    off = search.searched_offset(SkillConfig(centre_gain=1.0), dy, np.zeros((4, 6)), far)
    np.testing.assert_array_equal(off, dy)
    assert search.aligned_rotation(SkillConfig(), far, wrench, *_over_goal(height), 1.0) is far


def test_alignment_bounds_its_yaw_apart_from_its_tilt_where_told():
    config = SkillConfig(align_rate=2.0, align_max=0.3, align_depth=0.01)
    wrench = _pressed_face(np.array([[0.01, -0.02]] * 2), np.array([40.0, 40.0]))
    wrench[:, 5] = [0.4, -0.4]  # the yaw moment of a face dragged off the tcp's axis
    height = np.full(2, 0.08 - 0.011)  # in the hole: the tilt integrates too
    start = np.array([[0.29, 0.0, 0.09], [0.0, -0.29, -0.09]])
    same = search.aligned_rotation(config, start, wrench, *_over_goal(height), 1.0)
    own = search.aligned_rotation(
        config.replace(align_max_yaw=0.1), start, wrench, *_over_goal(height), 1.0
    )
    np.testing.assert_allclose(same[:, 2], [0.3, -0.3])  # unset: the yaw runs to a_max
    np.testing.assert_allclose(own[:, 2], [0.1, -0.1])  # set: to its own bound
    np.testing.assert_array_equal(own[:, :2], same[:, :2])  # the tilt's bound is a_max's
    assert np.linalg.norm(own[0, :2]) == pytest.approx(0.3)
    with pytest.raises(UsageError, match="align_max_yaw"):
        SkillConfig(align_max_yaw=-0.1)


def test_alignment_yaw_relaxes_to_the_estimate_outside_the_hole_where_told():
    """With T_l set, a step above the alignment's depth moves the yaw by dt k_a g m_z - dt a_z /
    T_l (with no moment it decays by dt / T_l a period); in the hole (below d_a) it integrates
    as without; the tilt is never touched."""
    config = SkillConfig(align_rate=2.0, align_max=0.3, align_depth=0.01, align_yaw_leak=0.5)
    wrench = _pressed_face(np.array([[0.01, -0.02]] * 4), np.full(4, 40.0))
    wrench[:, 5] = [0.0, 0.2, 0.0, 0.2]
    height = 0.08 - np.array([0.0, 0.0, 0.011, 0.011])  # on the board top, then in the hole
    start = np.array([[0.02, 0.01, 0.08]] * 4)
    dt = 0.002
    got = search.aligned_rotation(config, start, wrench, *_over_goal(height), dt)
    plain = search.aligned_rotation(
        config.replace(align_yaw_leak=math.inf), start, wrench, *_over_goal(height), dt
    )
    leak = dt / 0.5 * 0.08
    np.testing.assert_allclose(got[:, 2], plain[:, 2] - np.array([leak, leak, 0.0, 0.0]),
                               rtol=1e-12)  # fmt: skip
    np.testing.assert_allclose(got[0, 2], 0.08 * (1.0 - dt / 0.5), rtol=1e-12)
    np.testing.assert_array_equal(got[:, :2], plain[:, :2])
    with pytest.raises(UsageError, match="align_yaw_leak"):
        SkillConfig(align_yaw_leak=0.0)


def test_spiral_path_runs_out_and_back_between_its_turns_at_its_speed_within_its_radius():
    p, v, big_r = 0.006, 0.01, 0.012
    config = SkillConfig(spiral_speed=v, spiral_pitch=p, spiral_radius=big_r, spiral_wait=1.0)
    t_out, t_across = math.pi * big_r**2 / (p * v), math.pi * big_r / v  # 7.5 s, 3.8 s
    period = 2 * t_out + t_across
    tau = np.arange(0.0, 1.0 + period + 1.0, 1e-3)
    s = search.spiral_path(config, tau)
    r = np.linalg.norm(s, axis=-1)
    t = tau - 1.0
    np.testing.assert_array_equal(s[t <= 0.0], 0.0)  # it waits t_w
    assert r.max() == pytest.approx(big_r) and np.all(r <= big_r + 1e-15)
    out, across = (t > 0) & (t < t_out), (t > t_out) & (t < t_out + t_across)
    back = (t > t_out + t_across) & (t < period)
    np.testing.assert_allclose(r[out], np.sqrt(p * v * t[out] / math.pi))
    np.testing.assert_allclose(r[across], big_r)
    np.testing.assert_allclose(r[back], np.sqrt(p * v * (period - t[back]) / math.pi), atol=1e-12)
    # the angle at r: 2 pi r / p out (one turn widens it by the pitch), and back in on the same
    # arm turned by half a turn, half the pitch from the outward turns at every angle
    moving = t > 0
    phi = np.unwrap(np.arctan2(s[moving, 1], s[moving, 0]))
    phi += 2 * math.pi * r[moving][0] / p - phi[0]
    np.testing.assert_allclose(phi[out[moving]], 2 * math.pi * r[out] / p, atol=1e-6)
    np.testing.assert_allclose(r[back], p * (phi[back[moving]] - math.pi) / (2 * math.pi),
                               atol=1e-6)  # fmt: skip
    # round its turns at v (the radius changes at p v / (2 pi r) besides), out, across and back
    arm = np.select([out, across, back], [1, 2, 3], 0) * (r > 0.001)  # away from the centre
    steady = (arm[1:] == arm[:-1]) & (arm[1:] > 0)  # both ends on one arm
    angle = np.unwrap(np.arctan2(s[:, 1], s[:, 0]))
    tangential = 0.5 * (r[1:] + r[:-1]) * np.abs(np.diff(angle)) / 1e-3
    np.testing.assert_allclose(tangential[steady], v, rtol=1e-3)
    # no jump where the arms meet, and over again after a period
    assert np.max(np.linalg.norm(np.diff(s, axis=0), axis=-1)) < 3e-4
    np.testing.assert_allclose(search.spiral_path(config, tau[moving] + period), s[moving],
                               atol=1e-9)  # fmt: skip


def test_spiral_state_runs_while_the_peg_rests_and_stops_once_it_drops_in():
    config = SkillConfig(spiral_speed=0.01, spiral_wait=0.5, spiral_ramp=0.25,
                          entry_depth=0.0015, entry_follow=1.0)  # fmt: skip
    dt = 0.002
    pressed = _pressed_face(np.zeros((2, 2)), np.array([30.0, 30.0]))
    light = _pressed_face(np.zeros((2, 2)), np.array([15.0, 15.0]))  # the gate half open
    state, history = np.zeros((2, 3)), []
    for k in range(1500):  # 3 s: 0.2 s in flight, resting, then from 2 s on (row 0) dropping in
        t = k * dt
        wrench = np.zeros((2, 6)) if t < 0.2 else (pressed if t < 1.0 or t >= 2.0 else light)
        # row 0: a flat board, then down the hole at 20 mm/s; row 1: down a tilted board at
        # 0.5 mm/s throughout
        height = np.array([0.081 - 0.02 * max(t - 2.0, 0.0), 0.081 - 0.0005 * t])
        state = search.spiral_state(config, state, wrench, *_over_goal(height), dt)
        history.append(state.copy())
    tau, h_r, sigma = np.moveaxis(np.array(history), -1, 0)  # (steps, rows) each
    np.testing.assert_array_equal(tau[:100], 0.0)  # in flight: no press, nothing runs
    assert h_r[100, 0] == pytest.approx(0.081)  # the touchdown
    assert tau[999, 0] == pytest.approx(0.8 + 0.5 * 1.0, abs=2 * dt)  # dt g: 1, then 1/2
    assert sigma[345, 0] == 0.0 and sigma[355, 0] > 0.0  # tau passes t_w at 0.7 s
    assert sigma[340 + 125, 0] < 1.0 and sigma[360 + 125, 0] == 1.0  # T_r to switch on
    # dropping in: tau stops once the tcp is e below h_r (~0.1 s), the offset kept; sigma off
    stop = 1000 + int(np.argmax(np.diff(tau[1000:, 0]) == 0.0))
    assert 1030 < stop < 1045 and np.all(tau[stop:, 0] == tau[stop, 0])  # 1.5 mm / 20 mm/s
    assert sigma[stop + 120, 0] > 0.0 and sigma[stop + 130, 0] == 0.0
    # down a tilted board it keeps resting: the resting height follows it, 0.5 mm behind
    np.testing.assert_allclose(np.diff(tau[1000:, 1]), dt)
    assert 0.0 < h_r[-1, 1] - (0.081 - 0.0005 * 1499 * dt) < 0.0006
    # zero speed: the state as it is
    assert search.spiral_state(SkillConfig(), state, pressed, *_over_goal(height), dt) is state


def test_spiral_offset_moves_the_goal_with_a_lighter_press_and_a_stiffer_tip():
    config = SkillConfig(centre_gain=1.0, spiral_speed=0.01, spiral_axial=2.0,
                          spiral_lateral=0.2, spiral_centre=0.5)  # fmt: skip
    r = np.array([[0.01, -0.004]] * 3)
    wrench = _pressed_face(r, np.full(3, 30.0))
    dy = RNG.normal(0.0, 1e-3, (3, 6))
    spiral = np.array([[4.0, 0.08, 1.0], [4.0, 0.08, 0.5], [0.2, 0.08, 0.0]])
    out = search.searched_offset(config, dy, wrench, None, spiral)
    s = search.spiral_path(config, spiral[:2, 0])
    assert np.linalg.norm(s[0]) > 0.005
    np.testing.assert_allclose(out[0, :2], 0.2 * dy[0, :2] - 0.5 * r[0] + s[0], atol=1e-15)
    np.testing.assert_allclose(out[1, :2], 0.6 * dy[1, :2] - 0.75 * r[1] + s[1], atol=1e-15)
    np.testing.assert_allclose(out[:2, 2], [2.0 * dy[0, 2], 1.5 * dy[1, 2]], atol=1e-15)
    # before t_w, sigma 0: the search's offset without the spiral
    np.testing.assert_array_equal(out[2], search.searched_offset(config, dy, wrench)[2])
    np.testing.assert_array_equal(out[:, 3:], dy[:, 3:])


def test_a_spiral_press_of_its_own_compliance_does_not_follow_c():
    """With c_r > 0 the spiral's axial offset blends to kappa c_r F_z: two compliances whose
    axial offsets differ tenfold press alike once the spiral is on (sigma 1), and as each one's
    own offset before it starts (sigma 0); c_r 0 is the former kappa (C F)_z."""
    config = SkillConfig(spiral_speed=0.01, spiral_axial=1.5, spiral_axial_ref=1e-3)
    wrench = np.zeros((3, 6))
    wrench[:, 2] = -20.0  # the board pushes the peg up with 20 N
    spiral = np.array([[4.0, 0.08, 1.0], [4.0, 0.08, 0.5], [0.2, 0.08, 0.0]])
    soft, stiff = np.zeros((3, 6)), np.zeros((3, 6))
    soft[:, 2], stiff[:, 2] = -0.02, -0.002  # (C F)_z, m
    a = search.searched_offset(config, soft, wrench, None, spiral)[:, 2]
    b = search.searched_offset(config, stiff, wrench, None, spiral)[:, 2]
    np.testing.assert_allclose([a[0], b[0]], [-0.03, -0.03], atol=1e-15)  # 1.5 x 1e-3 x -20
    np.testing.assert_allclose([a[1], b[1]], [-0.025, -0.016], atol=1e-15)  # halfway
    np.testing.assert_array_equal([a[2], b[2]], [-0.02, -0.002])
    former = search.searched_offset(config.replace(spiral_axial_ref=0.0), soft, wrench, None,
                                    spiral)[:, 2]  # fmt: skip
    np.testing.assert_allclose(former[:2], [-0.03, -0.025], atol=1e-15)


def test_a_tilt_while_spiralling_lowers_the_faces_edge_away_from_the_spirals_centre():
    """With theta_s the goal turns by sigma theta_s about the goal-frame axis normal to the
    spiral's offset s: the point of the face at s / |s| from the tcp moves down the goal's z
    (into the board), the one towards the centre up; position and press as without it."""
    tilted = SkillConfig(spiral_speed=0.01, spiral_wait=0.0, spiral_tilt=0.1)
    upright = tilted.replace(spiral_tilt=0.0)
    wrench = _pressed_face(np.zeros((3, 2)), np.full(3, 30.0))
    dy = RNG.normal(0.0, 1e-3, (3, 6))
    spiral = np.array([[4.0, 0.08, 1.0], [7.0, 0.08, 0.5], [4.0, 0.08, 0.0]])
    out = search.searched_offset(tilted, dy, wrench, None, spiral)
    before = search.searched_offset(upright, dy, wrench, None, spiral)
    np.testing.assert_array_equal(out[:, :3], before[:, :3])
    np.testing.assert_array_equal(out[:, 5], dy[:, 5])
    np.testing.assert_array_equal(out[2], before[2])  # sigma 0: upright
    turn = out[:2, 3:] - dy[:2, 3:]
    np.testing.assert_allclose(np.linalg.norm(turn, axis=-1), [0.1, 0.05], rtol=1e-12)
    s = search.spiral_path(tilted, spiral[:2, 0])
    assert np.all(np.linalg.norm(s, axis=-1) > 1e-3)
    outward = 0.02 * s / np.linalg.norm(s, axis=-1, keepdims=True)  # a point of the face
    drop = np.cross(turn, np.concatenate([outward, np.zeros((2, 1))], axis=-1))[:, 2]
    np.testing.assert_allclose(drop, [0.1 * 0.02, 0.05 * 0.02], rtol=1e-12)  # down: goal z


def test_a_yaw_sweep_while_spiralling_turns_the_goal_about_its_axis_alone():
    """With psi_s the goal's yaw runs a triangle wave of amplitude sigma psi_s and period T_psi
    in the resting time tau (0 at tau = 0, psi_s at T_psi / 4, 0 at T_psi / 2, -psi_s at
    3 T_psi / 4), stopped with tau at the budget; nothing else moves, and without it nothing."""
    swept = SkillConfig(spiral_speed=0.01, spiral_wait=0.0, spiral_yaw=0.1,
                        spiral_yaw_period=2.0, search_budget=8.0)  # fmt: skip
    still = swept.replace(spiral_yaw=0.0)
    n = 7
    wrench = _pressed_face(np.zeros((n, 2)), np.full(n, 30.0))
    dy = RNG.normal(0.0, 1e-3, (n, 6))
    tau = np.array([0.0, 0.5, 1.0, 1.5, 0.25, 0.5, 9.5])
    sigma = np.array([1.0, 1.0, 1.0, 1.0, 1.0, 0.5, 1.0])
    spiral = np.stack([tau, np.full(n, 0.08), sigma], axis=-1)
    out = search.searched_offset(swept, dy, wrench, None, spiral)
    before = search.searched_offset(still, dy, wrench, None, spiral)
    np.testing.assert_array_equal(out[:, :5], before[:, :5])
    # tau 9.5 is past the budget (8 s): the sweep stays where tau stopped, at 0
    np.testing.assert_allclose(out[:, 5] - before[:, 5],
                               [0.0, 0.1, 0.0, -0.1, 0.05, 0.05, 0.0], atol=1e-15)  # fmt: skip
    with pytest.raises(UsageError, match="spiral_yaw"):
        SkillConfig(spiral_yaw=0.5)
    with pytest.raises(UsageError, match="spiral_yaw_period"):
        SkillConfig(spiral_yaw_period=0.0)


def test_a_search_past_its_budget_stops_and_withdraws_the_peg():
    """Past tau_b of resting the resting time runs with the clock, pressed or not; the spiral
    stays where it stopped and over T_w the goal's axial offset blends to h_w above the hole's
    estimated entrance (80 mm over the goal); before tau_b nothing differs from no budget."""
    config = SkillConfig(spiral_speed=0.01, spiral_wait=0.5, search_budget=4.0, withdraw_s=0.5,
                          withdraw_height=0.02)  # fmt: skip
    endless = config.replace(search_budget=math.inf)
    dt, height = 0.002, np.array([0.081, 0.081])
    free = np.zeros((2, 6))
    before = np.array([[3.0, 0.081, 1.0], [4.0, 0.081, 1.0]])  # row 1 has spent its budget
    after = search.spiral_state(config, before, free, *_over_goal(height), dt)
    np.testing.assert_array_equal(after[:, 0], [3.0, 4.0 + dt])  # lifted: only row 1 runs
    np.testing.assert_array_equal(
        search.spiral_state(endless, before, free, *_over_goal(height), dt)[:, 0], [3.0, 4.0]
    )
    dy = RNG.normal(0.0, 1e-3, (4, 6))
    wrench = _pressed_face(np.zeros((4, 2)), np.full(4, 30.0))
    spiral = np.array([[3.0, 0.08, 1.0], [4.0, 0.08, 1.0], [4.25, 0.08, 1.0], [9.0, 0.08, 1.0]])
    out = search.searched_offset(config, dy, wrench, None, spiral)
    np.testing.assert_array_equal(out[0], search.searched_offset(endless, dy, wrench, None,
                                                                  spiral)[0])  # fmt: skip
    # pressed at 30 N the tip follows the goal (c_s = 0): the lateral offset is the spiral's,
    # stopped at tau_b
    stopped = search.spiral_path(config, np.array([3.0, 4.0, 4.0, 4.0]))
    np.testing.assert_allclose(out[:, :2], stopped, atol=1e-15)
    assert np.linalg.norm(stopped[1] - search.spiral_path(config, 9.0)) > 0.005
    lift = -(0.08 + 0.02)
    pressed = 2.0 * dy[:, 2]  # the spiral's lighter press (kappa = 2)
    np.testing.assert_allclose(out[:, 2], pressed + np.array([0.0, 0.0, 0.5, 1.0])
                               * (lift - pressed), atol=1e-15)  # fmt: skip
    np.testing.assert_array_equal(out[:, 3:], dy[:, 3:])


def test_insertion_press_stiffens_the_axial_compliance_deep_in_the_hole():
    """dy_z times 1 + b (kappa_i - 1), b rising from 0 at d_i below the estimated entrance (80 mm
    over the goal) to 1 at d_i + d_r; every other component, and the offset without a height,
    as they were; with no gate: the same whatever the wrench."""
    config = SkillConfig(insert_axial=0.4, insert_depth=0.03, insert_ramp=0.02)
    height = 0.08 - np.array([0.0, 0.03, 0.04, 0.05, 0.07])  # depths 0, 30, 40, 50, 70 mm
    dy = RNG.normal(0.0, 1e-3, (5, 6))
    wrench = RNG.normal(0.0, 5.0, (5, 6))
    out = search.searched_offset(config, dy, wrench, height=height)
    np.testing.assert_allclose(out[:, 2] / dy[:, 2], [1.0, 1.0, 0.7, 0.4, 0.4], rtol=1e-12)
    np.testing.assert_array_equal(out[:, [0, 1, 3, 4, 5]], dy[:, [0, 1, 3, 4, 5]])
    np.testing.assert_array_equal(search.searched_offset(config, dy, wrench), dy)
    free = search.searched_offset(config, dy, np.zeros_like(wrench), height=height)
    np.testing.assert_array_equal(free[:, 2], out[:, 2])


def test_the_paper_skill_is_the_default_and_changes_no_torque():
    from mjx_peg.engines.trial import TrialConfig, control_config

    assert list(search.SKILLS) == list(search.SKILL_DESCRIPTIONS) == ["paper", "spiral"]
    assert not search.skill_config("paper").active and not TrialConfig().search.active
    spiral = SkillConfig(
        centre_gain=1.0,
        align_rate=1.0,
        spiral_speed=0.03,
        movement_s=1.3,
        movement_cruise=0.5,
        insert_axial=0.75,
        align_depth=0.015,
        align_yaw_leak=0.5,
        search_budget=45.0,
        align_max_yaw=0.1,
        spiral_tilt=0.1,
        spiral_yaw=0.1,
        spiral_yaw_period=1.0,
    )
    assert search.skill_config("spiral") == spiral  # the other constants: SkillConfig's defaults
    assert control_config(TrialConfig()).search == search.skill_config("paper")


def test_a_skill_is_recorded_by_its_name_and_every_constant():
    """`constants_record` is every SkillConfig field in plain JSON (an unbounded budget as
    null) and reads back as it was; the names files of earlier versions use read as those
    skills were (`search`: the centring alone; `align`: with the alignment); a bad record is
    one UsageError naming the field."""
    import json

    for config in (*search.SKILLS.values(), SkillConfig(centre_gain=1.0, align_max_yaw=0.1)):
        record = search.constants_record(config)
        assert list(record) == list(SkillConfig.__dataclass_fields__)
        text = json.dumps(record, allow_nan=False)
        assert search.constants_from_record(json.loads(text)) == config
    assert search.constants_record(search.SKILLS["paper"])["search_budget"] is None
    assert search.named_skill("search").config == SkillConfig(centre_gain=1.0)
    assert search.named_skill("align").config == SkillConfig(centre_gain=1.0, align_rate=1.0)
    assert search.named_skill("spiral") == search.NamedSkill("spiral", search.SKILLS["spiral"])
    partial = search.named_skill("spiral", {"centre_gain": 2.0})  # recorded before the others
    assert partial.config == SkillConfig(centre_gain=2.0)
    for record, message in (({"wiggle": 1.0}, "'wiggle' is not a SkillConfig field"),
                            ({"centre_gain": "1"}, "centre_gain must be a number"),
                            ({"centre_gain": True}, "centre_gain must be a number"),
                            ({"centre_gain": -1.0}, "SkillConfig.centre_gain must be"),
                            ([1.0], "must be an object")):  # fmt: skip
        with pytest.raises(UsageError, match=message):
            search.named_skill("spiral", record)
    with pytest.raises(UsageError, match="unknown skill 'wiggle': choose one of paper, spiral"):
        search.named_skill("wiggle")


def test_a_skill_that_names_its_movement_runs_the_path_of_that_movement():
    """`SkillConfig.movement_s` and `movement_cruise` replace the DMP's movement duration T and
    cruise; the forcing fitted at them follows the cruising path of T (within 1 % of the travel),
    and the other skills keep the trial's own DMP (minimum jerk over 2 s)."""
    from mjx_peg.engines.trial import TrialConfig, fitted_basis
    from mjx_peg.skill import dmp

    assert TrialConfig().movement == TrialConfig().dmp
    assert TrialConfig(search=search.skill_config("paper")).movement == TrialConfig().dmp
    movement = TrialConfig(search=search.skill_config("spiral")).movement
    assert movement == dmp.DMPConfig(duration=1.3, cruise=0.5)
    y0, goal = np.array([0.0, 0.0, -0.15, 0.1, -0.05, 0.2]), np.zeros(6)
    k_y = np.full(6, movement.k_ref)
    weights = fitted_basis(movement).weights
    t, y, _ = dmp.rollout(y0, goal, k_y, movement, weights, duration=3.0, dt=2e-3)
    p, _, _ = dmp.cruise_profile(t, 1.3, 0.5)
    path = y0 + (goal - y0) * p[:, None]
    assert np.max(np.abs(y - path) / np.abs(goal - y0).max()) < 0.01
    slow = y0 + (goal - y0) * dmp.minimum_jerk(t, 2.0)[0][:, None]
    assert np.max(np.abs(y - slow) / np.abs(goal - y0).max()) > 0.1  # not the 2 s path


def test_numpy_and_jax_agree(x64):
    import jax
    import jax.numpy as jnp

    config = SkillConfig(centre_gain=1.0, lateral_scale=0.5, press_accel=3.0, align_rate=1.0,
                          spiral_speed=0.01, spiral_wait=0.0, insert_axial=0.5,
                          insert_depth=0.005, search_budget=10.0, spiral_tilt=0.05,
                          spiral_yaw=0.08, align_yaw_leak=0.7)  # fmt: skip
    wrench = _pressed_face(RNG.uniform(-0.02, 0.02, (8, 2)), RNG.uniform(0.0, 40.0, 8))
    wrench = wrench + RNG.normal(0.0, 0.5, wrench.shape)
    dy, ydd = RNG.normal(0.0, 1e-3, (8, 6)), RNG.normal(0.0, 5.0, (8, 6))
    tilt, height = RNG.normal(0.0, 0.2, (8, 3)), RNG.uniform(0.05, 0.09, 8)
    spiral = np.stack([RNG.uniform(0, 20, 8), RNG.uniform(0.07, 0.09, 8) * (RNG.random(8) < 0.7),
                       RNG.uniform(0, 1, 8)], axis=-1)  # fmt: skip

    def both(dy, wrench, ydd, tilt, spiral, goal):
        return (
            search.searched_offset(config, dy, wrench, tilt, spiral, goal[0][..., 2]),
            search.bounded_press(config, ydd),
            search.aligned_rotation(config, tilt, wrench, *goal, 0.002),
            search.spiral_state(config, spiral, wrench, *goal, 0.002),
        )

    goal = _over_goal(height)
    expected = both(dy, wrench, ydd, tilt, spiral, goal)
    got = jax.jit(both)(*(jnp.asarray(a) for a in (dy, wrench, ydd, tilt, spiral)),
                        tuple(jnp.asarray(a) for a in goal))  # fmt: skip
    for e, g in zip(expected, got, strict=True):
        np.testing.assert_allclose(np.asarray(g), e, rtol=1e-12, atol=1e-15)


def test_bad_config_and_unknown_skill_are_one_clear_error():
    with pytest.raises(UsageError, match="centre_gain"):
        SkillConfig(centre_gain=-1.0)
    with pytest.raises(UsageError, match="align_rate"):
        SkillConfig(align_rate=-0.5)
    with pytest.raises(UsageError, match="lateral_scale"):
        SkillConfig(lateral_scale=1.5)
    with pytest.raises(UsageError, match="force_on < force_full"):
        SkillConfig(force_on=5.0, force_full=5.0)
    with pytest.raises(UsageError, match="spiral_pitch"):
        SkillConfig(spiral_pitch=0.0)
    with pytest.raises(UsageError, match="spiral_lateral"):
        SkillConfig(spiral_lateral=-0.1)
    with pytest.raises(UsageError, match="movement_s"):
        SkillConfig(movement_s=-1.0)
    with pytest.raises(UsageError, match="movement_cruise"):
        SkillConfig(movement_cruise=1.0)
    with pytest.raises(UsageError, match="insert_axial"):
        SkillConfig(insert_axial=0.0)
    with pytest.raises(UsageError, match="insert_ramp"):
        SkillConfig(insert_ramp=-0.01)
    with pytest.raises(UsageError, match="search_budget"):
        SkillConfig(search_budget=0.0)
    with pytest.raises(UsageError, match="withdraw_s"):
        SkillConfig(withdraw_s=0.0)
    with pytest.raises(UsageError, match="spiral_tilt"):
        SkillConfig(spiral_tilt=0.2)
    with pytest.raises(UsageError, match="choose one of paper, spiral"):
        search.skill_config("wiggle")


CENTRING = SkillConfig(centre_gain=1.0)  # the contact search's centring alone
ALIGNMENT = CENTRING.replace(align_rate=1.0)  # the centring and the alignment


def _baseline_trials(shape, linear_error, angular_deg, seed, n, time_limit_s, skills):
    """{name: TrialResult} of the baseline's numbers on the same n trials of one 50 mm shape,
    for each skill {name: SkillConfig}."""
    from mjx_peg.engines import run_trials
    from mjx_peg.engines.trial import TrialConfig
    from mjx_peg.skill.baseline import baseline_params
    from mjx_peg.world.task import TaskConfig, sample_trials

    task = TaskConfig(shapes=(shape,), sizes=(0.05,), linear_error=linear_error,
                      angular_error=math.radians(angular_deg))  # fmt: skip
    specs = sample_trials(task, seed, n)
    return {
        name: run_trials(specs, baseline_params(), engine="mujoco", threads=1,
                         config=TrialConfig(time_limit_s=time_limit_s, search=skill))
        for name, skill in skills.items()
    }  # fmt: skip


def test_centring_frees_pegs_that_the_paper_skill_leaves_on_the_rim():
    """Localization error alone (6 mm, no tilt: the board flat, so the centre of pressure
    points away from the hole): the paper's skill leaves half of these square pegs on the
    rim after 8 s, the centring inserts all of them (measured: 6/12 and 12/12)."""
    results = _baseline_trials("square", 0.006, 0.0, seed=5, n=12, time_limit_s=8.0,
                               skills={"paper": SkillConfig(), "centring": CENTRING})  # fmt: skip
    assert results["paper"].success.sum() <= 8
    assert results["centring"].success.sum() >= 11
    assert not results["centring"].protective_stop.any()
    assert np.median(results["centring"].chatter) < 5.0


@pytest.mark.slow
def test_alignment_takes_pegs_through_tilted_holes():
    """Circles into holes tilted up to 12 deg (1 mm of localization error): the goal's
    orientation is the estimated hole's, so without the alignment the peg is held up to 12 deg
    off the hole's axis and creeps through it against the walls' friction; with the alignment
    nearly all insert (measured: 2/8 and 7/8 in 10 s; the eighth is tilted 16 deg)."""
    results = _baseline_trials("circle", 0.001, 12.0, seed=3, n=8, time_limit_s=10.0,
                               skills={"centring": CENTRING, "alignment": ALIGNMENT})  # fmt: skip
    assert results["centring"].success.sum() <= 3
    assert results["alignment"].success.sum() >= 7
    assert not results["alignment"].protective_stop.any()


@pytest.mark.slow
def test_spiral_inserts_pegs_that_the_alignment_leaves_on_the_rim(paper_38):
    """Eight of the 500 trials of experiments/contact.py (+-4 mm / +-6 deg, seed 1) that the
    `paper` policy shipped until 2026-12 (docs/design/data) leaves on the rim with the alignment
    alone (in 60 s; these are the eight the spiral inserted within 8 s there): the spiral inserts
    them in 10 s (measured: 0/8 and 8/8), with no protective stop."""
    from mjx_peg.engines import run_trials
    from mjx_peg.engines.trial import TrialConfig
    from mjx_peg.policy.export import load_policy
    from mjx_peg.world.task import TaskConfig, sample_trials

    task = TaskConfig(shapes=("circle", "square"), sizes=(0.05,), linear_error=0.004,
                      angular_error=math.radians(6.0))  # fmt: skip
    specs = sample_trials(task, 1, 500).take([116, 121, 128, 155, 161, 183, 195, 204])
    vectors = load_policy(paper_38).controller_vectors(specs)
    results = {
        name: run_trials(specs, vectors, engine="mujoco", threads=1,
                         config=TrialConfig(time_limit_s=10.0, search=skill))
        for name, skill in (("align", ALIGNMENT), ("spiral", search.skill_config("spiral")))
    }  # fmt: skip
    assert results["align"].success.sum() == 0
    assert results["spiral"].success.sum() >= 7
    assert not results["spiral"].protective_stop.any()


def test_a_trials_own_constants_equal_to_the_configs_give_the_configs_offsets_bit_for_bit():
    config = search.SKILLS["spiral"]
    n = 16
    wrench = _pressed_face(RNG.uniform(-0.02, 0.02, (n, 2)), RNG.uniform(0.0, 40.0, n))
    dy, tilt = RNG.normal(0.0, 1e-3, (n, 6)), RNG.normal(0.0, 0.2, (n, 3))
    height = RNG.uniform(0.0, 0.09, n)
    spiral = np.stack([RNG.uniform(0, 60, n), RNG.uniform(0.07, 0.09, n), RNG.uniform(0, 1, n)],
                      axis=-1)  # fmt: skip
    values = search.search_values(config, 2.0, height)
    assert values.movement_s[0] == config.movement_s and values.spiral_pitch.shape == (n,)
    goal = _over_goal(height)
    for own in (None, values):
        got = (search.searched_offset(config, dy, wrench, tilt, spiral, height, own),
               search.aligned_rotation(config, tilt, wrench, *goal, 0.002, own),
               search.spiral_path(config, spiral[:, 0], own))  # fmt: skip
        if own is None:
            expected = got
    for e, g in zip(expected, got, strict=True):
        np.testing.assert_array_equal(g, e)


def test_a_trials_own_spiral_runs_at_its_own_pitch_speed_and_radius():
    config = search.SKILLS["spiral"]
    tau = np.linspace(0.0, 200.0, 20001)
    for pitch, speed, radius in ((0.004, 0.01, 0.012), (0.02, 0.08, 0.045)):
        values = search.search_values(config, 2.0, tau)._replace(
            spiral_pitch=np.full_like(tau, pitch), spiral_speed=np.full_like(tau, speed),
            spiral_radius=np.full_like(tau, radius))  # fmt: skip
        s = search.spiral_path(config, tau, values)
        r = np.linalg.norm(s, axis=-1)
        assert r.max() == pytest.approx(radius, rel=1e-6)
        moving = tau > config.spiral_wait + 0.5
        v = np.linalg.norm(np.diff(s, axis=0), axis=-1) / np.diff(tau)
        # the tangential speed is v; the radius grows at p v / (2 pi r) on top
        assert np.median(v[moving[1:]]) == pytest.approx(speed, rel=0.02)
        # successive outward turns are a pitch apart
        out = (tau > config.spiral_wait) & (r < radius * 0.99)
        assert np.diff(np.sort(r[out & (np.abs(s[:, 1]) < 1e-4) & (s[:, 0] > 0)]))[-1] < pitch * 1.1


def test_the_spirals_lengths_follow_the_parts_size_where_told():
    absolute = search.SKILLS["spiral"]
    scaled = absolute.replace(part_scale="size")
    size = np.array([0.05, 0.025, 0.08])
    assert search.for_part(absolute, None, 2.0, size) is None  # the config's, as set
    values = search.for_part(scaled, None, 2.0, size)
    for name in search.SIZE_SCALED:
        np.testing.assert_allclose(getattr(values, name),
                                   getattr(absolute, name) * size / 0.05, rtol=1e-15)  # fmt: skip
    np.testing.assert_array_equal(values.align_depth, absolute.align_depth)  # the hole's depth
    at_50 = search.for_part(scaled, None, 2.0, size[:1])
    assert at_50.spiral_pitch[0] == absolute.spiral_pitch  # the paper's size: as set, exactly
    with pytest.raises(UsageError, match="part_scale"):
        absolute.replace(part_scale="shape")


def test_the_yaw_sweep_follows_the_declared_yaw_uncertainty_where_told():
    """yaw_scale "uncertainty": psi_s = spiral_yaw max(1, r / 6 deg) per trial, r the estimate's
    declared yaw uncertainty; up to 6 deg exactly spiral_yaw; only the sweep is the trial's (the
    learnable fields stay None: the config's); no r or "absolute": the config's, as set."""
    absolute = search.SKILLS["spiral"]
    swept = absolute.replace(yaw_scale="uncertainty")
    size = np.full(4, 0.05)
    r = np.radians([2.0, 6.0, 12.0, 15.0])
    assert search.for_part(absolute, None, 2.0, size, r) is None
    assert search.for_part(swept, None, 2.0, size) is None  # nothing declared
    values = search.for_part(swept, None, 2.0, size, r)
    np.testing.assert_allclose(values.spiral_yaw, [0.1, 0.1, 0.2, 0.25], rtol=1e-12)
    assert values.spiral_yaw[0] == values.spiral_yaw[1] == absolute.spiral_yaw  # exactly
    assert all(getattr(values, name) is None for name in search.LEARNED)
    both = search.for_part(swept.replace(part_scale="size"), None, 2.0, size / 2, r)
    np.testing.assert_allclose(both.spiral_pitch, absolute.spiral_pitch / 2, rtol=1e-15)
    np.testing.assert_array_equal(both.spiral_yaw, values.spiral_yaw)
    # the goal's yaw at the sweep's peak (tau = T_psi / 4) is each trial's psi_s
    n = len(r)
    wrench = _pressed_face(np.zeros((n, 2)), np.full(n, 30.0))
    dy = np.zeros((n, 6))
    spiral = np.stack([np.full(n, 0.25), np.full(n, 0.08), np.ones(n)], axis=-1)
    peak = search.searched_offset(swept, dy, wrench, None, spiral, values=values)
    flat = search.searched_offset(swept.replace(spiral_yaw=0.0), dy, wrench, None, spiral)
    np.testing.assert_allclose(peak[:, 5] - flat[:, 5], values.spiral_yaw, rtol=1e-12)
    np.testing.assert_array_equal(peak[:, :5], flat[:, :5])
    with pytest.raises(UsageError, match="yaw_scale"):
        absolute.replace(yaw_scale="size")


def test_the_yaw_sweep_of_each_trial_is_computed_alike_in_jax(x64):
    """`for_part` on JAX arrays inside jit (the MJX engine's slot, the compiled pass) gives the
    NumPy amplitudes."""
    import jax
    import jax.numpy as jnp

    swept = search.SKILLS["spiral"].replace(yaw_scale="uncertainty")
    r = np.radians([3.0, 15.0])
    jitted = jax.jit(lambda size, r: search.for_part(swept, None, 1.3, size, r).spiral_yaw)
    np.testing.assert_allclose(jitted(jnp.full(2, 0.05), jnp.asarray(r)),
                               search.for_part(swept, None, 1.3, np.full(2, 0.05), r).spiral_yaw,
                               rtol=1e-15)  # fmt: skip


def test_a_skills_record_reads_back_names_and_numbers_alike():
    config = search.SKILLS["spiral"].replace(part_scale="size")
    record = search.constants_record(config)
    assert record["part_scale"] == "size" and record["spiral_pitch"] == 0.01
    assert search.constants_from_record(record) == config
    with pytest.raises(UsageError, match="part_scale must be a name"):
        search.constants_from_record({**record, "part_scale": 1.0})
    with pytest.raises(UsageError, match="spiral_pitch must be a number"):
        search.constants_from_record({**record, "spiral_pitch": "ten"})
    # a record written before a constant existed reads as today's with that constant off
    older = {k: v for k, v in record.items() if k != "yaw_scale"}
    assert search.record_as_today(older) == record and record["yaw_scale"] == "absolute"
