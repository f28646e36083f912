"""A catalogue of hostile inputs against every command, on a fresh clone, each result classified.

    python experiments/catalogue.py --out /tmp/catalogue                 # every case
    python experiments/catalogue.py --out /tmp/catalogue --mode ctrl-c   # Ctrl-C at 0.1..2 s, 5x
    python experiments/catalogue.py --out /tmp/catalogue --only ray,kill # names containing either
    python experiments/catalogue.py --list                               # the cases, not run

It clones this checkout's HEAD into OUT/clone (`git clone`), makes shared fixtures there once (a
tiny evaluation, a tiny training run, a tiny vision split), and runs each case in its own
folder OUT/cases/NAME with PYTHONPATH=clone: a command line (stdin closed, a time limit), or a
scripted sequence (kills and resumes, two writers at once, a signal at an instant). Each result
is one of:

    ok            exit 0 where a success is expected (or allowed)
    one-line      refused: exit 1 or 2 (130 / 143 when stopped), one line on stderr naming the
                  program, no traceback
    traceback     a Python traceback, a fatal error or a crash (a signal we did not send)
    hang          still running at the time limit
    lost          a file lost or corrupted: an input changed, a result missing or different
                  from an uninterrupted run's, something written before the input was accepted
    wrong         the opposite of what the case expects (bad input accepted, good one refused)
    noisy         the right outcome with more than one line on stderr

Results go to OUT/results.jsonl as each case ends (a rerun skips the cases it holds) and the
table of counts per class of case to OUT/table.md. Classes: edge values of every numeric flag,
damaged files of every kind each command reads, kills and resumes, two writers on one --out,
signals, the UR5e CLI without a robot, Ray addresses, odd environments (encodings, JAX and
MuJoCo back-ends, a full disk), and the Python API.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import io
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from mjx_peg import signals

HERE = Path(__file__).resolve().parents[1]
PY = sys.executable
BIN = Path(sys.executable).parent
TIMEOUT_S = 240.0
CLASSES = ("ok", "one-line", "traceback", "hang", "lost", "wrong", "noisy")


# -- what a case is --------------------------------------------------------------------------


@dataclasses.dataclass
class Result:
    code: int | None  # None: hung
    out: str
    err: str
    wall_s: float
    note: str = ""  # what a check found (lost, wrong)


@dataclasses.dataclass
class Case:
    name: str
    group: str
    argv: list[str] | None = None  # a command line, run in the case folder
    expect: str = "error"  # "ok", "error", "stopped", "any"
    setup: Callable[[Path], None] | None = None  # makes the case's files (in its folder)
    check: Callable[[Path, Result], str | None] | None = None  # a lost or corrupted file
    env: dict = dataclasses.field(default_factory=dict)
    script: Callable[[Case, Path], Result] | None = None  # instead of argv: a sequence
    timeout: float = TIMEOUT_S
    prog: str = ""  # the program name its lines start with
    needs: tuple[str, ...] = ()  # the shared fixtures it reads (make_fixtures)


class Runner:
    """Runs commands of the clone with PYTHONPATH set; remembers the clone and the fixtures."""

    def __init__(self, out: Path):
        self.out = out
        self.clone = out / "clone"
        self.fixtures = out / "fixtures"

    def env(self, extra: dict | None = None) -> dict:
        env = {**os.environ, "PYTHONPATH": str(self.clone), "JAX_PLATFORMS": "cpu"}
        env.pop("PYTHONSTARTUP", None)
        for key, value in (extra or {}).items():
            if value is None:
                env.pop(key, None)
            else:
                env[key] = value
        return env

    def program(self, name: str) -> list[str]:
        if name in ("train.py", "eval.py"):
            return [PY, str(self.clone / name)]
        if name == "robot":
            return [PY, "-m", "mjx_peg.robot"]
        return [str(BIN / name)]

    def run(self, argv, cwd: Path, env=None, timeout=TIMEOUT_S, preexec=None) -> Result:
        start = time.monotonic()
        child = subprocess.Popen(
            argv, cwd=cwd, env=self.env(env), stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
            stderr=subprocess.PIPE, text=True, errors="replace", start_new_session=True,
            preexec_fn=preexec or _default_sigint,
        )  # fmt: skip
        try:
            out, err = child.communicate(timeout=timeout)
            code = child.returncode
        except subprocess.TimeoutExpired:
            os.killpg(child.pid, signal.SIGKILL)
            out, err = child.communicate()
            code = None
        return Result(code, out, err, time.monotonic() - start)


def _default_sigint():
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def classify(case: Case, r: Result) -> str:
    lines = [line for line in r.err.splitlines() if line.strip()]
    if r.code is None:
        return "hang"
    if r.code < 0 or re.search(r"Traceback \(most recent call last\)|Fatal Python error", r.err):
        return "traceback"
    if r.note.startswith("lost"):
        return "lost"
    if r.note.startswith("wrong"):
        return "wrong"
    if r.note.startswith("finished") and r.code == 0:
        return "ok"  # a signal case whose command ended before the signal was sent
    if r.code == 0:
        return "wrong" if case.expect in ("error", "stopped") else "ok"
    if case.expect == "ok" or (case.expect == "stopped" and r.code not in (130, 143)):
        return "wrong"
    ours = all(line.startswith(case.prog) for line in lines) if case.prog else True
    return "one-line" if len(lines) == 1 and ours else "noisy"


# -- files --------------------------------------------------------------------------------------


def tree_digest(path: Path) -> str:
    """A digest of every file (and link) under `path`: an input's before and after."""
    h = hashlib.sha256()
    if not path.exists() and not path.is_symlink():
        return "absent"
    items = [path] if not path.is_dir() else sorted(path.rglob("*"))
    for p in items:
        h.update(str(p.relative_to(path.parent)).encode())
        if p.is_symlink():
            h.update(os.readlink(p).encode())
        elif p.is_file():
            h.update(p.read_bytes())
    return h.hexdigest()


def npy(array=None, header: dict | None = None, data: bytes = b"") -> bytes:
    f = io.BytesIO()
    if header is None:
        np.lib.format.write_array(f, np.asarray(array), allow_pickle=True)
    else:
        np.lib.format.write_array_header_1_0(f, header)
        f.write(data)
    return f.getvalue()


def write_npz(path: Path, members: dict[str, bytes], compress: bool = False) -> None:
    mode = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
    with zipfile.ZipFile(path, "w", mode) as z:
        for name, blob in members.items():
            z.writestr(f"{name}.npy", blob)


def npz_members(path: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(path) as z:
        return {n[:-4]: z.read(n) for n in z.namelist()}


def edit_json(path: Path, edit) -> None:
    doc = json.loads(path.read_text())
    edit(doc)
    path.write_text(json.dumps(doc))


HUGE = {"descr": "<f8", "fortran_order": False, "shape": (2**40,)}
DEEP = "[" * 200_000 + "]" * 200_000


def replace_with(path: Path, kind: str) -> None:
    """Put something that is not a regular file where `path` was."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    elif path.exists() or path.is_symlink():
        path.unlink()
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "directory":
        path.mkdir()
    elif kind == "loop":
        path.symlink_to(path.name)
    elif kind == "dangling":
        path.symlink_to("nowhere-at-all")
    elif kind == "empty":
        path.write_bytes(b"")


# -- the damaged files --------------------------------------------------------------------------


def _m(edit):
    return lambda run: edit_json(run / "manifest.json", edit)


def _z(**members):
    def damage(run):
        blobs = npz_members(run / "policy.npz")
        blobs.update(members)
        write_npz(run / "policy.npz", blobs)

    return damage


def _config(**fields):
    return _m(lambda d: d["config"].update(fields))


POLICY_DAMAGE: dict[str, Callable[[Path], None]] = {
    "config-list": _m(lambda d: d.update(config=[1])),
    "skill-list": _config(skill=["spiral"]),
    "shapes-string": _config(shapes="circle"),
    "shapes-empty": _config(shapes=[]),
    "sizes-zero": _config(size_mm=[0]),
    "deep-manifest": lambda r: (r / "manifest.json").write_text(DEEP),
    "one-number-layer": _m(lambda d: d["network"].update(layers=[[8]])),
    "layers-unchained": _m(lambda d: d["network"].update(layers=[[8, 64], [32, 38]])),
    "seventeen-layers": _m(lambda d: d["network"].update(layers=[[8, 8]] * 17)),
    "width-5000": _m(lambda d: d["network"].update(layers=[[8, 5000], [5000, 38]])),
    "trials-text": _m(lambda d: d.update(trials="many")),
    "finished-text": _m(lambda d: d.update(finished="yes")),
    "schema-version-2": _m(lambda d: d.update(schema_version=2)),
    "activation-relu": _m(lambda d: d["network"].update(activation="relu")),
    "obs-names-reversed": _m(lambda d: d["observation"].update(
        names=d["observation"]["names"][::-1])),
    "ranges-list": _m(lambda d: d["action"].update(ranges=[1])),
    "centre-short": _m(lambda d: d["action"]["ranges"].update(centre=[1.0])),
    "layout-list": _m(lambda d: d["observation"].update(layout=[1])),
    "layout-unknown": _m(lambda d: d["observation"].update(layout="pixels")),
    "layout-geometry": _m(lambda d: d["observation"].update(layout="geometry")),
    "outputs-47": _m(lambda d: d["network"]["layers"][-1].__setitem__(1, 47)),
    "manifest-null": lambda r: (r / "manifest.json").write_text("null"),
    "manifest-empty": lambda r: replace_with(r / "manifest.json", "empty"),
    "manifest-fifo": lambda r: replace_with(r / "manifest.json", "fifo"),
    "manifest-directory": lambda r: replace_with(r / "manifest.json", "directory"),
    "manifest-loop": lambda r: replace_with(r / "manifest.json", "loop"),
    "manifest-dangling": lambda r: replace_with(r / "manifest.json", "dangling"),
    "manifest-latin1": lambda r: (r / "manifest.json").write_bytes(
        (r / "manifest.json").read_bytes().replace(b'"quick"', b'"qu\xefck"')),
    "obs-mean-text": _z(obs_mean=npy(np.array(["0"] * 8))),
    "obs-std-dates": _z(obs_std=npy(np.ones(8, "M8[D]"))),
    "obs-mean-object": _z(obs_mean=npy(np.array([object()] * 8, dtype=object))),
    "kernel-complex": _z(layer0_kernel=npy(np.ones((8, 64), complex))),
    "kernel-float128": _z(layer0_kernel=npy(np.ones((8, 64), np.longdouble))),
    "kernel-1d": _z(layer0_kernel=npy(np.ones(8 * 64, np.float32))),
    "member-8tib": _z(obs_mean=npy(header=HUGE)),
    "extra-member-8tib": _z(extra=npy(header=HUGE, data=b"\0" * 64)),
    "bias-nan": _z(layer1_bias=npy(np.full(64, np.nan, np.float32))),
    "bias-inf": _z(layer2_bias=npy(np.full(38, np.inf, np.float32))),
    "std-zero": _z(obs_std=npy(np.zeros(8, np.float32))),
    "npz-truncated": lambda r: (r / "policy.npz").write_bytes(
        (r / "policy.npz").read_bytes()[:900]),
    "npz-empty": lambda r: replace_with(r / "policy.npz", "empty"),
    "npz-directory": lambda r: replace_with(r / "policy.npz", "directory"),
    "npz-fifo": lambda r: replace_with(r / "policy.npz", "fifo"),
    "npz-not-zip": lambda r: (r / "policy.npz").write_text("policy"),
    "npz-member-missing": lambda r: write_npz(r / "policy.npz", {
        k: v for k, v in npz_members(r / "policy.npz").items() if k != "layer1_kernel"}),
    "npz-bomb": lambda r: write_npz(r / "policy.npz", {
        **npz_members(r / "policy.npz"),
        "obs_mean": npy(header={"descr": "<f4", "fortran_order": False, "shape": (8,)},
                        data=b"\0" * 50_000_000)}, compress=True),
}  # fmt: skip
POLICY_OK = ("extra-member-8tib",)  # damage that a policy is read past (never loaded)


def _policy_copy(runner: Runner, folder: Path, name: str = "quick") -> Path:
    run = folder / "policy"
    shutil.copytree(runner.clone / "policies" / name, run, symlinks=True)
    return run


def policy_commands(runner: Runner) -> dict[str, list[str]]:
    q = ["--no-progress"]
    return {
        "eval": [*runner.program("eval.py"), "--policy", "policy", "--grid", "custom",
                 "--linear-mm", "1", "--angular-deg", "1", "--trials", "2", "--time-limit",
                 "0.05", "--processes", "0", "--out", "new/out", *q],
        "train-init-from": [*runner.program("train.py"), "--preset", "transfer", "--init-from",
                            "policy", "--trials", "8", "--num-envs", "8", "--time-limit", "0.05",
                            "--processes", "0", "--out", "new/out", *q],
        "demo": [*runner.program("mjx-peg-demo"), "--policy", "policy", "--frames", "0",
                 "--time-limit", "0.05", "--out", "new/out"],
        "robot": [*runner.program("robot"), "--policy", "policy", "--trials", "1",
                  "--time-limit", "0.05", "--out", "new/out", *q],
        "robot-dry-run": [*runner.program("robot"), "--dry-run", "--policy", "policy", "--hole",
                          "450,-120,30", "--shape", "circle", "--out", "new/out"],
        "vision-act": [*runner.program("mjx-peg-vision"), "act", "--policy", "policy",
                       "--trials", "1", "--time-limit", "0.05", "--threads", "1", "--out",
                       "new/out", *q],
    }  # fmt: skip


def _unchanged(paths: list[str], *, nothing_new: bool = True):
    """A check: the inputs `paths` (relative to the case folder) are as before the command, and
    (`nothing_new`) no new/ folder was made by a refused command."""

    def check(folder: Path, r: Result) -> str | None:
        saved = json.loads((folder / ".digests.json").read_text())
        for p in paths:
            if tree_digest(folder / p) != saved[p]:
                return f"lost: {p} changed"
        if nothing_new and r.code not in (0, None) and (folder / "new").exists():
            return "lost: new/ was written before the input was refused"
        return None

    return check


def _remember(folder: Path, paths: list[str]) -> None:
    (folder / ".digests.json").write_text(json.dumps({p: tree_digest(folder / p) for p in paths}))


def damaged_policy_cases(runner: Runner) -> list[Case]:
    cases = []
    for command, argv in policy_commands(runner).items():
        for kind, damage in POLICY_DAMAGE.items():
            if command == "train-init-from" and kind in ("extra-member-8tib",):
                continue  # would train: the same read as eval's

            def setup(folder, damage=damage):
                damage(_policy_copy(runner, folder))
                _remember(folder, ["policy"])

            prog = {"robot": "python -m mjx_peg.robot", "robot-dry-run": "python -m mjx_peg.robot",
                    "eval": "eval.py", "train-init-from": "train.py", "demo": "mjx-peg-demo",
                    "vision-act": "mjx-peg-vision"}[command]  # fmt: skip
            cases.append(Case(
                f"damaged-policy/{command}/{kind}", "damaged files", argv,
                expect="ok" if kind in POLICY_OK else "error", setup=setup,
                check=_unchanged(["policy"], nothing_new=kind not in POLICY_OK),
                timeout=120 if "fifo" in kind else TIMEOUT_S, prog=prog,
            ))  # fmt: skip
    return cases


def _l(edit):
    return lambda m: edit_json(m / "model.json", edit)


MODEL_DAMAGE: dict[str, Callable[[Path], None]] = {
    "no-arch": _l(lambda d: d.pop("arch")),
    "arch-text": _l(lambda d: d["arch"]["detector"].update(convs=[["a", 2]])),
    "arch-huge": _l(lambda d: d["arch"]["regressor"].update(dense=[10**9])),
    "views-list": _l(lambda d: d.update(views=[1])),
    "views-fine-size-huge": _l(lambda d: d["views"].update(fine_size=10**9)),
    "refine-text": _l(lambda d: d.update(refine="x")),
    "workspace-list": _l(lambda d: d.update(workspace=[1])),
    "schema-other": _l(lambda d: d.update(schema="x")),
    "deep-json": lambda m: (m / "model.json").write_text(DEEP),
    "json-fifo": lambda m: replace_with(m / "model.json", "fifo"),
    "npz-truncated": lambda m: (m / "model.npz").write_bytes((m / "model.npz").read_bytes()[:5000]),
    "npz-kernel-shape": lambda m: write_npz(m / "model.npz", {
        **npz_members(m / "model.npz"), "regressor/out/kernel": npy(np.zeros((128, 11), "f4"))}),
    "npz-complex": lambda m: write_npz(m / "model.npz", {
        **npz_members(m / "model.npz"), "detector/head/bias": npy(np.zeros(3, np.complex64))}),
    "npz-missing-member": lambda m: write_npz(m / "model.npz", {
        k: v for k, v in npz_members(m / "model.npz").items() if k != "regressor/out/bias"}),
    "npz-8tib": lambda m: write_npz(m / "model.npz", {
        **npz_members(m / "model.npz"), "detector/head/bias": npy(header=HUGE)}),
    "npz-fifo": lambda m: replace_with(m / "model.npz", "fifo"),
}  # fmt: skip


def _label(runner: Runner):
    return runner.fixtures / "split"


LABEL_DAMAGE: dict[str, Callable[[Path], None]] = {
    "label-empty-list": lambda s: (s / "000000.json").write_text("[]"),
    "label-no-board": lambda s: edit_json(s / "000000.json", lambda d: d.pop("board")),
    "label-shape-class-7": lambda s: edit_json(s / "000000.json", lambda d: d.update(
        shape_class=7)),
    "label-hole-px-text": lambda s: edit_json(s / "000000.json", lambda d: d.update(
        hole_px=["a", "b"])),
    "label-calibration-int": lambda s: edit_json(s / "000000.json", lambda d: d.update(
        calibration=3)),
    "label-fifo": lambda s: replace_with(s / "000000.json", "fifo"),
    "label-deep": lambda s: (s / "000000.json").write_text(DEEP),
    "manifest-count-text": lambda s: edit_json(s / "manifest.json", lambda d: d["config"].update(
        count="x")),
    "manifest-fifo": lambda s: replace_with(s / "manifest.json", "fifo"),
    "png-text": lambda s: (s / "000000.png").write_text("not a png"),
    "png-missing": lambda s: (s / "000000.png").unlink(),
    "png-fifo": lambda s: replace_with(s / "000000.png", "fifo"),
}  # fmt: skip


def vision_cases(runner: Runner) -> list[Case]:
    """A damaged localizer, split, calibration or image, for each verb that reads it."""
    return [dataclasses.replace(c, needs=("split",)) for c in _vision_cases(runner)]


def _vision_cases(runner: Runner) -> list[Case]:
    cases = []
    vis = runner.program("mjx-peg-vision")
    model = runner.clone / "policies" / "localizer"
    for kind, damage in MODEL_DAMAGE.items():
        for command in ("localize", "evaluate", "act"):
            argv = {
                "localize": [*vis, "localize", "split/000000.png", "--camera", "camera.json",
                             "--model", "model"],
                "evaluate": [*vis, "evaluate", "--model", "model", "--data", "split", "--out",
                             "new/out", "--no-progress"],
                "act": [*vis, "act", "--model", "model", "--trials", "1", "--time-limit", "0.05",
                        "--threads", "1", "--out", "new/out", "--no-progress"],
            }[command]  # fmt: skip

            def setup(folder, damage=damage):
                shutil.copytree(model, folder / "model")
                shutil.copytree(_label(runner), folder / "split")
                camera = json.loads((folder / "split" / "000000.json").read_text())
                (folder / "camera.json").write_text(json.dumps(camera["calibration"]))
                damage(folder / "model")
                _remember(folder, ["model", "split"])

            cases.append(Case(f"damaged-localizer/{command}/{kind}", "damaged files", argv,
                              setup=setup, check=_unchanged(["model", "split"]),
                              prog="mjx-peg-vision"))  # fmt: skip
    for kind, damage in LABEL_DAMAGE.items():
        for command in ("evaluate", "train", "figures"):
            argv = {
                "evaluate": [*vis, "evaluate", "--data", "split", "--out", "new/out",
                             "--no-progress"],
                "train": [*vis, "train", "--data", "split", "--detector-steps", "1",
                          "--regressor-steps", "1", "--out", "new/out", "--no-progress"],
                "figures": [*vis, "figures", "--data", "split", "--out", "new/out"],
            }[command]  # fmt: skip

            def setup(folder, damage=damage):
                shutil.copytree(_label(runner), folder / "split")
                damage(folder / "split")
                _remember(folder, ["split"])

            late = kind.startswith("png")  # an image is read while the command works
            cases.append(Case(f"damaged-split/{command}/{kind}", "damaged files", argv,
                              setup=setup, check=_unchanged(["split"], nothing_new=not late),
                              prog="mjx-peg-vision"))  # fmt: skip
    camera_damage = {
        "fifo": lambda p: replace_with(p, "fifo"),
        "directory": lambda p: replace_with(p, "directory"),
        "deep": lambda p: p.write_text(DEEP),
        "no-intrinsics": lambda p: edit_json(p, lambda d: d.pop("intrinsics")),
        "width-1e9": lambda p: edit_json(p, lambda d: d.update(width=10**9)),
        "rotation-scaled": lambda p: edit_json(p, lambda d: d["extrinsics"].update(
            R_base_camera=[[2, 0, 0], [0, 2, 0], [0, 0, 2]])),
        "nan": lambda p: p.write_text(p.read_text().replace('"fx": ', '"fx": NaN, "x": ')),
        "missing": lambda p: p.unlink(),
    }  # fmt: skip
    image_damage = {
        "image-fifo": lambda p: replace_with(p, "fifo"),
        "image-directory": lambda p: replace_with(p, "directory"),
        "image-text": lambda p: p.write_text("text"),
        "image-truncated": lambda p: p.write_bytes(p.read_bytes()[:200]),
        "image-1x1": lambda p: _png(p, np.zeros((1, 1, 3), np.uint8)),
        "image-gray": lambda p: _png(p, np.zeros((240, 320), np.uint8)),
    }
    for kind, damage in {**camera_damage, **image_damage}.items():
        target = "image.png" if kind.startswith("image") else "camera.json"

        def setup(folder, damage=damage, target=target):
            shutil.copy(_label(runner) / "000000.png", folder / "image.png")
            label = json.loads((_label(runner) / "000000.json").read_text())
            (folder / "camera.json").write_text(json.dumps(label["calibration"]))
            damage(folder / target)

        expect = "any" if kind in ("image-1x1", "image-gray") else "error"
        cases.append(
            Case(
                f"damaged-camera/localize/{kind}",
                "damaged files",
                [*vis, "localize", "image.png", "--camera", "camera.json"],
                expect=expect,
                setup=setup,
                timeout=120,
                prog="mjx-peg-vision",
            )
        )
    return cases


def _png(path: Path, array) -> None:
    from PIL import Image

    Image.fromarray(array).save(path)


RANGE_DAMAGE = {
    "success-text": lambda a: {**a, "success": np.array(["x"] * len(a["success"]))},
    "time-shape": lambda a: {**a, "time_s": np.zeros((3, 3))},
    "time-complex": lambda a: {**a, "time_s": a["time_s"].astype(complex)},
    "time-negative": lambda a: {**a, "time_s": -np.ones_like(a["time_s"])},
    "shape-id-9": lambda a: {**a, "shape_id": np.full_like(a["shape_id"], 9)},
    "steps-float": lambda a: {**a, "steps": a["steps"].astype(float)},
    "no-success": lambda a: {k: v for k, v in a.items() if k != "success"},
}


def eval_resume_cases(runner: Runner) -> list[Case]:
    """A finished range of a resumed evaluation, damaged: the rerun refuses in one line naming
    it, and the other ranges stay."""
    return [dataclasses.replace(c, needs=("eval",)) for c in _eval_resume_cases(runner)]


def _eval_resume_cases(runner: Runner) -> list[Case]:
    argv = [*runner.program("eval.py"), *_EVAL_ARGS, "--out", "eval"]
    cases = []

    def base(folder):
        shutil.copytree(runner.fixtures / "eval", folder / "eval")
        (folder / "eval" / "grid.csv").unlink()

    for kind, change in RANGE_DAMAGE.items():

        def setup(folder, change=change):
            base(folder)
            path = folder / "eval" / "ranges" / "00000.npz"
            with np.load(path) as z:
                arrays = {k: z[k] for k in z.files}
            np.savez(path, **change(arrays))
            _remember(folder, ["eval/ranges/00001.npz"])

        cases.append(Case(f"damaged-range/{kind}", "damaged files", argv, setup=setup,
                          check=_unchanged(["eval/ranges/00001.npz"], nothing_new=False),
                          prog="eval.py"))  # fmt: skip
    for kind in ("fifo", "directory", "empty", "loop"):

        def setup(folder, kind=kind):
            base(folder)
            replace_with(folder / "eval" / "ranges" / "00000.npz", kind)
            _remember(folder, ["eval/ranges/00001.npz"])

        cases.append(Case(f"damaged-range/{kind}", "damaged files", argv, setup=setup,
                          check=_unchanged(["eval/ranges/00001.npz"], nothing_new=False),
                          timeout=120, prog="eval.py"))  # fmt: skip
    npz_damage = {
        "truncated": lambda p: p.write_bytes(p.read_bytes()[:300]),
        "8tib": lambda p: write_npz(p, {**npz_members(p), "time_s": npy(header=HUGE)}),
    }
    for kind, change in npz_damage.items():

        def setup(folder, change=change):
            base(folder)
            change(folder / "eval" / "ranges" / "00000.npz")

        cases.append(Case(f"damaged-range/{kind}", "damaged files", argv, setup=setup,
                          prog="eval.py"))  # fmt: skip
    config_damage = {
        "deep": lambda p: p.write_text(DEEP),
        "list": lambda p: p.write_text("[1]"),
        "schema-other": lambda p: edit_json(p, lambda d: d.update(schema="x")),
        "config-list": lambda p: edit_json(p, lambda d: d.update(config=[1])),
        "fifo": lambda p: replace_with(p, "fifo"),
        "trials-text": lambda p: edit_json(p, lambda d: d["config"].update(trials="2")),
    }
    for kind, damage in config_damage.items():

        def setup(folder, damage=damage):
            base(folder)
            damage(folder / "eval" / "config.json")
            _remember(folder, ["eval/ranges"])

        cases.append(Case(f"damaged-eval-config/resume/{kind}", "damaged files", argv,
                          setup=setup, check=_unchanged(["eval/ranges"], nothing_new=False),
                          timeout=120, prog="eval.py"))  # fmt: skip

        def setup_replay(folder, damage=damage):
            shutil.copytree(runner.fixtures / "eval", folder / "eval")
            damage(folder / "eval" / "config.json")

        cases.append(Case(f"damaged-eval-config/replay/{kind}", "damaged files",
                          [*runner.program("mjx-peg-demo"), "--replay", "eval", "--range", "0",
                           "--frames", "0", "--out", "new/out"], setup=setup_replay,
                          timeout=120, prog="mjx-peg-demo"))  # fmt: skip
    grid_damage = {
        "fifo": lambda p: replace_with(p, "fifo"),
        "directory": lambda p: replace_with(p, "directory"),
        "empty": lambda p: replace_with(p, "empty"),
        "text-values": lambda p: p.write_text(p.read_text().replace(",1,", ",x,", 1)),
        "more-successes": lambda p: p.write_text(_grid_successes(p.read_text(), "999")),
        "huge-int": lambda p: p.write_text(_grid_successes(p.read_text(), "9" * 30)),
        "missing": lambda p: p.unlink(),
        "binary": lambda p: p.write_bytes(b"\xff\xfe\x00" * 100),
    }
    for kind, damage in grid_damage.items():

        def setup(folder, damage=damage):
            shutil.copytree(runner.fixtures / "eval", folder / "other")
            damage(folder / "other" / "grid.csv")

        cases.append(Case(f"damaged-grid-csv/compare/{kind}", "damaged files",
                          [*runner.program("eval.py"), *_EVAL_ARGS, "--compare", "other", "--out",
                           "new/out"], setup=setup, timeout=120, prog="eval.py"))  # fmt: skip
    return cases


def _grid_successes(text: str, value: str) -> str:
    lines = text.splitlines()
    header = lines[0].split(",")
    row = lines[1].split(",")
    row[header.index("successes")] = value
    return "\n".join([lines[0], ",".join(row), *lines[2:]]) + "\n"


_EVAL_ARGS = [
    "--policy",
    "baseline",
    "--grid",
    "custom",
    "--linear-mm",
    "1,2",
    "--angular-deg",
    "1",
    "--trials",
    "2",
    "--time-limit",
    "0.05",
    "--processes",
    "0",
    "--no-progress",
]
_TRAIN_ARGS = ["--trials", "16", "--num-envs", "8", "--time-limit", "0.3", "--seed", "3",
               "--checkpoint-every", "0", "--processes", "0", "--no-progress"]  # fmt: skip
_PARTIAL_ARGS = [*_TRAIN_ARGS, "--trials", "32"]  # the stopped run of the fixtures


def train_resume_cases(runner: Runner) -> list[Case]:
    """A stopped training run, damaged, resumed."""
    return [dataclasses.replace(c, needs=("run-partial",)) for c in _train_resume_cases(runner)]


def _train_resume_cases(runner: Runner) -> list[Case]:
    argv = [*runner.program("train.py"), *_PARTIAL_ARGS, "--out", "run"]
    damage = {
        "deep": lambda p: p.write_text(DEEP),
        "list": lambda p: p.write_text("[1]"),
        "unknown-key": lambda p: edit_json(p, lambda d: d.update(colour="blue")),
        "seed-text": lambda p: edit_json(p, lambda d: d.update(seed="3")),
        "hidden-huge": lambda p: edit_json(p, lambda d: d.update(policy_hidden=[10**9])),
        "fifo": lambda p: replace_with(p, "fifo"),
        "latin1": lambda p: p.write_bytes(b'{"preset": "\xe9"}'),
    }
    cases = []
    for kind, change in damage.items():

        def setup(folder, change=change):
            shutil.copytree(runner.fixtures / "run-partial", folder / "run")
            change(folder / "run" / "config.json")
            _remember(folder, ["run/checkpoints", "run/trials.csv"])

        cases.append(Case(f"damaged-run-config/resume/{kind}", "damaged files", argv,
                          setup=setup, check=_unchanged(["run/checkpoints", "run/trials.csv"],
                                                        nothing_new=False),
                          timeout=180, prog="train.py"))  # fmt: skip
    table_damage = {
        "trials-csv-fifo": lambda r: replace_with(r / "trials.csv", "fifo"),
        "trials-csv-empty": lambda r: replace_with(r / "trials.csv", "empty"),
        "trials-csv-half-row": lambda r: (r / "trials.csv").write_text(
            (r / "trials.csv").read_text() + "99,12"),
        "checkpoint-tmp-left": lambda r: (r / "checkpoints" / "2.orbax-checkpoint-tmp").mkdir(),
        "checkpoint-truncated": lambda r: [p.write_bytes(p.read_bytes()[:10]) for p in
                                           (r / "checkpoints").rglob("*") if p.is_file()
                                           and p.stat().st_size > 1000],
    }  # fmt: skip
    for kind, change in table_damage.items():

        def setup(folder, change=change):
            shutil.copytree(runner.fixtures / "run-partial", folder / "run")
            change(folder / "run")

        expect = "ok" if kind in ("trials-csv-half-row", "checkpoint-tmp-left",
                                  "trials-csv-empty") else "error"  # fmt: skip
        cases.append(Case(f"damaged-run/resume/{kind}", "damaged files", argv, expect=expect,
                          setup=setup, timeout=240, prog="train.py"))  # fmt: skip
    return cases


# -- edge values ----------------------------------------------------------------------------------

BAD_VALUES = {"neg": "-1", "nan": "nan", "inf": "inf", "1e309": "1e309", "empty": "",
              "word": "abc", "superscript": "\u00b2", "400-digits": "9" * 400,
              "denormal": "1e-320"}  # fmt: skip


def edge_cases(runner: Runner) -> list[Case]:
    # Each command with arguments that make a run short, should a value be accepted.
    flags = {
        "train.py": (["--trials", "8", "--num-envs", "8", "--time-limit", "0.01", "--processes",
                      "0", "--no-progress", "--out", "new/out"],
                     ["--seed", "--num-envs", "--trials", "--time-limit", "--checkpoint-every",
                      "--threads", "--processes", "--eval-every", "--seeds"]),
        "eval.py": (["--policy", "baseline", "--grid", "custom", "--linear-mm", "1",
                     "--angular-deg", "1", "--trials", "1", "--time-limit", "0.01", "--processes",
                     "0", "--no-progress", "--out", "new/out"],
                    ["--size", "--trials", "--time-limit", "--seed", "--threads", "--processes",
                     "--chunk-trials", "--linear-mm", "--angular-deg", "--hole-scale"]),
        "mjx-peg-baseline": (["--trials", "1", "--time-limit", "0.01", "--shapes", "circle"],
                             ["--size", "--linear-mm", "--angular-deg", "--trials",
                              "--time-limit", "--seed", "--hole-scale"]),
        "robot": (["--trials", "1", "--time-limit", "0.01", "--no-progress", "--out", "new/out"],
                  ["--size", "--linear-mm", "--angular-deg", "--trials", "--seed", "--command-hz",
                   "--actuator-lag-ms", "--time-limit", "--hole", "--hole-scale"]),
        "mjx-peg-demo": (["--time-limit", "0.01", "--frames", "0", "--out", "new/out"],
                         ["--size", "--linear-mm", "--angular-deg", "--seed", "--time-limit",
                          "--range", "--frames", "--hole-scale"]),
        "mjx-peg-vision render": (["--out", "new/out", "--count", "1", "--width", "64",
                                   "--height", "64", "--no-progress"],
                                  ["--count", "--seed", "--width", "--height", "--sizes"]),
        "mjx-peg-vision act": (["--trials", "1", "--time-limit", "0.01", "--threads", "1",
                                "--no-progress", "--out", "new/out"],
                               ["--size", "--trials", "--time-limit", "--seed", "--threads"]),
        "mjx-peg-scene": (["--shape", "circle", "--width", "16", "--height", "16", "--out",
                           "new/out"], ["--size", "--width", "--height", "--hole-scale"]),
    }  # fmt: skip
    cases = []
    for prog, (fixed, names) in flags.items():
        words = prog.split()
        argv0 = [*runner.program(words[0]), *words[1:]]
        label = {"robot": "python -m mjx_peg.robot"}.get(words[0], words[0])
        for flag in names:
            for kind, value in BAD_VALUES.items():
                argv = [*argv0, *fixed, f"{flag}={value}"]
                if flag == "--hole":
                    argv = [*argv0, *fixed, "--dry-run", f"--hole={value},1,1"]
                if prog == "mjx-peg-scene" and flag == "--size":
                    argv = [*argv0, *fixed, f"{flag}={value}"]
                elif prog == "mjx-peg-scene":
                    argv = [*argv0, *fixed, "--size", "50", f"{flag}={value}"]
                # 1e-320 lies in a range that starts at 0: a valid (if odd) value there
                expect = "any" if kind == "denormal" else "error"
                cases.append(Case(f"edge/{prog.replace(' ', '-')}/{flag[2:]}/{kind}", "edge values",
                                  argv, expect=expect, check=_nothing_new, prog=label))  # fmt: skip
    good = {
        "robot-seed-max": [*runner.program("robot"), "--seed", "4294967295", "--trials", "1",
                           "--time-limit", "0.01", "--out", "new/out", "--no-progress"],
        "robot-command-hz-166.6667": [*runner.program("robot"), "--command-hz", "166.6667",
                                      "--trials", "1", "--time-limit", "0.05", "--out",
                                      "new/out", "--no-progress"],
        "robot-size-10": [*runner.program("robot"), "--size", "10", "--trials", "1",
                          "--time-limit", "0.02", "--out", "new/out", "--no-progress"],
        "robot-size-100": [*runner.program("robot"), "--size", "100", "--trials", "1",
                           "--time-limit", "0.02", "--out", "new/out", "--no-progress"],
        "baseline-errors-zero": [*runner.program("mjx-peg-baseline"), "--linear-mm", "0",
                                 "--angular-deg", "0", "--trials", "1", "--time-limit", "0.02",
                                 "--shapes", "circle"],
        "eval-linear-50": [*runner.program("eval.py"), "--policy", "baseline", "--grid",
                           "custom", "--linear-mm", "50", "--angular-deg", "45", "--trials", "1",
                           "--time-limit", "0.02", "--processes", "0", "--out", "new/out",
                           "--no-progress"],
        "demo-frames-0": [*runner.program("mjx-peg-demo"), "--frames", "0", "--time-limit",
                          "0.02", "--out", "new/out"],
        "scene-size-10": [*runner.program("mjx-peg-scene"), "--shape", "triangle", "--size",
                          "10", "--width", "16", "--height", "16", "--out", "new/out"],
        "scene-hexagon-hole-1.25": [*runner.program("mjx-peg-scene"), "--shape", "hexagon",
                                    "--size", "80", "--hole-scale", "1.25", "--width", "16",
                                    "--height", "16", "--out", "new/out"],
        "baseline-rectangle-tight": [*runner.program("mjx-peg-baseline"), "--shapes", "rectangle",
                                     "--hole-scale", "tight", "--trials", "1", "--time-limit",
                                     "0.02"],
        "train-seed-and-seeds": [*runner.program("train.py"), "--seed", "1", "--seeds", "1,2",
                                 "--trials", "8", "--num-envs", "8", "--out", "new/out"],
    }  # fmt: skip
    for name, argv in good.items():
        refused = name == "train-seed-and-seeds"
        cases.append(Case(f"edge/valid/{name}", "edge values", argv,
                          expect="error" if refused else "any",
                          check=_nothing_new if refused else None))  # fmt: skip
    return cases


def _nothing_new(folder: Path, r: Result) -> str | None:
    if r.code not in (0, None) and (folder / "new").exists():
        return "lost: new/ was written before the input was refused"
    return None


# -- the UR5e CLI without a robot, Ray, environments -----------------------------------------------


def ur5e_cases(runner: Runner) -> list[Case]:
    robot = runner.program("robot")
    hole = ["--hole", "450,-120,30"]
    cases = []
    bad = {
        "unreachable-ip": ["--robot-ip", "127.0.0.1", *hole],
        "bad-host": ["--robot-ip", "not a host!", *hole],
        "host-too-long": ["--robot-ip", "a" * 300, *hole],
        "no-hole": ["--robot-ip", "127.0.0.1"],
        "hole-two-numbers": ["--dry-run", "--hole", "450,-120"],
        "hole-four-numbers": ["--dry-run", "--hole", "450,-120,30,1"],
        "hole-nan": ["--dry-run", "--hole", "nan,1,1"],
        "hole-inf": ["--dry-run", "--hole", "inf,1,1"],
        "hole-negative-unquoted": ["--dry-run", "--hole", "-450,120,30"],
        "hole-out-of-reach": ["--dry-run", "--hole", "2000,0,0"],
        "hole-at-base": ["--dry-run", "--hole", "0,0,0"],
        "shadow-without-arm": ["--shadow", *hole],
        "rehearse-with-ip": ["--rehearse", "--robot-ip", "127.0.0.1", *hole],
        "dry-run-and-shadow": ["--dry-run", "--shadow", *hole],
        "command-hz-125": ["--robot-ip", "127.0.0.1", *hole, "--command-hz", "125"],
        "actuator-lag": ["--rehearse", *hole, "--actuator-lag-ms", "5"],
        "model-controller-sim": ["--model", "controller", "--trials", "1"],
        "friction-comp-sim": ["--friction-comp", "--trials", "1"],
        "out-into-policy": ["--rehearse", *hole, "--policy", "paper", "--out",
                            str(runner.clone / "policies" / "paper")],
        "out-into-policy-relative": ["--rehearse", *hole, "--policy", "paper", "--out",
                                     "../../clone/policies/paper"],
        "policy-5000-chars": ["--dry-run", *hole, "--policy", "p" * 5000],
        "policy-nul": ["--dry-run", *hole, "--policy", "a\x01b"],
        "time-limit-tiny": ["--rehearse", *hole, "--time-limit", "0.01", "--command-hz", "500"],
    }  # fmt: skip
    for name, argv in bad.items():
        expect = "any" if name in ("hole-at-base", "time-limit-tiny") else "error"

        def check(folder, r, argv=argv):
            if "--out" in argv and "policies/paper" in argv[argv.index("--out") + 1]:
                for p in (runner.clone / "policies" / "paper").iterdir():
                    if p.name.startswith("ur5e_run"):
                        return f"lost: {p} written into the policy it read"
            return _nothing_new(folder, r)

        cases.append(Case(f"ur5e/{name}", "UR5e CLI without a robot",
                          [*robot, *argv, "--out", "new/out"] if "--out" not in argv else
                          [*robot, *argv], expect=expect, check=check, timeout=120,
                          prog="python -m mjx_peg.robot"))  # fmt: skip
    # Every shipped policy on every shape, dry run and rehearsal: refused unless trained on it.
    for policy in sorted(p.name for p in (HERE / "policies").iterdir()
                         if (p / "manifest.json").is_file()):  # fmt: skip
        manifest = json.loads((HERE / "policies" / policy / "manifest.json").read_text())
        for shape in ("circle", "square", "triangle"):
            for size in ("50", "25"):
                trained = shape in manifest["config"]["shapes"] and float(size) in [
                    float(s) for s in manifest["config"]["size_mm"]]  # fmt: skip
                for mode in (["--dry-run"], ["--rehearse", "--time-limit", "0.2"]):
                    if mode[0] == "--rehearse" and trained and policy != "quick":
                        continue  # one rehearsal of a trained pair is enough
                    cases.append(Case(
                        f"ur5e/policy-part/{policy}/{shape}-{size}{mode[0]}",
                        "UR5e CLI without a robot",
                        [*robot, *mode, "--policy", policy, "--shape", shape, "--size", size,
                         *hole, "--out", "new/out"],
                        expect="any" if trained else "error", check=_nothing_new,
                        prog="python -m mjx_peg.robot",
                    ))  # fmt: skip
    return cases


def ray_cases(runner: Runner) -> list[Case]:
    addresses = {"superscript-port": "127.0.0.1:\u00b2", "port-99999": "127.0.0.1:99999",
                 "port-0": "127.0.0.1:0", "no-port": "127.0.0.1:", "no-host": ":6379",
                 "nonsense": "nonsense", "closed-port": "127.0.0.1:9", "ipv6": "[::1]:9",
                 "spaces": " 127.0.0.1 : 9 ", "negative-port": "127.0.0.1:-1",
                 "unicode-host": "h\u00f6st:9", "long": "a" * 5000 + ":9"}  # fmt: skip
    cases = []
    for name, address in addresses.items():
        cases.append(
            Case(
                f"ray/eval/{name}",
                "Ray addresses",
                [*runner.program("eval.py"), *_EVAL_ARGS, "--ray", address, "--out", "new/out"],
                check=_nothing_new,
                timeout=120,
                prog="eval.py",
            )
        )
        if name in ("superscript-port", "port-99999", "nonsense", "closed-port"):
            cases.append(Case(f"ray/train/{name}", "Ray addresses",
                              [*runner.program("train.py"), *_TRAIN_ARGS, "--ray", address,
                               "--out", "new/out"], check=_nothing_new, timeout=120,
                              prog="train.py"))  # fmt: skip
    cases.append(Case("ray/eval/with-processes", "Ray addresses",
                      [*runner.program("eval.py"), *_EVAL_ARGS, "--ray", "auto", "--out",
                       "new/out"], check=_nothing_new, prog="eval.py"))  # fmt: skip
    return cases


def environment_cases(runner: Runner) -> list[Case]:
    envs = {
        "ascii": {"PYTHONIOENCODING": "ascii"},
        "lang-c": {"LANG": "C", "LC_ALL": "C"},
        "jax-cuda": {"JAX_PLATFORMS": "cuda"},
        "jax-bogus": {"JAX_PLATFORMS": "bogus"},
        "jax-empty": {"JAX_PLATFORMS": ""},
        "mujoco-gl-bogus": {"MUJOCO_GL": "bogus"},
        "mujoco-gl-osmesa": {"MUJOCO_GL": "osmesa"},
        "mujoco-gl-glx": {"MUJOCO_GL": "glx", "DISPLAY": None},
        "no-home": {"HOME": None},
        "tmpdir-missing": {"TMPDIR": "/nonexistent/tmp"},
        "omp-threads-text": {"OMP_NUM_THREADS": "abc"},
        "xla-flags-bogus": {"XLA_FLAGS": "--xla_nonsense_flag"},
    }
    commands = {
        "robot": [*runner.program("robot"), "--trials", "1", "--time-limit", "0.05", "--out",
                  "new/out", "--no-progress"],
        "baseline": [*runner.program("mjx-peg-baseline"), "--trials", "1", "--time-limit",
                     "0.05", "--shapes", "circle"],
        "eval": [*runner.program("eval.py"), *_EVAL_ARGS, "--out", "new/out"],
        "train": [*runner.program("train.py"), *_TRAIN_ARGS, "--trials", "8", "--out",
                  "new/out"],
        "demo": [*runner.program("mjx-peg-demo"), "--frames", "1", "--time-limit", "0.05",
                 "--out", "new/out"],
        "scene": [*runner.program("mjx-peg-scene"), "--shape", "square", "--size", "50",
                  "--width", "64", "--height", "48", "--out", "new/out"],
    }  # fmt: skip
    cases = []
    for env_name, env in envs.items():
        for name, argv in commands.items():
            cases.append(Case(f"env/{env_name}/{name}", "odd environments", argv, expect="any",
                              env=env, check=_nothing_new))  # fmt: skip
    for name in ("robot", "eval", "demo"):  # a working directory that cannot be written
        cases.append(
            Case(
                f"env/read-only-cwd/{name}",
                "odd environments",
                commands[name],
                expect="any",
                setup=lambda f: None,
                script=_read_only_cwd,
            )
        )
    return cases


def _read_only_cwd(case: Case, folder: Path) -> Result:
    locked = folder / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    try:
        return RUNNER.run(case.argv, locked, case.env, case.timeout)
    finally:
        locked.chmod(0o755)


# -- a full disk ----------------------------------------------------------------------------------


def _mount_tmpfs(path: Path, size: str) -> bool:
    path.mkdir(parents=True, exist_ok=True)
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)],
                          capture_output=True)  # fmt: skip
    return done.returncode == 0


def _unmount(path: Path) -> None:
    subprocess.run(["umount", str(path)], capture_output=True)


def full_disk_cases(runner: Runner) -> list[Case]:
    commands = {
        "train": ([*runner.program("train.py"), *_TRAIN_ARGS], "train.py"),
        "eval": ([*runner.program("eval.py"), *_EVAL_ARGS], "eval.py"),
        "robot": ([*runner.program("robot"), "--trials", "3", "--time-limit", "0.05",
                   "--no-progress"], "python -m mjx_peg.robot"),
        "render": ([*runner.program("mjx-peg-vision"), "render", "--count", "3", "--width",
                    "320", "--height", "240", "--no-progress"], "mjx-peg-vision"),
        "demo": ([*runner.program("mjx-peg-demo"), "--time-limit", "0.3"], "mjx-peg-demo"),
        "scene": ([*runner.program("mjx-peg-scene"), "--shape", "circle", "--size", "50"],
                  "mjx-peg-scene"),
    }  # fmt: skip
    cases = []
    for name, (argv, prog) in commands.items():
        for size in ("4k", "64k", "300k"):
            cases.append(
                Case(
                    f"full-disk/{name}/{size}",
                    "odd environments",
                    argv,
                    expect="any",
                    script=_full_disk(size),
                    prog=prog,
                )
            )
    return cases


def _full_disk(size: str):
    """Run the command with --out on a tmpfs of `size` (or, where mounting is not allowed, with
    RLIMIT_FSIZE at that size); then give it room and rerun: it must finish (exit 0) and the
    first run's line must name a path."""

    def script(case: Case, folder: Path) -> Result:
        disk = folder / "disk"
        mounted = _mount_tmpfs(disk, size)
        limit = int(size[:-1]) * 1024
        preexec = None
        if not mounted:
            disk.mkdir(exist_ok=True)

            def preexec():
                import resource

                _default_sigint()
                signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
                resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

        out = str(disk / "out")
        again = None
        try:
            first = RUNNER.run([*case.argv, "--out", out], folder, timeout=case.timeout,
                               preexec=preexec)  # fmt: skip
            if first.code != 0:  # the disk was too small: given room, the same command ends
                if mounted:
                    subprocess.run(["mount", "-o", "remount,size=200m", str(disk)],
                                   capture_output=True)  # fmt: skip
                again = RUNNER.run([*case.argv, "--out", out], folder, timeout=case.timeout)
                if again.code == 2 and "--force" in again.err:  # finished results are kept:
                    again = RUNNER.run([*case.argv, "--out", out, "--force"], folder,
                                       timeout=case.timeout)  # fmt: skip
        finally:
            if mounted:
                _unmount(disk)
        note = ""
        lines = [line for line in first.err.splitlines() if line.strip()]
        if first.code not in (0, None) and lines and str(disk) not in lines[-1]:
            note = "wrong: the full disk's line names no path"
        if again is not None and again.code != 0:
            note = f"lost: the rerun with room failed ({again.code}): {again.err[-300:]}"
        first.note = note or first.note
        if again is not None and again.code != 0:
            first.err += again.err
        return first

    return script


# -- kills and resumes, two writers, signals -------------------------------------------------------


def _start(argv, folder: Path, env=None) -> subprocess.Popen:
    return subprocess.Popen(argv, cwd=folder, env=RUNNER.env(env), stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            errors="replace", start_new_session=True,
                            preexec_fn=_default_sigint)  # fmt: skip


def _wait_for(predicate, child: subprocess.Popen, timeout: float = 300) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        if child.poll() is not None:
            return False
        time.sleep(0.05)
    return False


def _finish(child: subprocess.Popen, timeout: float = TIMEOUT_S) -> tuple[int | None, str]:
    try:
        _, err = child.communicate(timeout=timeout)
        return child.returncode, err
    except subprocess.TimeoutExpired:
        os.killpg(child.pid, signal.SIGKILL)
        _, err = child.communicate()
        return None, err


def kill_cases(runner: Runner) -> list[Case]:
    cases = []
    train = [*runner.program("train.py"), *_PARTIAL_ARGS]
    evaluate = [
        *runner.program("eval.py"),
        *_EVAL_ARGS[:-5],
        "--trials",
        "4",
        "--time-limit",
        "1",
        "--linear-mm",
        "1,2,3",
        "--chunk-trials",
        "4",
        "--no-progress",
    ]
    for signum in ("SIGKILL", "SIGINT", "SIGTERM"):
        cases.append(Case(f"kill/train/{signum}", "kills and resumes", train, expect="ok",
                          script=_kill_resume(signum, "trials.csv", "checkpoints/1"),
                          timeout=400, prog="train.py"))  # fmt: skip
        cases.append(Case(f"kill/eval/{signum}", "kills and resumes", evaluate, expect="ok",
                          script=_kill_resume(signum, "grid.csv", "ranges/00000.npz"),
                          timeout=400, prog="eval.py"))  # fmt: skip
    robot = [*runner.program("robot"), "--trials", "6", "--time-limit", "3", "--no-progress"]
    cases.append(
        Case(
            "kill/robot/SIGKILL",
            "kills and resumes",
            robot,
            expect="ok",
            script=_kill_robot,
            timeout=400,
            prog="python -m mjx_peg.robot",
        )
    )
    render = [*runner.program("mjx-peg-vision"), "render", "--count", "6", "--width", "320",
              "--height", "240", "--no-progress"]  # fmt: skip
    cases.append(Case("kill/render/SIGKILL", "kills and resumes", render, expect="ok",
                      script=_kill_resume("SIGKILL", None, "000001.json"), timeout=400,
                      prog="mjx-peg-vision"))  # fmt: skip
    return cases


def _kill_resume(signame: str, compare: str | None, marker: str):
    """Run uninterrupted into ref/; run into out/, send the signal once `marker` exists, rerun
    to the end: `compare` (a file) must be byte-identical to ref's."""

    def script(case: Case, folder: Path) -> Result:
        ref = RUNNER.run([*case.argv, "--out", "ref"], folder, timeout=case.timeout)
        child = _start([*case.argv, "--out", "out"], folder)
        reached = _wait_for(lambda: (folder / "out" / marker).exists(), child)
        if child.poll() is None:
            os.killpg(child.pid, getattr(signal, signame))
        code, err = _finish(child)
        again = RUNNER.run([*case.argv, "--out", "out"], folder, timeout=case.timeout)
        note = ""
        if ref.code != 0:
            note = f"wrong: the uninterrupted run failed: {ref.err[-300:]}"
        elif not reached:
            note = "wrong: the run ended before the signal"
        elif signame != "SIGKILL" and (
            code not in (130, 143) or len(err.strip().splitlines()) != 1
        ):
            note = f"wrong: stopped with {code} and {len(err.strip().splitlines())} lines"
        elif again.code != 0:
            note = f"lost: the rerun failed ({again.code})"
        elif (
            compare
            and (folder / "ref" / compare).read_bytes() != (folder / "out" / compare).read_bytes()
        ):
            note = f"lost: {compare} differs from the uninterrupted run's"
        return Result(again.code, again.out, err + again.err, ref.wall_s + again.wall_s, note)

    return script


def _kill_robot(case: Case, folder: Path) -> Result:
    child = _start([*case.argv, "--out", "out"], folder)
    csv_path = folder / "out" / "runs.csv"
    _wait_for(lambda: csv_path.exists() and len(csv_path.read_text().splitlines()) >= 3, child)
    os.killpg(child.pid, signal.SIGKILL)
    _finish(child)
    rows = csv_path.read_text().splitlines() if csv_path.exists() else []
    note = ""
    if len(rows) < 3 or any(len(r.split(",")) != len(rows[0].split(",")) for r in rows):
        note = f"lost: runs.csv has {len(rows)} lines, some not whole"
    again = RUNNER.run([*case.argv, "--out", "out"], folder, timeout=case.timeout)
    if again.code != 2 or "--force" not in again.err:
        note = note or f"wrong: a rerun without --force gave {again.code}"
    return Result(0, "", "", 0.0, note)


def concurrency_cases(runner: Runner) -> list[Case]:
    cmds = {
        "train": ([*runner.program("train.py"), *_TRAIN_ARGS, "--trials", "48"], "trials.csv",
                  49, "train.py"),
        "eval": ([*runner.program("eval.py"), *_EVAL_ARGS[:-5], "--trials", "16", "--time-limit",
                  "2", "--no-progress"], "grid.csv", 3, "eval.py"),
        "robot": ([*runner.program("robot"), "--trials", "8", "--time-limit", "2",
                   "--no-progress"], "runs.csv", 9, "python -m mjx_peg.robot"),
        "render": ([*runner.program("mjx-peg-vision"), "render", "--count", "24", "--width",
                    "320", "--height", "240", "--no-progress"], "000003.json", None,
                   "mjx-peg-vision"),
        "demo": ([*runner.program("mjx-peg-demo"), "--time-limit", "2", "--frames", "2"],
                 "trial.png", None, "mjx-peg-demo"),
    }  # fmt: skip
    cases = []
    for name, (argv, result, lines, prog) in cmds.items():
        for gap in (0.5, 3.0):
            cases.append(Case(f"concurrency/two-{name}/{gap:g}s", "two writers on one --out",
                              argv, expect="error", script=_two_writers(gap, result, lines),
                              timeout=400, prog=prog))  # fmt: skip
    cases.append(Case("concurrency/train-then-eval", "two writers on one --out",
                      [*runner.program("train.py"), *_TRAIN_ARGS, "--trials", "48"],
                      expect="error", prog="eval.py",
                      script=_two_writers(3.0, "trials.csv", 49,
                                          [*runner.program("eval.py"), *_EVAL_ARGS]),
                      timeout=400))  # fmt: skip
    for attack in ("symlink", "hardlink", "directory", "fifo"):
        cases.append(
            Case(
                f"concurrency/lock-{attack}",
                "two writers on one --out",
                [*runner.program("eval.py"), *_EVAL_ARGS, "--out", "target"],
                expect="any",
                script=_lock_attack(attack),
                prog="eval.py",
            )
        )
    return cases


def _two_writers(gap: float, result: str, lines: int | None, second_argv=None):
    def script(case: Case, folder: Path) -> Result:
        first = _start([*case.argv, "--out", "out"], folder)
        time.sleep(gap)
        if first.poll() is not None:  # no second writer while it ran: the case shows nothing
            _finish(first)
            raise RuntimeError(f"the first writer ended within {gap:g} s, before the second")
        second = RUNNER.run([*(second_argv or case.argv), "--out", "out"], folder,
                            timeout=case.timeout)  # fmt: skip
        code, err = _finish(first)
        note = ""
        if code != 0:
            note = f"wrong: the first writer failed ({code}): {err[-300:]}"
        elif second.code == 0:
            note = "lost: both writers ran on one --out"
        elif not (folder / "out" / result).exists():
            note = f"lost: {result} is missing"
        elif lines is not None:
            n = len((folder / "out" / result).read_text().splitlines())
            if n != lines:
                note = f"lost: {result} has {n} lines, not {lines}"
        return Result(second.code, second.out, second.err, second.wall_s, note)

    return script


def _lock_attack(kind: str):
    def script(case: Case, folder: Path) -> Result:
        victim = folder / "victim.txt"
        victim.write_text("precious\n")
        lock = folder / ".target.lock"
        if kind == "symlink":
            lock.symlink_to("victim.txt")
        elif kind == "hardlink":
            os.link(victim, lock)
        elif kind == "directory":
            lock.mkdir()
        else:
            os.mkfifo(lock)
        r = RUNNER.run(case.argv, folder, timeout=120)
        if victim.read_text() != "precious\n":
            r.note = "lost: the lock wrote into the file it pointed to"
        return r

    return script


def signal_cases(runner: Runner) -> list[Case]:
    commands = ctrl_c_commands(runner)
    cases = []
    for name, (argv, prog) in commands.items():
        for at in (0.3, 1.5, 4.0):
            cases.append(Case(f"signal/SIGTERM/{name}/{at:g}s", "signals", argv, expect="any",
                              script=_signal_at(signal.SIGTERM, at, from_handler=True),
                              prog=prog))  # fmt: skip
        cases.append(Case(f"signal/SIGINT-twice/{name}", "signals", argv, expect="any",
                          script=_signal_at(signal.SIGINT, 4.0, twice=True, from_handler=True),
                          prog=prog))  # fmt: skip
    return cases


def ctrl_c_commands(runner: Runner) -> dict[str, tuple[list[str], str]]:
    return {
        "train.py": ([*runner.program("train.py"), "--trials", "48", "--num-envs", "8",
                      "--time-limit", "1", "--no-progress", "--out", "out"], "train.py"),
        "eval.py": ([*runner.program("eval.py"), "--policy", "baseline", "--grid", "custom",
                     "--linear-mm", "1", "--angular-deg", "1", "--trials", "8", "--no-progress",
                     "--out", "out"], "eval.py"),
        "mjx-peg-baseline": ([*runner.program("mjx-peg-baseline"), "--trials", "20"],
                             "mjx-peg-baseline"),
        "python -m mjx_peg.robot": ([*runner.program("robot"), "--trials", "5", "--no-progress",
                                     "--out", "out"], "python -m mjx_peg.robot"),
        "mjx-peg-vision": ([*runner.program("mjx-peg-vision"), "render", "--out", "out",
                            "--count", "50", "--width", "64", "--height", "64", "--no-progress"],
                           "mjx-peg-vision"),
        "mjx-peg-demo": ([*runner.program("mjx-peg-demo"), "--frames", "0", "--out", "out"],
                         "mjx-peg-demo"),
        "mjx-peg-scene": ([*runner.program("mjx-peg-scene"), "--shape", "circle", "--size", "50",
                           "--out", "out"], "mjx-peg-scene"),
    }  # fmt: skip


def _signal_at(signum: int, at_s: float, twice: bool = False, from_handler: bool = False):
    """Send `signum` to the process group at `at_s` after the start (`from_handler`: after the
    program took its signals, if later); classify by exit status and lines."""

    def script(case: Case, folder: Path) -> Result:
        start = time.monotonic()
        child = _start(case.argv, folder)
        if from_handler:
            while not signals.taken(child.pid) and child.poll() is None:
                time.sleep(0.002)
        time.sleep(max(0.0, at_s - (time.monotonic() - start)))
        sent = child.poll() is None and not signals.done(child.pid)
        if sent:
            os.killpg(child.pid, signum)
            if twice:
                time.sleep(0.3)
                if child.poll() is None:
                    os.killpg(child.pid, signum)
        code, err = _finish(child, timeout=120)
        note = "" if sent else f"finished: its command had ended before the signal at {at_s:g} s"
        return Result(code, "", err, time.monotonic() - start, note)

    return script


# -- the Python API -------------------------------------------------------------------------------

API_CALLS = {
    "load_policy-missing": "from mjx_peg.policy.export import load_policy; load_policy('nowhere')",
    "load_policy-int": "from mjx_peg.policy.export import load_policy; load_policy(3)",
    "resolve_policy-nul": "from mjx_peg.policy.shipped import resolve_policy; "
                          "resolve_policy('a\\x00b')",
    "run_trials-list": "from mjx_peg.engines import run_trials; run_trials([1], None)",
    "run_trials-params-nan": "import numpy as np; from mjx_peg.engines import run_trials; "
                             "from mjx_peg.world.task import TaskConfig, sample_trials; "
                             "s = sample_trials(TaskConfig(), 0, 1); "
                             "run_trials(s, np.full(38, np.nan), engine='mujoco')",
    "run_trials-params-shape": "import numpy as np; from mjx_peg.engines import run_trials; "
                               "from mjx_peg.world.task import TaskConfig, sample_trials; "
                               "run_trials(sample_trials(TaskConfig(), 0, 2), np.ones((3, 38)))",
    "run_trials-engine": "from mjx_peg.engines import run_trials; from mjx_peg.world.task import "
                         "TaskConfig, sample_trials; "
                         "run_trials(sample_trials(TaskConfig(), 0, 1), None, engine='gpu')",
    "sample_trials-negative": "from mjx_peg.world.task import TaskConfig, sample_trials; "
                              "sample_trials(TaskConfig(), 0, -1)",
    "TaskConfig-nan": "from mjx_peg.world.task import TaskConfig; "
                      "TaskConfig.from_mm_deg(('circle',), float('nan'), 1, 1)",
    "TaskConfig-shape": "from mjx_peg.world.task import TaskConfig; "
                        "TaskConfig.from_mm_deg(('hexagon!',), 50, 1, 1)",
    "TrainConfig-seed-text": "from mjx_peg.learn.config import TrainConfig; TrainConfig(seed='x')",
    "TrainConfig-trials-bool": "from mjx_peg.learn.config import TrainConfig; "
                               "TrainConfig(trials=True)",
    "TrainConfig-hidden-huge": "from mjx_peg.learn.config import TrainConfig; "
                               "TrainConfig(policy_hidden=(10**9,))",
    "TrainConfig-from_json-list": "from mjx_peg.learn.config import TrainConfig; "
                                  "TrainConfig.from_json({'shapes': 5})",
    "EvalConfig-trials-float": "from mjx_peg.evaluation.config import EvalConfig; "
                               "EvalConfig('baseline', 'custom', (1,), (1,), 2.5, ('circle',), 50)",
    "EvalConfig-shapes-int": "from mjx_peg.evaluation.config import EvalConfig; "
                             "EvalConfig('baseline', 'custom', (1,), (1,), 2, 5, 50)",
    "EvalConfig-size-text": "from mjx_peg.evaluation.config import EvalConfig; "
                            "EvalConfig('baseline', 'custom', (1,), (1,), 2, ('circle',), '50')",
    "parse_ranges-huge": "from mjx_peg.cli import parse_ranges; "
                         "parse_ranges('0:1e9:1e-9', '--linear-mm')",
    "HoleEstimate-nan": "from mjx_peg.robot.runtime import HoleEstimate; "
                        "HoleEstimate(float('nan'), 0, 0, 'circle', 0.05)",
    "HoleEstimate-shape": "from mjx_peg.robot.runtime import HoleEstimate; "
                          "HoleEstimate(0.4, 0, 0, 'blob', 0.05)",
    "controller_vector-bad": "from mjx_peg.robot.runtime import HoleEstimate, controller_vector; "
                             "controller_vector('nowhere', HoleEstimate(0.4, 0, 0, 'circle', .05))",
    "CameraCalibration-list": "from mjx_peg.vision.camera import CameraCalibration; "
                              "CameraCalibration.from_json([1])",
    "CameraCalibration-width-float": "from mjx_peg.vision.camera import CameraCalibration; "
                                     "CameraCalibration(width=1.5, height=2, fx=1, fy=1, cx=0, "
                                     "cy=0, R_base_camera=[[1,0,0],[0,1,0],[0,0,1]], "
                                     "t_base_camera=[0,0,1])",
    "Localizer-missing": "from mjx_peg.vision.localizer import Localizer; Localizer.load('x')",
    "SplitConfig-count": "from mjx_peg.vision.dataset import SplitConfig; SplitConfig(count=-1, "
                         "seed=0)",
    "read_png-dir": "from mjx_peg.vision.dataset import read_png; read_png('/')",
    "skill_config-unknown": "from mjx_peg.skill.search import skill_config; skill_config('x')",
    "skill_config-list": "from mjx_peg.skill.search import skill_config; skill_config(['x'])",
    "Checkpoints-restore-empty": "from mjx_peg.learn.checkpoints import Checkpoints; import "
                                 "numpy as np; Checkpoints('ck', 3).restore({'a': np.zeros(2)})",
    "train-bad-out": "from mjx_peg.learn.trainer import train; from mjx_peg.learn.config import "
                     "PRESETS; train(PRESETS['quick'].replace(trials=8, num_envs=8), '/proc/x')",
    "write_atomic-dir": "from mjx_peg.outdir import write_atomic; write_atomic('/proc/x/y', 'z')",
    "inputs-read_json-fifo": "import os; os.mkfifo('f'); from mjx_peg import inputs; "
                             "inputs.read_json('f')",
}  # fmt: skip


def api_cases(runner: Runner) -> list[Case]:
    """Each call in a fresh interpreter: a UsageError or an OSError (what the command lines
    print as one line; here through this wrapper) or a clean return counts as handled; any
    other exception is a traceback."""
    wrapper = (
        "import sys\nfrom mjx_peg.errors import UsageError, message\ntry:\n    exec(sys.argv[1])\n"
        "except (UsageError, OSError) as e:\n"
        "    print(f'api: error: {message(e)}', file=sys.stderr); sys.exit(2)\n"
    )
    return [Case(f"api/{name}", "the Python API", [PY, "-c", wrapper, code], expect="any",
                 timeout=180, prog="api") for name, code in API_CALLS.items()]  # fmt: skip


# -- fixtures, running, the table ------------------------------------------------------------------

RUNNER: Runner


def make_fixtures(runner: Runner, needed: set[str]) -> None:
    """The fixtures `needed` (of eval, run-partial, split), each made once."""
    f = runner.fixtures
    f.mkdir(parents=True, exist_ok=True)
    steps = [
        ("eval", [*runner.program("eval.py"), *_EVAL_ARGS, "--out", str(f / "eval")]),
        ("run-partial", None),
        ("split", [*runner.program("mjx-peg-vision"), "render", "--count", "2", "--width", "320",
                   "--height", "240", "--no-progress", "--out", str(f / "split")]),
    ]  # fmt: skip
    for name, argv in steps:
        if (f / name).exists() or name not in needed:
            continue
        if argv is None:  # a training run stopped after its first iteration's checkpoint
            child = _start([*runner.program("train.py"), *_PARTIAL_ARGS, "--out",
                            str(f / "partial-tmp")], f)  # fmt: skip
            _wait_for(lambda: (f / "partial-tmp" / "checkpoints" / "1").is_dir(), child)
            os.killpg(child.pid, signal.SIGKILL)
            _finish(child)
            os.rename(f / "partial-tmp", f / name)
            continue
        r = runner.run(argv, f, timeout=600)
        if r.code != 0:
            raise SystemExit(f"fixture {name} failed: {r.err[-2000:]}")


def all_cases(runner: Runner) -> list[Case]:
    return [
        *edge_cases(runner),
        *damaged_policy_cases(runner),
        *vision_cases(runner),
        *eval_resume_cases(runner),
        *train_resume_cases(runner),
        *ur5e_cases(runner),
        *ray_cases(runner),
        *environment_cases(runner),
        *full_disk_cases(runner),
        *kill_cases(runner),
        *concurrency_cases(runner),
        *signal_cases(runner),
        *api_cases(runner),
    ]


def ctrl_c_cases(runner: Runner, repeats: int) -> list[Case]:
    cases = []
    for name, (argv, prog) in ctrl_c_commands(runner).items():
        for at in (0.1, 0.3, 0.5, 1.0, 2.0):
            for k in range(repeats):
                cases.append(Case(f"ctrl-c/{name}/{at:g}s/{k}", "Ctrl-C", argv, expect="stopped",
                                  script=_signal_at(signal.SIGINT, at, from_handler=True),
                                  prog=prog))  # fmt: skip
    return cases


def run_case(runner: Runner, case: Case) -> dict:
    folder = runner.out / "cases" / re.sub(r"[^A-Za-z0-9_.-]+", "_", case.name)
    _unmount(folder / "disk")  # a tmpfs a killed catalogue left mounted
    if folder.exists():
        for p in folder.rglob("*"):  # a read-only folder left by a killed run
            if p.is_dir() and not p.is_symlink():
                p.chmod(0o755)
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    try:
        if case.setup is not None:
            case.setup(folder)
        if case.script is not None:
            r = case.script(case, folder)
        else:
            r = runner.run(case.argv, folder, case.env, case.timeout)
        if case.check is not None and not r.note.startswith(("lost", "wrong")):
            r.note = case.check(folder, r) or r.note
    except Exception as e:  # the catalogue's own failure: recorded, not hidden
        r = Result(-999, "", f"catalogue error: {type(e).__name__}: {e}", 0.0, "")
    kind = classify(case, r) if r.code != -999 else "catalogue-error"
    lines = [line for line in r.err.splitlines() if line.strip()]
    _unmount(folder / "disk")
    shutil.rmtree(folder, ignore_errors=True)
    record = {"name": case.name, "group": case.group, "class": kind, "code": r.code,
              "lines": len(lines), "last": lines[-1][:300] if lines else "", "note": r.note[:300],
              "wall_s": round(r.wall_s, 2)}  # fmt: skip
    if kind not in ("ok", "one-line"):
        record["stderr"] = r.err[-3000:]  # what went wrong, kept for reading
    return record


def write_table(out: Path, results: list[dict], title: str) -> str:
    groups = list(dict.fromkeys(r["group"] for r in results))
    kinds = [k for k in (*CLASSES, "catalogue-error") if any(r["class"] == k for r in results)]
    head = f"| class of case | cases | {' | '.join(kinds)} |"
    rows = [head, "|" + "---|" * (len(kinds) + 2)]
    for g in [*groups, "all"]:
        mine = [r for r in results if g in ("all", r["group"])]
        counts = [str(sum(r["class"] == k for r in mine)) for k in kinds]
        rows.append(f"| {g} | {len(mine)} | {' | '.join(counts)} |")
    bad = [r for r in results if r["class"] not in ("ok", "one-line")]
    detail = [f"- `{r['name']}`: {r['class']} (exit {r['code']}, {r['lines']} lines) "
              f"{r['note'] or r['last']}" for r in bad]  # fmt: skip
    text = "\n".join([f"# {title}", "", *rows, "", f"Not ok or one line: {len(bad)}", *detail])
    (out / ("table.md" if title.startswith("Catalogue") else "ctrl_c.md")).write_text(text + "\n")
    return text


def main(argv=None) -> int:
    global RUNNER
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("/tmp/catalogue"))
    p.add_argument("--mode", choices=("cases", "ctrl-c"), default="cases")
    p.add_argument("--only", default="", help="run the cases whose name contains one of these "
                   "(comma-separated)")  # fmt: skip
    p.add_argument("--repeats", type=int, default=5, help="ctrl-c: tries per instant")
    p.add_argument("--list", action="store_true", help="print the cases' names, run nothing")
    p.add_argument("--source", type=Path, default=HERE, help="the checkout to clone")
    args = p.parse_args(argv)
    out = args.out.resolve()
    RUNNER = runner = Runner(out)
    cases = all_cases(runner) if args.mode == "cases" else ctrl_c_cases(runner, args.repeats)
    only = args.only.split(",")
    cases = [c for c in cases if any(part in c.name for part in only)]
    names = [c.name for c in cases]
    assert len(set(names)) == len(names), "case names repeat"
    if args.list:
        print("\n".join(names))
        print(f"{len(names)} cases", file=sys.stderr)
        return 0
    out.mkdir(parents=True, exist_ok=True)
    if not runner.clone.exists():
        subprocess.run(["git", "clone", "-q", str(args.source), str(runner.clone)], check=True)
    log = out / ("results.jsonl" if args.mode == "cases" else "ctrl_c.jsonl")
    done = {}
    if log.exists():
        for line in log.read_text().splitlines():
            record = json.loads(line)
            done[record["name"]] = record
    make_fixtures(runner, {n for c in cases if c.name not in done for n in c.needs})
    for k, case in enumerate(cases):
        if case.name in done:
            continue
        record = run_case(runner, case)
        done[case.name] = record
        with open(log, "a") as f:
            f.write(json.dumps(record) + "\n")
        print(f"[{k + 1}/{len(cases)}] {record['class']:10s} {case.name} {record['wall_s']} s",
              flush=True)  # fmt: skip
    results = [done[n] for n in names]
    commit = subprocess.run(["git", "-C", str(runner.clone), "rev-parse", "--short", "HEAD"],
                            capture_output=True, text=True).stdout.strip()  # fmt: skip
    title = ("Catalogue" if args.mode == "cases" else "Ctrl-C") + f" of {commit}"
    print(write_table(out, results, title))
    return 0


if __name__ == "__main__":
    sys.exit(main())
