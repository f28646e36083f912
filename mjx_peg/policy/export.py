"""The portable policy export: `policy.npz` + `manifest.json`, loaded with NumPy alone.

A run directory's policy is plain arrays (`policy.npz`, read with allow_pickle=False) and a JSON
manifest that says what they mean: schema version, observation layout (`observation.LAYOUTS`:
manifests without one are `names`), its feature names and normalization, layer
shapes, activation, the 38 parameter names, their physical ranges and the map from the network's
action to them (`skill/params.py`: "centred" on a recorded vector, or "sigmoid", which manifests
without a map used), the range of its training parts' features where recorded (a part outside it
is read with each feature held to that range, `observation.clip_part`; manifests without one
read every part as it is), the skill to run it with (its name and every constant: the skill its
published numbers used; by default the one it was trained with) and the config that made it.
`load_policy` checks all of it and raises `PolicyError` (one line) on anything missing,
truncated or inconsistent. No JAX is imported here: the real robot runs this.

    policy = load_policy("runs/quick")
    vectors = policy.controller_vectors(specs)   # (B, 38) [k_t, k_theta, C row-major]
    obs = policy.observe(shape_id, size, hole_scale, hole_est_pos, hole_est_yaw)  # its layout
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np

from mjx_peg import file_versions, inputs
from mjx_peg.errors import UsageError
from mjx_peg.outdir import write_json, write_npz
from mjx_peg.policy import network, observation, shipped
from mjx_peg.skill import params
from mjx_peg.skill.search import SKILLS, NamedSkill, named_skill
from mjx_peg.world.constants import SHAPES

SCHEMA = "mjx-peg-policy"
SCHEMA_VERSION = 1
POLICY_FILE = "policy.npz"
MANIFEST_FILE = "manifest.json"
ACTIVATION = "swish"


class PolicyError(UsageError):
    """A policy file is missing, truncated or inconsistent with its manifest."""


@dataclasses.dataclass(frozen=True)
class Policy:
    """A deterministic policy: observation -> action -> 38 physical controller numbers, and the
    contact search's 9 learned constants where it learned them (47)."""

    layers: tuple[tuple[np.ndarray, np.ndarray], ...]
    obs_mean: np.ndarray
    obs_std: np.ndarray
    manifest: dict
    centre: np.ndarray | None = None  # (38,) or (47,) the centred map's centre; None: sigmoid
    layout: str = "names"  # its observation layout (observation.LAYOUTS)
    # (2, k) the training parts' range of the part features (observation.part_range), which
    # `act` clips them to; None: the network reads every part as it is
    part_range: np.ndarray | None = None

    @property
    def skill(self) -> NamedSkill:
        """The skill to run it with unless told otherwise (`file_versions.manifest_skill`)."""
        return _run_skill(self.manifest)

    @property
    def trained_skill(self) -> NamedSkill:
        """The skill it was trained with ("paper" for runs made before skills had names)."""
        return trained_skill(self.manifest.get("config", {}))

    @property
    def shapes(self) -> tuple[str, ...]:
        """The shapes it was trained on (its manifest's config.shapes); () if unrecorded."""
        return tuple(self.manifest.get("config", {}).get("shapes", ()))

    @property
    def sizes_mm(self) -> tuple[float, ...]:
        """The sizes S (mm) it was trained on (config.size_mm); () if unrecorded."""
        return tuple(float(s) for s in self.manifest.get("config", {}).get("size_mm", ()))

    def act(self, obs) -> np.ndarray:
        """(B, 38) or (B, 47) unbounded action (the network's mean) for (B, n) observations,
        their part features clipped to `part_range` first where it is recorded."""
        obs = np.asarray(obs)
        width = len(observation.LAYOUTS[self.layout])
        if obs.shape[-1:] != (width,):
            raise UsageError(
                f"the policy reads {width} observation numbers (its {self.layout} layout), "
                f"got an array of shape {obs.shape}"
            )
        if self.part_range is not None:
            obs = observation.clip_part(obs, self.part_range[0], self.part_range[1])
        return network.mean_action(self.layers, self.obs_mean, self.obs_std, obs)

    def observe(self, shape_id, size, hole_scale, hole_est_pos, hole_est_yaw) -> np.ndarray:
        """(B, n) observations in this policy's layout (`observation.observe_part`) of (B,) parts
        (shape ids, sizes S in m, hole scales) and their estimated holes ((B, 2) x, y; (B,) yaw)."""
        return observation.observe_part(self.layout, np.asarray(shape_id), np.asarray(size),
                                        np.asarray(hole_scale), np.asarray(hole_est_pos),
                                        np.asarray(hole_est_yaw))  # fmt: skip

    def controller_vectors(self, specs) -> np.ndarray:
        """(B, 38) physical parameter vectors for the trials of a `TrialSpec`."""
        return self.vectors_for(observation.observe_specs(specs, self.layout))

    def vectors_for(self, obs) -> np.ndarray:
        """(B, 38) physical parameter vectors for (B, n) observations in this policy's layout
        (`observe`)."""
        vectors = network.controller_vector(self.act(obs), self.centre)
        return np.asarray(vectors, dtype=np.float64)


def _ranges_json(ranges: params.ParamRanges, centre) -> dict:
    ranges = {
        "k_t": list(ranges.k_t),
        "k_theta": list(ranges.k_theta),
        "compliance_bound": [list(row) for row in ranges.compliance_bound()],
        "search": {name: list(params.SEARCH_RANGES[name]) for name in params.LEARNED_NAMES[38:]},
    }
    if centre is None:
        return {
            **ranges,
            "map": "sigmoid",
            "compliance_diagonal": "C[i,i] = bound * sigmoid(a)",
            "compliance_off_diagonal": "C[i,j] = bound * tanh(a)",
            "stiffness": "k = exp(log lo + (log hi - log lo) * sigmoid(a))",
        }
    return {
        **ranges,
        "map": "centred",
        "centre": [float(v) for v in centre],
        "definition": "mjx_peg/skill/params.py controller_from_centred_action",
    }


def _map_centre(manifest: dict, where) -> np.ndarray | None:
    """The manifest's centred-map centre, or None for the sigmoid map (manifests written before
    the centred map have no "map" and used the sigmoid one)."""
    ranges = manifest["action"]["ranges"]
    if not isinstance(ranges, dict):
        raise PolicyError(f"{where}: action.ranges is not an object")
    kind = ranges.get("map", file_versions.MANIFEST_ACTION_MAP)
    if kind == "sigmoid":
        return None
    if kind != "centred":
        raise PolicyError(f"{where}: unknown action map {str(kind)[:40]!r}")
    try:
        return params.check_centre(ranges["centre"])
    except (ValueError, TypeError) as e:
        raise PolicyError(f"{where}: {e}") from None


def part_range_json(layout: str, part_range) -> dict:
    """The manifest's `observation.part_range` of a (2, k) range in `layout`."""
    low, high = np.asarray(part_range, np.float64)
    return {
        "features": list(observation.LAYOUTS[layout][observation.POSE_FEATURES :]),
        "low": [float(v) for v in low],
        "high": [float(v) for v in high],
        "use": "the training parts' range: part features are clipped to it before the network "
        "(mjx_peg/policy/observation.py clip_part)",
    }


def _part_range(record, layout: str, where) -> np.ndarray | None:
    """The (2, k) part range a manifest records for `layout`, None where it records none;
    PolicyError where it is malformed."""
    if record is None:
        return None
    k = len(observation.LAYOUTS[layout]) - observation.POSE_FEATURES
    try:
        low = np.asarray(record["low"], np.float64)
        high = np.asarray(record["high"], np.float64)
    except (KeyError, TypeError, ValueError):
        raise PolicyError(
            f"{where}: observation.part_range is not {{low: [...], high: [...]}}"
        ) from None
    if low.shape != (k,) or high.shape != (k,):
        raise PolicyError(f"{where}: observation.part_range needs {k} numbers in low and high "
                          f"(the {layout} layout's part features)")  # fmt: skip
    if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high)) and np.all(low <= high)):
        raise PolicyError(f"{where}: observation.part_range holds a non-finite or empty interval")
    return np.stack([low, high])


def _run_skill(manifest: dict) -> NamedSkill:
    record = file_versions.manifest_skill(manifest)
    return named_skill(record["name"], record["constants"])


def trained_skill(config: dict) -> NamedSkill:
    """The skill a training config (config.json) trained with, its constants included."""
    config = file_versions.train_config(config)
    return named_skill(config["skill"], config["skill_constants"])


def save_policy(
    run_dir,
    layers,
    obs_mean,
    obs_std,
    config: dict,
    extra: dict | None = None,
    centre=None,
    skill: NamedSkill | None = None,
    layout: str | None = None,
    part_range=None,
) -> Path:
    """Write `policy.npz` + `manifest.json` into run_dir, each atomically; the network outputs
    38 numbers (the controller) or 47 (and the contact search's constants). `skill`: the skill to
    run it with (default: the one `config` trained with); `layout`: its observation layout
    (default: the one `config` names, `TrainConfig.observation`); `part_range`: the (2, k)
    range of its training parts' features (`TrainConfig.part_range`), or None to record none."""
    size = int(np.shape(layers[-1][0])[1])
    if size not in (params.N_PARAMS, params.N_LEARNED):
        raise ValueError(f"a policy outputs {params.N_PARAMS} or {params.N_LEARNED} numbers")
    layout = observation.check_layout(layout or file_versions.train_config(config)["observation"])
    width = len(observation.LAYOUTS[layout])
    assert np.shape(layers[0][0])[0] == width == np.size(obs_mean) == np.size(obs_std), (
        f"a policy of the {layout} layout reads {width} numbers: its first layer and the "
        "observation statistics must match"
    )
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    arrays = {
        "obs_mean": np.asarray(obs_mean, np.float32),
        "obs_std": np.asarray(obs_std, np.float32),
    }
    for i, (kernel, bias) in enumerate(layers):
        arrays[f"layer{i}_kernel"] = np.asarray(kernel, np.float32)
        arrays[f"layer{i}_bias"] = np.asarray(bias, np.float32)
    manifest = {
        "schema": SCHEMA,
        "schema_version": SCHEMA_VERSION,
        "observation": {
            "layout": layout,
            "names": list(observation.LAYOUTS[layout]),
            "normalization": "(obs - obs_mean) / obs_std, arrays in policy.npz",
            "definition": "mjx_peg/policy/observation.py",
            **({} if part_range is None else {"part_range": part_range_json(layout, part_range)}),
        },
        "network": {
            "layers": [list(np.shape(k)) for k, _ in layers],
            "activation": ACTIVATION,
            "output": "mean action; deterministic policy (Brax PPO, normal distribution)",
        },
        "action": {
            "size": size,
            "param_names": list(params.LEARNED_NAMES[:size]),
            "units": list(params.LEARNED_UNITS[:size]),
            "ranges": _ranges_json(params.DEFAULT_RANGES, centre),
        },
        "skill": (skill or trained_skill(config)).record(),
        "config": config,
        **(extra or {}),
    }
    write_npz(run_dir / POLICY_FILE, arrays)
    write_json(run_dir / MANIFEST_FILE, manifest)
    return run_dir / POLICY_FILE


def policy_skill(policy) -> NamedSkill:
    """The skill `policy` runs unless told otherwise: the one its manifest names to run it with
    (`Policy.skill`), "paper" for the hand-tuned baseline (the string "baseline"). `policy`: a
    loaded Policy, "baseline", or what `load_policy` takes (PolicyError if that is bad)."""
    if isinstance(policy, Policy):
        return policy.skill
    if str(policy) == "baseline":
        return NamedSkill("paper", SKILLS["paper"])
    return load_policy(policy).skill


def choose_skill(name: str | None, policy, changes=()) -> NamedSkill:
    """The skill a command runs: `name` (a --skill, `SKILLS`, its constants as they are today)
    where given, else the policy's (`policy_skill`), with `changes` ((name, value) pairs of
    --skill-constant) to its constants (UsageError on a value the skill refuses)."""
    skill = policy_skill(policy) if name is None else named_skill(name)
    if not changes:
        return skill
    return NamedSkill(skill.name, skill.config.replace(**dict(changes)))


MAX_LAYERS, MAX_WIDTH = 16, 4096  # a policy network no larger than this is read


def _manifest_problem(manifest: dict) -> str | None:
    """What makes a manifest's structure unusable, or None: types and sizes of every field
    `load_policy` and its callers read."""
    network, obs, action = (manifest.get(k) for k in ("network", "observation", "action"))
    for name, part in (("network", network), ("observation", obs), ("action", action)):
        if not isinstance(part, dict):
            return f"{name} is not an object"
    layers = network.get("layers")
    if not isinstance(layers, list) or not 1 <= len(layers) <= MAX_LAYERS:
        return f"network.layers is not a list of 1 to {MAX_LAYERS} layer shapes"
    for shape in layers:
        if not (
            isinstance(shape, list)
            and len(shape) == 2
            and all(type(n) is int and 1 <= n <= MAX_WIDTH for n in shape)
        ):
            shown = str(shape)[:40]
            return f"network.layers holds {shown}, not [inputs, outputs] in 1..{MAX_WIDTH}"
    if not isinstance(action.get("ranges"), dict):
        return "action.ranges is not an object"
    config = manifest.get("config", {})
    if not isinstance(config, dict):
        return "config is not an object"
    skill = config.get("skill", "paper")
    if not isinstance(skill, str) or not (skill in SKILLS or skill in file_versions.FORMER_SKILLS):
        return f"config.skill {str(skill)[:40]} is not one of {', '.join(SKILLS)}"
    shapes, sizes = config.get("shapes"), config.get("size_mm")  # absent: not recorded
    if shapes is not None and not (
        isinstance(shapes, list) and shapes and all(s in SHAPES for s in map(str, shapes))
    ):
        return f"config.shapes is not a list of shapes of {', '.join(SHAPES)}"
    if sizes is not None and not (
        isinstance(sizes, list) and sizes and all(type(v) in (int, float) and 0 < v < 1e3
                                                  for v in sizes)
    ):  # fmt: skip
        return "config.size_mm is not a list of sizes in mm"
    if "trials" in manifest and not (type(manifest["trials"]) is int and manifest["trials"] >= 0):
        return "trials is not a count"
    if "finished" in manifest and not isinstance(manifest["finished"], bool):
        return "finished is not true or false"
    return None


def load_policy(path) -> Policy:
    """Load a policy from a run directory (or its policy.npz), or a shipped policy by name
    (`policy/shipped.py`: "paper" is policies/paper); PolicyError on any defect. Only the
    arrays the manifest names are read from policy.npz, each checked by its header first."""
    if not isinstance(path, str | os.PathLike):
        raise PolicyError(f"a policy is a path or a shipped policy's name, not {path!r:.40}")
    path = Path(path)
    if not path.exists() and str(path) in shipped.shipped_names():
        path = shipped.SHIPPED_DIR / str(path)
    run_dir = path.parent if path.name == POLICY_FILE else path
    npz_path, manifest_path = run_dir / POLICY_FILE, run_dir / MANIFEST_FILE
    if not run_dir.is_dir():
        raise PolicyError(f"{run_dir} is not a directory")
    for f in (npz_path, manifest_path):
        if not f.exists():
            raise PolicyError(f"{run_dir} holds no {f.name}: not a run directory with a policy")
    manifest = inputs.read_json(manifest_path, "a policy manifest", error=PolicyError)
    if not isinstance(manifest, dict) or manifest.get("schema") != SCHEMA:
        raise PolicyError(f"{manifest_path} is not an mjx-peg policy manifest")
    if manifest.get("schema_version") != SCHEMA_VERSION:
        raise PolicyError(
            f"{manifest_path} has schema version {str(manifest.get('schema_version'))[:20]}; "
            f"this mjx-peg reads version {SCHEMA_VERSION}"
        )
    why = _manifest_problem(manifest)
    if why:
        raise PolicyError(f"{manifest_path}: {why}")
    try:
        shapes = [tuple(s) for s in manifest["network"]["layers"]]
        names = manifest["observation"]["names"]
        layout = manifest["observation"].get("layout", file_versions.MANIFEST_OBSERVATION)
        activation = manifest["network"]["activation"]
        centre = _map_centre(manifest, manifest_path)
    except (KeyError, TypeError) as e:
        raise PolicyError(f"{manifest_path} lacks {e} (not a complete policy manifest)") from None
    try:
        _run_skill(manifest)
    except (UsageError, KeyError, TypeError) as e:
        raise PolicyError(f"{manifest_path}: its skill is not readable ({e})") from None
    if not isinstance(layout, str) or layout not in observation.LAYOUTS:
        raise PolicyError(f"{manifest_path}: unknown observation layout {str(layout)[:40]!r}")
    expected = observation.LAYOUTS[layout]
    if names != list(expected):
        raise PolicyError(
            f"{manifest_path}: observation.names is not the {layout} layout's "
            f"({', '.join(expected)})"
        )
    if activation != ACTIVATION:
        raise PolicyError(f"{manifest_path}: unsupported activation")
    part_range = _part_range(manifest["observation"].get("part_range"), layout, manifest_path)
    width = len(expected)
    for i, shape in enumerate(shapes):
        if shape[0] != width:
            before = "the one before" if i else f"the {layout} observation layout"
            raise PolicyError(
                f"{manifest_path}: layer {i} takes {shape[0]} inputs, {before} gives {width}"
            )
        width = shape[1]
    if width not in (params.N_PARAMS, params.N_LEARNED):
        raise PolicyError(
            f"{manifest_path}: the network outputs {width} numbers, not {params.N_PARAMS} or "
            f"{params.N_LEARNED}"
        )
    if centre is not None and centre.shape != (width,):
        raise PolicyError(f"{manifest_path}: the map's centre has {centre.size} numbers, the "
                          f"network outputs {width}")  # fmt: skip
    members = {
        "obs_mean": inputs.Member("f", (len(expected),)),
        "obs_std": inputs.Member("f", (len(expected),)),
    }
    for i, shape in enumerate(shapes):
        members[f"layer{i}_kernel"] = inputs.Member("f", shape)
        members[f"layer{i}_bias"] = inputs.Member("f", (shape[1],))
    arrays = inputs.read_npz(npz_path, members, error=PolicyError)
    layers = tuple(
        (arrays[f"layer{i}_kernel"], arrays[f"layer{i}_bias"]) for i in range(len(shapes))
    )
    obs_mean, obs_std = arrays["obs_mean"], arrays["obs_std"]
    if np.any(obs_std <= 0):
        raise PolicyError(f"{npz_path}: obs_std holds values <= 0")
    return Policy(layers, obs_mean, obs_std, manifest, centre, layout, part_range)
