"""The contact search: how the skill frees a peg resting on the board top and turns it with a
tilted or turned hole (an extension).

The paper's skill moves the goal by dy = C F (Eq. 6) and drives the tcp towards it (Eq. 10).
A peg that lands on the rim stays there: static friction holds its tip until the lateral
tracking force passes mu N, i.e. until a lateral goal offset s passes mu N (1 / K_e + C_xx)
(docs/rim_escape.md: 16-72 mm at the ~40 N press that C_zz and the goal's depth make). Four
elements, each off by default, change that while the peg rests on something. In the goal
frame (the tool's orientation at the goal: z points down, into the hole):

    gate        g = clip((N - f_on) / (f_full - f_on), 0, 1),  N = -F_z  (the board pushing up)
    press       ydd_z <= a_p                         the axial command, and so the press
                                                     Lambda_zz a_p, bounded
    lateral     dy_xy <- (1 - g (1 - c_lat)) dy_xy   a stiffer tip while resting: C_xx c_lat
    centring    dy_xy <- dy_xy - k_cop g r,  r = (m_y, -m_x) / max(N, f_full)
    alignment   a_k = a_(k-1) + T k_a g (h m_x, h m_y, m_z),  |a_xy|, |a_z| <= a_max
                dy_rot <- dy_rot + a;  h = 1 once the tcp is d_a below the hole's estimated
                entrance

The centring is the paper's moment-to-shift coupling (C[0,4], C[1,3]) divided by the axial
force: a face pressed on the board top by N at its centre of pressure r (goal frame x, y from
the tcp) feels the moment m = r x (-N e_z) = N (-r_y, r_x, 0), so r = (m_y, -m_x) / N; the hole
lies on the side of the face that does not touch, and the goal moves by -k_cop r. The bounded
press and the stiffer tip lower the friction threshold; measured, both cost more than they free
(docs/rim_escape.md), so `SKILLS["search"]` is the centring alone.

The alignment is an integral term beside the rotational compliance (C[3,3], C[4,4], C[5,5]):
the goal's rotation a follows the moment at the tcp while the peg is pressed, and keeps what it
found. The goal's orientation is the estimated hole's. A hole tilted by theta (the paper's grasp
error, up to 12 deg) holds the peg theta off its goal, and the compliance alone asks for a
moment theta / C_rr to do that: 3 N m at the baseline's 0.07 rad/(N m), which the hole's walls
give only through normal forces of ~75 N at 40 mm depth; the peg creeps through the hole at
~1 mm/s against their friction. A hole turned by the localization's yaw error (up to 12 deg as
well) keeps a square or a triangle out until the peg turns with it, which C[5,5] (at most
0.1 rad/(N m)) does only against 2 N m; the peg wedges on the hole's edge. With the integral the
moment falls to zero as a approaches the hole's pose. The tilt (a_x, a_y) waits until the tcp is
d_a (20 mm) below the hole's estimated entrance, 12 mm inside the hole at the paper's largest
height error (8 mm): nearer the entrance a peg that rests over the hole's edge feels a moment
that tilts it further into the hole, and the integral wedges it (on docs/tilted_hole.md's 500
trials, d_a = 10 mm lost 5 of the baseline's successes, 20 mm none). The yaw (a_z) starts with the
press: a polygon enters only once it is turned. Measured (docs/tilted_hole.md): on 60 trials
at +-2 mm / +-12 deg, 58.3 % -> 83.3 % (the tilt alone 71.7 %), the median time 7.6 s -> 3.8 s,
no peg left wedged of 14; on the 500 trials at +-4 mm / +-6 deg, 83.0 % -> 84.6 % and the time
p90 18.4 s -> 8.3 s. `SKILLS["align"]` is the centring and the alignment.

Written over the array-API namespace of the inputs, batched over leading dimensions, like the
rest of `skill/`; it imports neither numpy nor jax.
"""

from __future__ import annotations

import dataclasses
import math

from mjx_peg._xp import namespace_of
from mjx_peg.errors import UsageError
from mjx_peg.world.constants import GOAL_HEIGHT, HOLE_DEPTH


@dataclasses.dataclass(frozen=True)
class SearchConfig:
    """The contact search's constants (not learned); the defaults, every element off: the paper's
    skill."""

    press_accel: float = 0.0  # m/s^2: a_p, the largest axial command into the hole; 0: unbounded
    lateral_scale: float = 1.0  # c_lat: lateral compliance while resting, times C's x, y rows
    centre_gain: float = 0.0  # k_cop: goal shift per metre of centre-of-pressure offset
    force_on: float = 10.0  # N: f_on, the axial force where the gate starts to open
    force_full: float = 20.0  # N: f_full, where it is fully open
    align_rate: float = 0.0  # k_a, rad/(N m s): how fast the goal's rotation follows the moment
    align_max: float = 0.35  # rad: a_max, the largest tilt and the largest yaw (20 deg)
    align_depth: float = 0.02  # m: d_a, the tcp's depth below the estimated entrance

    def __post_init__(self):
        for name in ("press_accel", "centre_gain", "align_rate", "align_max", "align_depth"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise UsageError(f"SearchConfig.{name} must be a number >= 0, got {value!r}")
        if not (math.isfinite(self.lateral_scale) and 0 <= self.lateral_scale <= 1):
            raise UsageError(
                f"SearchConfig.lateral_scale must be in [0, 1], got {self.lateral_scale!r}"
            )
        if not (0 <= self.force_on < self.force_full < math.inf):
            raise UsageError(
                "SearchConfig needs 0 <= force_on < force_full, got "
                f"{self.force_on!r}, {self.force_full!r}"
            )

    @property
    def active(self) -> bool:
        """Whether any element is on (else the control step is the paper's, bit for bit)."""
        return (
            self.press_accel > 0
            or self.lateral_scale < 1
            or self.centre_gain > 0
            or self.align_rate > 0
        )

    def replace(self, **changes) -> SearchConfig:
        return dataclasses.replace(self, **changes)


# The named skills of the CLIs: the paper's literal one, and ours with the contact search.
SKILLS = {
    "paper": SearchConfig(),
    "search": SearchConfig(centre_gain=1.0),
    "align": SearchConfig(centre_gain=1.0, align_rate=1.0),
}


SKILL_DESCRIPTIONS = {
    "paper": "the paper's compliant DMP as written",
    "search": "with the contact search: the goal moved away from the centre of pressure of a peg "
    "resting on the board top, skill/search.py",
    "align": "the contact search, and the goal's rotation following the moment (an integral "
    "rotational compliance; its tilt once the peg is in the hole), skill/search.py",
}


def skill_search(name: str) -> SearchConfig:
    """The SearchConfig of a named skill (`SKILLS`)."""
    if name not in SKILLS:
        raise UsageError(f"unknown skill {name!r}: choose one of {', '.join(SKILLS)}")
    return SKILLS[name]


def resting_gate(config: SearchConfig, wrench):
    """(...,) g in [0, 1]: how firmly the peg rests on something, from the axial force
    N = -wrench[..., 2] (N; goal frame, z down: the board pushing the peg up is positive)."""
    xp = namespace_of(wrench)
    span = config.force_full - config.force_on
    return xp.clip((-wrench[..., 2] - config.force_on) / span, 0.0, 1.0)


def centre_of_pressure(wrench, min_force: float):
    """(..., 2) r = (m_y, -m_x) / max(N, min_force): where on the tip's face (goal-frame x, y
    from the tcp, m) an axial force N = -wrench[..., 2] with moment wrench[..., 3:5] acts."""
    xp = namespace_of(wrench)
    n = xp.maximum(-wrench[..., 2], min_force)
    return xp.stack([wrench[..., 4], -wrench[..., 3]], axis=-1) / n[..., None]


def searched_offset(config: SearchConfig, dy, wrench, rotation=None):
    """(..., 6) the compliance's goal offset dy (..., 6) with the lateral, centring and alignment
    elements applied, from the wrench (..., 6) the compliance sees and the goal's rotation
    (..., 3) the alignment found (`aligned_rotation`; None: none)."""
    xp = namespace_of(dy, wrench)
    g = resting_gate(config, wrench)[..., None]
    lateral = dy[..., :2] * (1.0 - g * (1.0 - config.lateral_scale))
    if config.centre_gain > 0:
        lateral = lateral - config.centre_gain * g * centre_of_pressure(wrench, config.force_full)
    rest = dy[..., 2:]
    if config.align_rate > 0 and rotation is not None:
        rest = xp.concat([dy[..., 2:3], dy[..., 3:] + rotation], axis=-1)
    return xp.concat([lateral, rest], axis=-1)


def aligned_rotation(config: SearchConfig, rotation, wrench, tcp_pos, goal_pos, goal_rot,
                     dt: float):  # fmt: skip
    """(..., 3) the goal's rotation a about goal x, y, z (rad) after one period of dt seconds:
    a + dt k_a g (h m_x, h m_y, m_z), its tilt (x, y) and its yaw each bounded to a_max; from the
    rotation (..., 3) before, the wrench (..., 6) the compliance sees (its moment, and its axial
    force through the gate g), and the tcp's position (..., 3) against the goal's pose (..., 3),
    (..., 3, 3) (world frame; h: the tcp below the hole's estimated entrance by d_a). Zero rate:
    the rotation as it is, nothing computed."""
    if config.align_rate == 0.0:
        return rotation
    xp = namespace_of(rotation, wrench)
    # the tcp's height over the goal, along the goal's z (which points down)
    height = -xp.sum(goal_rot[..., :, 2] * (tcp_pos - goal_pos), axis=-1)
    g = resting_gate(config, wrench)[..., None]
    inside = (height < (HOLE_DEPTH - GOAL_HEIGHT - config.align_depth))[..., None]  # entrance
    step = (dt * config.align_rate) * g * wrench[..., 3:]
    tilt = rotation[..., :2] + xp.where(inside, step[..., :2], 0.0)
    norm = xp.linalg.vector_norm(tilt, axis=-1, keepdims=True)
    tilt = tilt * xp.minimum(1.0, config.align_max / xp.maximum(norm, 1e-12))
    yaw = xp.clip(rotation[..., 2:] + step[..., 2:], -config.align_max, config.align_max)
    return xp.concat([tilt, yaw], axis=-1)


def bounded_press(config: SearchConfig, ydd):
    """(..., 6) the task acceleration command ydd (..., 6) with its axial part (goal z, into the
    hole) bounded by press_accel: the press the tcp can exert is then Lambda_zz press_accel."""
    xp = namespace_of(ydd)
    z = xp.minimum(ydd[..., 2:3], config.press_accel)
    return xp.concat([ydd[..., :2], z, ydd[..., 3:]], axis=-1)


__all__ = [
    "SKILLS",
    "SKILL_DESCRIPTIONS",
    "SearchConfig",
    "aligned_rotation",
    "bounded_press",
    "centre_of_pressure",
    "resting_gate",
    "searched_offset",
    "skill_search",
]
