"""The contact search: how the skill frees a peg resting on the board top, turns it with a tilted
or turned hole, then pushes it through (an extension of the paper's skill).

The paper's skill moves the goal by dy = C F (Eq. 6) and drives the tcp towards it (Eq. 10); a
peg on the rim stays there, held by static friction until the lateral goal offset passes
mu N (1 / K_e + C_xx). Seven elements change that, each off by default (the defaults are the
paper's skill): the first six while the peg rests on something, the seventh once it is deep in
the hole; a budget ends the spiral. In the goal frame (z points down, into the hole):

    gate        g = clip((N - f_on) / (f_full - f_on), 0, 1),  N = -F_z  (the board pushing up)
    press       ydd_z <= a_p                         the axial command, and so the press
                                                     Lambda_zz a_p, bounded
    lateral     dy_xy <- (1 - g (1 - c_lat)) dy_xy   a stiffer tip while resting: C_xx c_lat
    centring    dy_xy <- dy_xy - k_cop g r,  r = (m_y, -m_x) / max(N, f_full)
    alignment   a_k = a_(k-1) + T k_a g (h m_x, h m_y, m_z),  |a_xy|, |a_z| <= a_max
                dy_rot <- dy_rot + a;  h = 1 once the tcp is d_a below the hole's estimated
                entrance
    spiral      dy_xy <- dy_xy + s(tau), s an Archimedean spiral about the hole's estimated
                axis (`spiral_path`), tau the time the peg has rested (`spiral_state`); while
                it runs (sigma): dy_z <- (1 + sigma (kappa - 1)) dy_z, c_lat -> c_s, k_cop ->
                k_cop (1 + sigma (k_s - 1))
    tilt        dy_rot <- dy_rot + sigma theta_s (s_y, -s_x, 0) / max(|s|, 1 mm): the goal turned
                about the axis normal to s, the face's edge away from the spiral's centre
                lowest (off by default: docs/design/parts_family.md, "Tilted while spiralling")
    insertion   dy_z <- (1 + b (kappa_i - 1)) dy_z,  b = clip((d - d_i) / d_r, 0, 1), d the
                tcp's depth below the hole's estimated entrance: a stiffer press once the peg
                is deep in the hole (no gate)
    budget      from tau = tau_b on: s(tau) -> s(tau_b), tau += dt whether resting or not, and
                dy_z <- dy_z + w (-(H + h_w) - dy_z),  w = clip((tau - tau_b) / T_w, 0, 1),
                H the estimated entrance over the goal: the peg withdrawn h_w above it

The centring is the paper's moment-to-shift coupling (C[0,4], C[1,3]) divided by the axial
force: a face pressed on the board top by N at its centre of pressure r (goal frame x, y from the
tcp) feels the moment m = r x (-N e_z) = N (-r_y, r_x, 0), so r = (m_y, -m_x) / N; the hole lies
on the side of the face that does not touch, and the goal moves by -k_cop r. It points the right
way within d* = sqrt(R_h^2 - R_p^2) of the hole's axis.

The alignment is an integral term beside the rotational compliance (C[3,3], C[4,4], C[5,5]): the
goal's rotation a follows the moment at the tcp while the peg is pressed, and keeps what it
found, so the moment falls to zero as a reaches the hole's pose (a tilted hole, the paper's grasp
error; a turned one, its yaw error). The tilt waits until the tcp is d_a below the estimated
entrance; the yaw starts with the press.

The spiral frees the pegs beyond d*, which the centring walks away: after t_w of resting, the
goal runs an Archimedean spiral (pitch p, under the capture width 2 d*, out to R and back in
between its outward turns, at speed v: `spiral_path`) about the estimated axis, with a lighter
press (kappa), the tip at the arm's own stiffness (c_s) and part of the centring's gain (k_s). It
stops once the tcp drops e below its resting height (a height that follows the tcp down over
T_h, so that a tilted board does not stop it): the peg has found the hole.

The insertion press pushes a peg through the hole once it is in: the axial compliance C_zz that
keeps the touchdown gentle also sets the press, about (g_z - y_z) / (1 / K_e + C_zz), falling as
the peg goes down; past d_i below the estimated entrance it blends to kappa_i C_zz over d_r.

The budget ends a search that has not found the hole, as the spiral searches of force-controlled
arms end at their largest radius or time: once the peg has rested tau_b the spiral stops where it
is, the resting time runs on with the clock, and over T_w the goal's axial offset blends to h_w
above the estimated entrance, lifting the peg clear of the board.

Why each element is there and how its constants were chosen, with the measurements:
docs/design/contact_search.md. Written over the array-API namespace of the inputs, batched over
leading dimensions, like the rest of `skill/`; it imports neither numpy nor jax.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import NamedTuple

from mjx_peg import file_versions
from mjx_peg.array_api import namespace_of
from mjx_peg.errors import UsageError
from mjx_peg.world.constants import GOAL_HEIGHT, HOLE_DEPTH

# m: the hole's estimated entrance over the goal, along the goal's z (the goal is the table top)
ENTRANCE_HEIGHT = HOLE_DEPTH - GOAL_HEIGHT


@dataclasses.dataclass(frozen=True)
class SkillConfig:
    """The skill's configuration: the contact search's constants (not learned); the defaults,
    every element off, are the paper's skill."""

    press_accel: float = 0.0  # m/s^2: a_p, the largest axial command into the hole; 0: unbounded
    lateral_scale: float = 1.0  # c_lat: lateral compliance while resting, times C's x, y rows
    centre_gain: float = 0.0  # k_cop: goal shift per metre of centre-of-pressure offset
    force_on: float = 10.0  # N: f_on, the axial force where the gate starts to open
    force_full: float = 20.0  # N: f_full, where it is fully open
    align_rate: float = 0.0  # k_a, rad/(N m s): how fast the goal's rotation follows the moment
    align_max: float = 0.35  # rad: a_max, the largest tilt and the largest yaw (20 deg)
    align_max_yaw: float = 0.0  # rad: the yaw's own bound, where it differs from a_max; 0: a_max
    align_depth: float = 0.02  # m: d_a, the tcp's depth below the estimated entrance
    # s: T_l, outside the hole (above d_a) the alignment's yaw relaxes to the estimate's over
    # T_l, so the moment of a face dragged over the board top does not hold it at its bound;
    # inf: never
    align_yaw_leak: float = math.inf
    spiral_speed: float = 0.0  # m/s: v, the spiral's speed round its turns; 0: no spiral
    spiral_pitch: float = 0.01  # m: p, the spiral's pitch, its radius's growth per turn
    spiral_radius: float = 0.025  # m: R, its largest radius (then it turns back in)
    spiral_wait: float = 0.3  # s: t_w, the resting time before it starts
    spiral_ramp: float = 0.5  # s: T_r, the time its phase sigma takes to switch on or off
    spiral_axial: float = 2.0  # kappa: axial compliance while spiralling, times C_zz
    # m/N: c_r. 0: kappa multiplies the compliance's own axial offset (C F)_z; > 0: while
    # spiralling the axial offset is kappa c_r F_z, a compliance of its own that the learned and
    # explored C does not move
    spiral_axial_ref: float = 0.0
    # rad: theta_s, the peg tilted while it spirals (times sigma), the edge of its face away from
    # the spiral's centre lowest, so that an edge finds a hole too tight for the flat face to
    # fall in; 0: upright
    spiral_tilt: float = 0.0
    # rad: psi_s, the amplitude of a yaw sweep while the peg spirals (times sigma): the goal
    # turned about its axis along a triangle wave of period T_psi; 0: none
    spiral_yaw: float = 0.0
    spiral_yaw_period: float = 2.0  # s: T_psi
    spiral_lateral: float = 0.0  # c_s: lateral compliance while spiralling, times C_xx, C_yy
    spiral_centre: float = 0.25  # the centring's gain while spiralling, times k_cop
    entry_depth: float = 0.0015  # m: e, the tcp's fall below its resting height that ends it
    entry_follow: float = 1.0  # s: T_h, how slowly the resting height follows the tcp down
    # s: T, the duration of the DMP's movement (`dmp.DMPConfig.duration`) for this skill; 0: the
    # trial's (`TrialConfig.movement`)
    movement_s: float = 0.0
    # c, the fraction of that movement at constant speed (`dmp.DMPConfig.cruise`); 0: the trial's
    movement_cruise: float = 0.0
    insert_axial: float = 1.0  # kappa_i: axial compliance deep in the hole, times C_zz; 1: off
    insert_depth: float = 0.035  # m: d_i, the tcp's depth below the estimated entrance where
    # the stiffer press starts
    insert_ramp: float = 0.015  # m: d_r, the further depth over which it blends in
    # s: tau_b, the resting time after which the search gives up and withdraws the peg; inf: never
    search_budget: float = math.inf
    withdraw_height: float = 0.02  # m: h_w, the withdrawn goal over the estimated entrance
    withdraw_s: float = 1.0  # s: T_w, the time the withdrawal takes to blend in
    # How the spiral's pitch, radius and speed follow the part (`for_part`): "absolute", as set
    # (tuned at the paper's 50 mm); "size", times S / 50 mm, the part's characteristic size over
    # the one they were set at
    part_scale: str = "absolute"
    # How the yaw sweep's amplitude follows the hole's estimate (`for_part`): "absolute", as set
    # (tuned at the paper's +-6 deg); "uncertainty", times max(1, r / 6 deg), r the estimate's
    # declared yaw uncertainty (+- rad), so that the sweep reaches a yaw error the alignment's
    # bound cannot
    yaw_scale: str = "absolute"

    def __post_init__(self):
        for name in ("press_accel", "centre_gain", "align_rate", "align_max", "align_max_yaw",
                     "align_depth", "spiral_speed", "spiral_wait", "spiral_centre", "entry_depth",
                     "movement_s", "insert_depth"):  # fmt: skip
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise UsageError(f"SkillConfig.{name} must be a number >= 0, got {value!r}")
        if not (math.isfinite(self.spiral_axial_ref) and 0 <= self.spiral_axial_ref <= 2e-3):
            raise UsageError(  # up to the largest C_zz: the compliance loop's stable range
                f"SkillConfig.spiral_axial_ref must be in [0, 2e-3] m/N, got "
                f"{self.spiral_axial_ref!r}"
            )
        if not (math.isfinite(self.spiral_tilt) and 0 <= self.spiral_tilt <= 0.15):
            raise UsageError(  # under 9 deg: the tilt the alignment's range takes back
                f"SkillConfig.spiral_tilt must be in [0, 0.15] rad, got {self.spiral_tilt!r}"
            )
        if not (math.isfinite(self.movement_cruise) and 0 <= self.movement_cruise < 1):
            raise UsageError(
                f"SkillConfig.movement_cruise must be in [0, 1), got {self.movement_cruise!r}"
            )
        if not (math.isfinite(self.spiral_yaw) and 0 <= self.spiral_yaw <= 0.3):
            raise UsageError(
                f"SkillConfig.spiral_yaw must be in [0, 0.3] rad, got {self.spiral_yaw!r}"
            )
        if not (math.isfinite(self.lateral_scale) and 0 <= self.lateral_scale <= 1):
            raise UsageError(
                f"SkillConfig.lateral_scale must be in [0, 1], got {self.lateral_scale!r}"
            )
        for name in ("spiral_pitch", "spiral_radius", "spiral_ramp", "spiral_axial",
                     "entry_follow", "insert_axial", "insert_ramp", "withdraw_s",
                     "spiral_yaw_period"):  # fmt: skip
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise UsageError(f"SkillConfig.{name} must be a number > 0, got {value!r}")
        for name in ("align_yaw_leak", "search_budget"):  # times that may be inf: never
            value = getattr(self, name)
            if not value > 0:
                raise UsageError(f"SkillConfig.{name} must be > 0 s (inf: never), got {value!r}")
        if not math.isfinite(self.withdraw_height):
            raise UsageError(
                f"SkillConfig.withdraw_height must be a number, got {self.withdraw_height!r}"
            )
        if not (math.isfinite(self.spiral_lateral) and 0 <= self.spiral_lateral <= 1):
            raise UsageError(
                f"SkillConfig.spiral_lateral must be in [0, 1], got {self.spiral_lateral!r}"
            )
        if self.part_scale not in PART_SCALES:
            raise UsageError(
                f"SkillConfig.part_scale must be one of {', '.join(PART_SCALES)}, got "
                f"{self.part_scale!r}"
            )
        if self.yaw_scale not in YAW_SCALES:
            raise UsageError(
                f"SkillConfig.yaw_scale must be one of {', '.join(YAW_SCALES)}, got "
                f"{self.yaw_scale!r}"
            )
        if not (0 <= self.force_on < self.force_full < math.inf):
            raise UsageError(
                "SkillConfig needs 0 <= force_on < force_full, got "
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
            or self.spiral_speed > 0
            or self.insert_axial != 1.0
        )

    def replace(self, **changes) -> SkillConfig:
        return dataclasses.replace(self, **changes)


# How the search's lengths follow the part (SkillConfig.part_scale), and the size S they were
# set at; the spiral's lengths and speed that follow it.
PART_SCALES = ("absolute", "size")
REFERENCE_SIZE = 0.05  # m: the paper's training size
SIZE_SCALED = ("spiral_pitch", "spiral_radius", "spiral_speed")
# How the yaw sweep follows the estimate's yaw uncertainty (SkillConfig.yaw_scale), and the
# uncertainty its amplitude was set at: the paper's +-6 deg
YAW_SCALES = ("absolute", "uncertainty")
REFERENCE_YAW_RANGE = math.radians(6.0)
TEXT_CONSTANTS = ("part_scale", "yaw_scale")  # SkillConfig's constants that are names

# The constants a policy may learn per trial (`SearchValues`), in SkillConfig's units.
LEARNED = ("spiral_pitch", "spiral_radius", "spiral_speed", "spiral_axial", "align_rate",
           "align_depth", "insert_depth", "insert_axial", "movement_s")  # fmt: skip


class SearchValues(NamedTuple):
    """The skill's learnable constants of each trial, (...,) arrays (SkillConfig's fields of
    the same names and units; movement_s is the movement's duration T itself, in s); a field
    None: the config's (`for_part` fills spiral_yaw alone where only the sweep is the trial's)."""

    spiral_pitch: object  # m: p
    spiral_radius: object  # m: R
    spiral_speed: object  # m/s: v
    spiral_axial: object  # kappa: the axial compliance while spiralling, times C_zz
    align_rate: object  # rad/(N m s): k_a
    align_depth: object  # m: d_a
    insert_depth: object  # m: d_i
    insert_axial: object  # kappa_i: the axial compliance deep in the hole, times C_zz
    movement_s: object  # s: T
    # rad: psi_s, the yaw sweep's amplitude of the trial (`for_part`, yaw_scale "uncertainty");
    # None: the config's. Not learned: a policy's vector holds the fields above
    spiral_yaw: object = None


def search_values(config: SkillConfig, movement_s: float, like) -> SearchValues:
    """The config's constants as SearchValues shaped like `like` (...,); movement_s: the
    movement's duration T where the config names none (`TrialConfig.movement`)."""
    xp = namespace_of(like)
    fields = {name: getattr(config, name) for name in LEARNED}
    fields["movement_s"] = config.movement_s or movement_s
    return SearchValues(**{k: xp.full(like.shape, v, dtype=like.dtype) for k, v in fields.items()})


def for_part(config: SkillConfig, values: SearchValues | None, movement_s: float, size,
             yaw_range=None):  # fmt: skip
    """The trial's search constants for its part of size S (...,) m and its estimate's yaw
    uncertainty r (...,) (+- rad; None: none declared): under part_scale "size" the spiral's
    pitch, radius and speed of `values` (None: the config's) times S / 50 mm; under yaw_scale
    "uncertainty" the yaw sweep's amplitude psi_s = spiral_yaw max(1, r / 6 deg); the rest as
    they are. Both "absolute" (or no r): `values` as given (None stays None: the config's)."""
    sized = config.part_scale != "absolute"
    swept = config.yaw_scale != "absolute" and config.spiral_yaw > 0 and yaw_range is not None
    if not (sized or swept):
        return values
    if sized:
        if values is None:
            values = search_values(config, movement_s, size)
        factor = size / REFERENCE_SIZE
        values = values._replace(**{n: getattr(values, n) * factor for n in SIZE_SCALED})
    if swept:  # the learnable fields left None stay the config's floats, as without the sweep
        xp = namespace_of(size)
        widen = xp.maximum(1.0, xp.asarray(yaw_range, dtype=size.dtype) / REFERENCE_YAW_RANGE)
        if values is None:
            values = SearchValues(*(None,) * len(LEARNED))
        values = values._replace(spiral_yaw=config.spiral_yaw * widen)
    return values


def _value(config: SkillConfig, values, name: str, column: bool = True):
    """A learnable constant: the config's float (no values, or this field None), or the
    trial's (..., 1) (column) or (...,)."""
    value = None if values is None else getattr(values, name)
    if value is None:
        return getattr(config, name)
    return value[..., None] if column else value


# The two skills a user chooses between (every CLI's --skill): the paper's compliant DMP as
# written, and ours, the shipped one: the contact search with the alignment and the spiral. Its
# ancestors live on as named ablations (experiments/ablations.py); files that name them read
# their constants from file_versions.FORMER_SKILLS.
SKILLS = {
    "paper": SkillConfig(),
    "spiral": SkillConfig(
        centre_gain=1.0,
        align_rate=1.0,
        align_max_yaw=0.1,
        align_depth=0.015,
        align_yaw_leak=0.5,
        spiral_speed=0.03,
        spiral_tilt=0.1,
        spiral_yaw=0.1,
        spiral_yaw_period=1.0,
        movement_s=1.3,
        movement_cruise=0.5,
        insert_axial=0.75,
        search_budget=45.0,
    ),
}


SKILL_DESCRIPTIONS = {
    "paper": "the paper's compliant DMP as written",
    "spiral": "ours, the shipped skill: the paper's with a contact search (skill/search.py): the "
    "goal moved away from the centre of pressure of a peg resting on the board top and turned "
    "with the moment it feels (its yaw bounded to 0.1 rad, and relaxing to the estimate over "
    "0.5 s until the peg is in the hole), a spiral about the estimated hole while the peg rests "
    "there (its press lighter, its tip stiffer, the peg tilted 0.1 rad, its edge away from the "
    "spiral's centre lowest, its yaw swept 0.1 rad each way once a second), a stiffer press deep "
    "in the hole, a 1.3 s movement that cruises half of it, and a search that has not found the "
    "hole in 45 s withdrawn",
}


class NamedSkill(NamedTuple):
    """A skill as a run records it: its name and its constants."""

    name: str
    config: SkillConfig

    def record(self) -> dict:
        """{"name", "constants"}: what a manifest records (`constants_record`)."""
        return {"name": self.name, "constants": constants_record(self.config)}


def skill_config(name: str) -> SkillConfig:
    """The SkillConfig of a named skill (`SKILLS`)."""
    if not isinstance(name, str) or name not in SKILLS:
        shown = repr(name)[:40]
        raise UsageError(f"unknown skill {shown}: choose one of {', '.join(SKILLS)}")
    return SKILLS[name]


def constants_set(name: str, config: SkillConfig) -> list[str]:
    """`NAME=VALUE` for each constant of `config` that differs from the named skill's own
    (`SKILLS`), as `--skill-constant` sets it; none for a skill of earlier versions."""
    if name not in SKILLS:
        return []
    changed = []
    for field in dataclasses.fields(config):
        value = getattr(config, field.name)
        if value != getattr(SKILLS[name], field.name):
            changed.append(f"{field.name}={value if isinstance(value, str) else f'{value:g}'}")
    return changed


def skill_description(name: str) -> str:
    """What the skill `name` is, in one phrase (`SKILL_DESCRIPTIONS`)."""
    if name in SKILL_DESCRIPTIONS:
        return SKILL_DESCRIPTIONS[name]
    return "a skill of earlier versions, its constants recorded (file_versions.FORMER_SKILLS)"


def constants_record(config: SkillConfig) -> dict:
    """Every constant of `config` by its field's name, as JSON records it: an infinite one (an
    unbounded `search_budget`) as null, JSON having no infinity."""
    values = ((f.name, getattr(config, f.name)) for f in dataclasses.fields(config))
    return {name: None if value == math.inf else value for name, value in values}


def constants_from_record(record) -> SkillConfig:
    """The SkillConfig of a record (`constants_record`); a field it lacks keeps its default,
    off (it predates the field). UsageError naming the field on anything else."""
    if not isinstance(record, Mapping):
        raise UsageError(f"skill constants must be an object of SkillConfig fields, got {record!r}")
    names = {f.name for f in dataclasses.fields(SkillConfig)}
    values = {}
    for name, value in record.items():
        if name not in names:
            raise UsageError(f"skill constants: {name!r} is not a SkillConfig field")
        if name in TEXT_CONSTANTS:
            if not isinstance(value, str):
                raise UsageError(f"skill constants: {name} must be a name, got {value!r}")
            values[name] = value
            continue
        if value is not None and (isinstance(value, bool) or not isinstance(value, int | float)):
            raise UsageError(f"skill constants: {name} must be a number, got {value!r}")
        values[name] = math.inf if value is None else float(value)
    return SkillConfig(**values)


def record_as_today(record) -> dict:
    """A record of constants (`constants_record`) as today's SkillConfig writes it: the fields
    added since it was written at their defaults, off (what a rerun's record compares with)."""
    return constants_record(constants_from_record(record))


def named_skill(name: str, constants=None) -> NamedSkill:
    """The skill `name` with its constants: `constants` (a SkillConfig or its record) where
    given, else the named skill's: one of `SKILLS` as it is today, or one that files of earlier
    versions name, as it was (`file_versions.FORMER_SKILLS`). UsageError on an unknown name or
    a bad constant."""
    if name not in SKILLS and name not in file_versions.FORMER_SKILLS:
        raise UsageError(f"unknown skill {name!r}: choose one of {', '.join(SKILLS)}")
    if constants is None:
        constants = SKILLS.get(name) or SkillConfig(**file_versions.FORMER_SKILLS[name])
    elif not isinstance(constants, SkillConfig):
        constants = constants_from_record(constants)
    return NamedSkill(name, constants)


def resting_gate(config: SkillConfig, wrench):
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


def searched_offset(config: SkillConfig, dy, wrench, rotation=None, spiral=None, height=None,
                    values: SearchValues | None = None):  # fmt: skip
    """(..., 6) the compliance's goal offset dy (..., 6) with the lateral, centring, alignment,
    spiral, tilt, yaw sweep and insertion elements applied, from the wrench (..., 6) the
    compliance sees, the goal's rotation (..., 3) the alignment found (`aligned_rotation`), the
    spiral's state (..., 3) (`spiral_state`) and the tcp's height (...,) over the goal along the
    goal's z (m; the insertion press's depth); None: none. values: the trial's learned constants
    (None: the config's)."""
    xp = namespace_of(dy, wrench)
    g = resting_gate(config, wrench)[..., None]
    c_lat, k_cop, axial = config.lateral_scale, config.centre_gain, dy[..., 2:3]
    spiralling = config.spiral_speed > 0 and spiral is not None
    if spiralling:  # sigma blends each element to its spiralling value
        sigma = spiral[..., 2:3]
        c_lat = c_lat + sigma * (config.spiral_lateral - c_lat)
        k_cop = k_cop * (1.0 + sigma * (config.spiral_centre - 1.0))
        kappa = _value(config, values, "spiral_axial")
        if config.spiral_axial_ref > 0:  # kappa c_r F_z, whatever C is
            axial = axial + sigma * (kappa * config.spiral_axial_ref * wrench[..., 2:3] - axial)
        else:
            axial = axial * (1.0 + sigma * (kappa - 1.0))
    if config.insert_axial != 1.0 and height is not None:
        depth = (ENTRANCE_HEIGHT - height)[..., None]  # below the hole's estimated entrance
        start = _value(config, values, "insert_depth")
        b = xp.clip((depth - start) / config.insert_ramp, 0.0, 1.0)
        axial = axial * (1.0 + b * (_value(config, values, "insert_axial") - 1.0))
    lateral = dy[..., :2] * (1.0 - g * (1.0 - c_lat))
    if config.centre_gain > 0:
        lateral = lateral - k_cop * g * centre_of_pressure(wrench, config.force_full)
    if spiralling:
        tau = spiral[..., 0]
        if math.isfinite(config.search_budget):  # the goal withdraws where the spiral stopped
            w = xp.clip((tau[..., None] - config.search_budget) / config.withdraw_s, 0.0, 1.0)
            axial = axial + w * (-(ENTRANCE_HEIGHT + config.withdraw_height) - axial)
            tau = xp.minimum(tau, config.search_budget)
        path = spiral_path(config, tau, values)
        lateral = lateral + path
    turn = dy[..., 3:]
    if config.align_rate > 0 and rotation is not None:
        turn = turn + rotation
    if spiralling and config.spiral_tilt > 0:  # the edge away from the spiral's centre lowest
        reach = xp.maximum(xp.linalg.vector_norm(path, axis=-1, keepdims=True), 1e-3)
        lean = (config.spiral_tilt * sigma / reach) * path
        turn = turn + xp.concat([lean[..., 1:], -lean[..., :1], xp.zeros_like(sigma)], axis=-1)
    if spiralling and config.spiral_yaw > 0:  # a triangle wave in [-psi_s, psi_s]
        phase = xp.remainder(tau / config.spiral_yaw_period + 0.25, 1.0)
        psi = _value(config, values, "spiral_yaw")  # the trial's where `for_part` set it
        sweep = psi * sigma * (1.0 - 4.0 * xp.abs(phase[..., None] - 0.5))
        turn = turn + xp.concat([xp.zeros_like(lateral), sweep], axis=-1)
    return xp.concat([lateral, axial, turn], axis=-1)


def _height_over_goal(tcp_pos, goal_pos, goal_rot):
    """(...,) m: the tcp's height over the goal, along the goal's z (which points down)."""
    xp = namespace_of(tcp_pos)
    return -xp.sum(goal_rot[..., :, 2] * (tcp_pos - goal_pos), axis=-1)


def aligned_rotation(config: SkillConfig, rotation, wrench, tcp_pos, goal_pos, goal_rot,
                     dt: float, values: SearchValues | None = None):  # fmt: skip
    """(..., 3) the goal's rotation a about goal x, y, z (rad) after one period of dt seconds:
    a + dt k_a g (h m_x, h m_y, m_z), its tilt (x, y) bounded to a_max and its yaw to a_max (or
    `align_max_yaw`, where set: docs/design/tilted_hole.md, "The yaw during the spiral"), the yaw
    less dt a_z / T_l while the tcp is not yet d_a in (`align_yaw_leak`, where set); from the
    rotation (..., 3) before, the wrench (..., 6) the compliance sees (its moment, and its axial
    force through the gate g), and the tcp's position (..., 3) against the goal's pose (..., 3),
    (..., 3, 3) (world frame; h: the tcp below the hole's estimated entrance by d_a); k_a and d_a
    the trial's `values` (None: the config's). The config's zero rate: the rotation as it is,
    nothing computed."""
    if config.align_rate == 0.0:
        return rotation
    xp = namespace_of(rotation, wrench)
    height = _height_over_goal(tcp_pos, goal_pos, goal_rot)
    g = resting_gate(config, wrench)[..., None]
    depth = _value(config, values, "align_depth", column=False)
    inside = (height < (ENTRANCE_HEIGHT - depth))[..., None]
    step = (dt * _value(config, values, "align_rate")) * g * wrench[..., 3:]
    tilt = rotation[..., :2] + xp.where(inside, step[..., :2], 0.0)
    norm = xp.linalg.vector_norm(tilt, axis=-1, keepdims=True)
    tilt = tilt * xp.minimum(1.0, config.align_max / xp.maximum(norm, 1e-12))
    yaw_max = config.align_max_yaw or config.align_max
    yaw = rotation[..., 2:] + step[..., 2:]
    if math.isfinite(config.align_yaw_leak):
        yaw = yaw - xp.where(inside, 0.0, (dt / config.align_yaw_leak) * rotation[..., 2:])
    yaw = xp.clip(yaw, -yaw_max, yaw_max)
    return xp.concat([tilt, yaw], axis=-1)


def spiral_state(config: SkillConfig, spiral, wrench, tcp_pos, goal_pos, goal_rot, dt: float):
    """(..., 3) the spiral's state (tau, h_r, sigma) after one period of dt seconds, from the
    state before (zeros at the start), the wrench (..., 6) the compliance sees (its axial force
    through the gate g) and the tcp's position (..., 3) against the goal's pose (..., 3),
    (..., 3, 3) (world frame), with h the tcp's height over the goal:

        h_r    the resting height: h at the first firm press (g > 1/2; 0 before: the goal lies
               80 mm below the hole's entrance, so a touching tcp is never at 0), then
               max(h, h_r + dt (h - h_r) / T_h): it follows the tcp up at once and down over
               T_h, so a peg sliding down a tilted board (~0.5 mm/s) keeps resting and a peg
               dropping into the hole (millimetres in a few tenths of a second) does not
        rest   the peg rests: pressed once, and h not e below h_r (checked before h_r moves)
        tau    += dt g while it rests: the resting time, which runs the spiral (`spiral_path`);
               it stops while the peg drops in, so the goal keeps the offset that found the hole;
               from tau_b (`search_budget`) on += dt: the search has given up (the withdrawal)
        sigma  the spiralling phase in [0, 1]: towards 1 at dt / T_r a period while it rests
               past t_w, else towards 0 (a ramp: the lighter press lifts the goal by
               (kappa - 1) C_zz N, ~40 mm, so a switch at once would lift the peg off)

    Zero speed: the state as it is, nothing computed."""
    if config.spiral_speed == 0.0:
        return spiral
    xp = namespace_of(spiral, wrench)
    height = _height_over_goal(tcp_pos, goal_pos, goal_rot)
    g = resting_gate(config, wrench)
    tau, h_r, sigma = spiral[..., 0], spiral[..., 1], spiral[..., 2]
    h_r = xp.where((h_r == 0.0) & (g > 0.5), height, h_r)
    touched = h_r != 0.0
    resting = touched & (height > h_r - config.entry_depth)
    h_r = xp.where(touched, xp.maximum(height, h_r + (dt / config.entry_follow) * (height - h_r)),
                   0.0)  # fmt: skip
    rate = xp.where(resting, g, 0.0)
    if math.isfinite(config.search_budget):  # given up: the resting time runs with the clock
        rate = xp.where(tau >= config.search_budget, 1.0, rate)
    tau = tau + dt * rate
    towards = xp.where(resting & (tau > config.spiral_wait), 1.0, -1.0)
    sigma = xp.clip(sigma + (dt / config.spiral_ramp) * towards, 0.0, 1.0)
    return xp.stack([tau, h_r, sigma], axis=-1)


def search_withdrawn(config: SkillConfig, spiral, hold: float):
    """(...,) bool: the search has given up and withdrawn the peg, `hold` s ago: the spiral's
    resting time tau (`spiral_state`, (..., 3)) is past tau_b + T_w + hold. The goal then stays
    h_w above the estimated entrance, the spiral stopped: the peg cannot go in any more. False
    without a spiral or a budget."""
    xp = namespace_of(spiral)
    if config.spiral_speed == 0.0 or not math.isfinite(config.search_budget):
        return xp.zeros(spiral.shape[:-1], dtype=bool)
    return spiral[..., 0] >= config.search_budget + config.withdraw_s + hold


def spiral_path(config: SkillConfig, tau, values: SearchValues | None = None):
    """(..., 2) the spiral's goal offset s (goal frame x, y; m) after a resting time tau (...,):
    an Archimedean spiral about the hole's estimated axis run round its turns at the speed v,
    out and back in, over and over. With t = tau - t_w (0 before) taken modulo the period
    2 t_R + t_b (t_R = pi R^2 / (p v), t_b = pi R / v):

        out     t < t_R:          r = sqrt(p v t / pi), phi = 2 pi r / p
        across  t < t_R + t_b:    r = R, half a turn on at v
        in      t < 2 t_R + t_b:  r = sqrt(p v u / pi), u = 2 t_R + t_b - t, turning back:
                                  phi = 2 pi R / p + pi - 2 pi (R - r) / p

    so r dphi/dt = v throughout (the radius changes at p v / (2 pi r) besides). The inward arm
    is the outward one turned by half a turn, r = p (phi - pi) / (2 pi), so at every angle it
    runs half the pitch from the outward turns: a peg that crossed the hole's capture width
    2 d* between two outward turns (d* = sqrt(R_h^2 - R_p^2), 3.1 mm at 25 mm, and a turned
    triangle's less) is swept again halfway between them, and the search stays over the board
    near the hole instead of circling R out. p, v and R: the trial's `values` (None: the
    config's)."""
    xp = namespace_of(tau)
    p, v, big_r = (_value(config, values, name, column=False)
                   for name in ("spiral_pitch", "spiral_speed", "spiral_radius"))  # fmt: skip
    t_out = math.pi * big_r**2 / (p * v)  # when r reaches R
    t_across = math.pi * big_r / v  # half a turn at R
    period = 2.0 * t_out + t_across
    t = xp.remainder(xp.maximum(tau - config.spiral_wait, 0.0), period)
    phi_out = 2.0 * math.pi * big_r / p  # the angle where the outward arm reaches R
    out = t < t_out
    across = (t >= t_out) & (t < t_out + t_across)
    r_out = xp.sqrt(p * v * xp.minimum(t, t_out) / math.pi)
    r_in = xp.sqrt(p * v * xp.clip(period - t, 0.0, t_out) / math.pi)
    r = xp.where(out, r_out, xp.where(across, big_r, r_in))
    phi = xp.where(out, 2.0 * math.pi * r_out / p,
                   xp.where(across, phi_out + v * (t - t_out) / big_r,
                            phi_out + math.pi - 2.0 * math.pi * (big_r - r_in) / p))  # fmt: skip
    return xp.stack([r * xp.cos(phi), r * xp.sin(phi)], axis=-1)


def bounded_press(config: SkillConfig, ydd):
    """(..., 6) the task acceleration command ydd (..., 6) with its axial part (goal z, into the
    hole) bounded by press_accel: the press the tcp can exert is then Lambda_zz press_accel."""
    xp = namespace_of(ydd)
    z = xp.minimum(ydd[..., 2:3], config.press_accel)
    return xp.concat([ydd[..., :2], z, ydd[..., 3:]], axis=-1)


__all__ = [
    "LEARNED",
    "SKILLS",
    "SKILL_DESCRIPTIONS",
    "SearchValues",
    "NamedSkill",
    "SkillConfig",
    "aligned_rotation",
    "bounded_press",
    "centre_of_pressure",
    "constants_from_record",
    "constants_record",
    "for_part",
    "named_skill",
    "record_as_today",
    "resting_gate",
    "search_values",
    "search_withdrawn",
    "searched_offset",
    "skill_config",
    "skill_description",
    "spiral_path",
    "spiral_state",
]
