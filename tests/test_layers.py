"""The layers (DESIGN.md): data flows one way; the robot side needs neither JAX nor MuJoCo."""

from __future__ import annotations

import ast
import pathlib
import subprocess
import sys

import pytest

PACKAGE = pathlib.Path(__file__).resolve().parents[1] / "mjx_peg"

# Rank of each layer: a module may import its own layer and lower ranks only. Rank 0 are the
# helpers every layer shares; `inputs` reads the files a command is given; `cli` is the shared
# command-line boundary and `outdir` where and how every command writes (rank 2 both, neither
# importing the other).
# The last rank's folders are peers that each consume the layers above; they may not import each
# other, except through the optional imports listed in PEER_IMPORTS.
RANKS = {
    "errors": 0,  # UsageError
    "file_versions": 0,  # reading files of earlier versions
    "cores": 0,
    "array_api": 0,  # the array namespace
    "signals": 0,  # how a program stops on SIGINT / SIGTERM
    "inputs": 1,  # reading a file someone gave us: checked before it is used
    "cli": 2,
    "outdir": 2,  # output directories: atomic writes, move aside, the --out lock
    "world": 3,
    "skill": 4,
    "engines": 5,
    "policy": 6,
    "learn": 7,
    "evaluation": 8,
    "robot": 8,
    "vision": 8,
}
PEER_IMPORTS: set[tuple[str, str]] = {
    ("vision", "robot"),  # the localizer returns robot.runtime.HoleEstimate
    ("vision", "evaluation"),  # vision-to-action trials are compared by evaluation.stats
}

# Modules the robot's computer runs: importable with neither JAX nor MuJoCo installed.
ROBOT_SIDE = ("skill", "policy", "robot")
NEEDS_MUJOCO = {
    "mjx_peg.robot.sim_arm",
    "mjx_peg.robot.sim_ur5e",
    "mjx_peg.robot.cli",
    "mjx_peg.robot.__main__",
}
BLOCKED = ("jax", "jaxlib", "mujoco", "flax", "brax", "optax", "orbax")


def _layer(module: str) -> str:
    parts = module.split(".")
    assert parts[0] == "mjx_peg", module
    return parts[1] if len(parts) > 1 else ""


def _modules(folder: str | None = None) -> list[str]:
    root = PACKAGE if folder is None else PACKAGE / folder
    names = []
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(PACKAGE.parent).with_suffix("")
        name = ".".join(rel.parts)
        names.append(name[: -len(".__init__")] if name.endswith(".__init__") else name)
    return names


def _imports(module: str) -> set[str]:
    """Every mjx_peg module `module` imports, at the top or inside a function."""
    rel = module.replace(".", "/")
    path = PACKAGE.parent / f"{rel}.py"
    if not path.exists():
        path = PACKAGE.parent / rel / "__init__.py"
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.startswith("mjx_peg")}
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("mjx_peg"):
            for alias in node.names:  # from mjx_peg.engines import lanes: the module lanes
                name = f"{node.module}.{alias.name}"
                if (PACKAGE.parent / f"{name.replace('.', '/')}.py").exists() or (
                    PACKAGE.parent / name.replace(".", "/") / "__init__.py"
                ).exists():
                    found.add(name)
                elif node.module != "mjx_peg":
                    found.add(node.module)
    return found


def import_cycles(modules=None, imports=_imports) -> list[list[str]]:
    """Every cycle of the import graph (imports inside functions count), each as its modules."""
    modules = modules or _modules()
    graph = {m: sorted(t for t in imports(m) if t in modules) for m in modules}
    cycles, state = [], dict.fromkeys(modules, 0)  # 0 new, 1 on the path, 2 done

    def visit(module, path):
        state[module] = 1
        for target in graph[module]:
            if state[target] == 1:
                cycles.append(path[path.index(target) :] + [target])
            elif state[target] == 0:
                visit(target, [*path, target])
        state[module] = 2

    for module in modules:
        if state[module] == 0:
            visit(module, [module])
    return cycles


def layer_violations(modules=None, imports=_imports) -> list[str]:
    """'importer -> imported' for every import that points up the layers or across peers."""
    bad = []
    for module in modules or _modules():
        mine = _layer(module)
        if mine not in RANKS:
            continue  # the package root
        for target in sorted(imports(module)):
            theirs = _layer(target)
            if theirs == mine or theirs not in RANKS:
                continue
            upward = RANKS[theirs] > RANKS[mine]
            across = RANKS[theirs] == RANKS[mine] and (mine, theirs) not in PEER_IMPORTS
            if upward or across:
                bad.append(f"{module} -> {target}")
    return bad


def is_command_line(module: str) -> bool:
    """A command-line module: the shared boundary `cli`, a `*cli` module or a `__main__`."""
    name = module.split(".")[-1]
    return name.endswith("cli") or name == "__main__"


def test_only_command_line_modules_import_the_cli_module():
    """The library writes through `outdir`; flag types and exit codes stay at the boundary."""
    library = [m for m in _modules() if not is_command_line(m)]
    assert "mjx_peg.outdir" in library and "mjx_peg.evaluation.runner" in library
    found = [m for m in library if "mjx_peg.cli" in _imports(m)]
    assert found == [], f"library modules that import mjx_peg.cli: {found}"


def test_every_module_belongs_to_a_layer():
    stray = [m for m in _modules() if _layer(m) not in RANKS and m != "mjx_peg"]
    assert not stray, f"modules outside the layer folders: {stray}"


def test_no_layer_imports_a_higher_one():
    assert layer_violations() == []


def test_no_module_imports_itself_through_others():
    assert import_cycles() == []


def test_the_cycle_check_catches_a_circle():
    fake = {
        "mjx_peg.engines.mujoco": {"mjx_peg.engines.processes"},
        "mjx_peg.engines.processes": {"mjx_peg.engines.mujoco"},
        "mjx_peg.engines.lanes": {"mjx_peg.engines.period"},
        "mjx_peg.engines.period": set(),
    }
    found = import_cycles(list(fake), imports=fake.__getitem__)
    assert found == [["mjx_peg.engines.mujoco", "mjx_peg.engines.processes",
                      "mjx_peg.engines.mujoco"]]  # fmt: skip


def test_the_layer_check_catches_a_wrong_import():
    """A skill module importing the engines, or the robot importing the evaluation, is caught."""
    fake = {
        "mjx_peg.skill.dmp": {"mjx_peg.engines.trial"},
        "mjx_peg.robot.runtime": {"mjx_peg.evaluation.runner", "mjx_peg.policy.export"},
        "mjx_peg.world.task": {"mjx_peg.world.kinematics"},
    }
    found = layer_violations(list(fake), imports=fake.__getitem__)
    assert found == [
        "mjx_peg.skill.dmp -> mjx_peg.engines.trial",
        "mjx_peg.robot.runtime -> mjx_peg.evaluation.runner",
    ]


_BLOCKER = f"""
import importlib, importlib.abc, sys

class Block(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in {BLOCKED!r}:
            raise ImportError(f"{{name}} is not installed on the robot's computer")

sys.meta_path.insert(0, Block())
"""


def _import_without_jax_and_mujoco(modules: list[str]) -> subprocess.CompletedProcess:
    code = _BLOCKER + "".join(f"import {m}\n" for m in modules)
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)


def test_the_robot_side_imports_without_jax_and_mujoco():
    modules = [m for f in ROBOT_SIDE for m in _modules(f) if m not in NEEDS_MUJOCO]
    assert "mjx_peg.robot.runtime" in modules and "mjx_peg.skill.control_step" in modules
    done = _import_without_jax_and_mujoco(modules)
    assert done.returncode == 0, done.stderr


@pytest.mark.parametrize("module", ["mjx_peg.world.scene", "mjx_peg.learn.ppo"])
def test_the_blocker_really_blocks(module):
    """The check above fails for a module that needs MuJoCo or JAX."""
    done = _import_without_jax_and_mujoco([module])
    assert done.returncode != 0 and "not installed on the robot's computer" in done.stderr


def test_plotting_the_learning_curve_needs_no_engine():
    done = subprocess.run(
        [sys.executable, "-c", "import sys, mjx_peg.learn.curves; "
         "print(sorted(m for m in sys.modules if m.split('.')[0] in "
         "('orbax', 'mujoco', 'jax', 'brax') or m.startswith('mjx_peg.engines')))"],
        capture_output=True, text=True,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"
