"""Every file we read is checked before use (`mjx_peg/inputs.py` and its readers): a damaged
file of each kind is one line naming it, never a traceback, a hang or an 8 TiB allocation.

The damaged files are built here from copies of the shipped files (policies/quick,
policies/localizer) and from labels the dataset code makes.
"""

from __future__ import annotations

import io
import json
import os
import shutil
import zipfile

import numpy as np
import pytest

from mjx_peg import inputs
from mjx_peg.errors import UsageError
from mjx_peg.policy import shipped
from mjx_peg.policy.export import PolicyError, load_policy
from mjx_peg.vision import dataset
from mjx_peg.vision.camera import CalibrationError, CameraCalibration
from mjx_peg.vision.localizer import Localizer, ModelError

DEEP = "[" * 200_000 + "]" * 200_000  # deeper than Python's recursion limit


def _npy(array=None, header: dict | None = None, data: bytes = b"") -> bytes:
    """The bytes of a .npy member: an array, or a hand-made header followed by `data`."""
    f = io.BytesIO()
    if header is None:
        np.lib.format.write_array(f, np.asarray(array), allow_pickle=False)
    else:
        np.lib.format.write_array_header_1_0(f, header)
        f.write(data)
    return f.getvalue()


def _write_npz(path, members: dict[str, bytes]) -> None:
    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED) as z:
        for name, blob in members.items():
            z.writestr(f"{name}.npy", blob)


def _truncate(path, size: int) -> None:
    path.write_bytes(path.read_bytes()[:size])


def _members(path) -> dict[str, bytes]:
    with zipfile.ZipFile(path) as z:
        return {n[:-4]: z.read(n) for n in z.namelist()}


HUGE = {"descr": "<f8", "fortran_order": False, "shape": (2**40,)}  # 8 TiB claimed


def _one_line(error: BaseException, path) -> str:
    text = str(error)
    assert "\n" not in text and text.startswith(str(path)), text
    return text


# -- inputs.py itself -------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kind, expected",
    [
        ("fifo", "not a regular file"),
        ("directory", "is a directory"),
        ("deep", "nested deeper than 32 levels"),
        ("nan", "NaN is not a JSON number"),
        ("latin1", "is not UTF-8"),
        ("large", "more than the 100 it may hold"),
        ("missing", "no such file"),
    ],
)
def test_read_json_refuses_a_damaged_file_in_one_line(kind, expected, tmp_path):
    path = tmp_path / "doc.json"
    if kind == "fifo":
        os.mkfifo(path)  # opened for reading without a writer, it would block forever
    elif kind == "directory":
        path.mkdir()
    elif kind == "deep":
        path.write_text(DEEP)
    elif kind == "nan":
        path.write_text('{"x": NaN}')
    elif kind == "latin1":
        path.write_bytes('{"x": "\xb1"}'.encode("latin-1"))
    elif kind == "large":
        path.write_text(json.dumps({"x": "a" * 200}))
    with pytest.raises(UsageError) as caught:
        inputs.read_json(path, limit=100 if kind == "large" else inputs.MAX_JSON_BYTES)
    assert expected in _one_line(caught.value, path)


def test_read_json_reads_a_good_file(tmp_path):
    (tmp_path / "ok.json").write_text('{"a": [1, {"b": 2.5}]}')
    assert inputs.read_json(tmp_path / "ok.json") == {"a": [1, {"b": 2.5}]}
    assert inputs.depth({"a": [1, {"b": 2.5}]}) == 3


@pytest.mark.parametrize(
    "member, expected",
    [
        (_npy(header=HUGE, data=b"\0" * 64), "more than the 64 it may"),
        (_npy(np.zeros(8, np.complex128)), "complex128"),
        (_npy(np.array(["1", "2"])), "<U1"),
        (_npy(np.zeros(8, "M8[s]")), "datetime64"),
        (_npy(np.zeros((2, 4))), "has shape (2, 4), not (8)"),
        (_npy(np.zeros(8))[:-16], "truncated or padded"),
        (_npy(np.array([0, 1, np.nan, 3, 4, 5, 6, 7.0])), "NaN or infinite"),
        (b"not an npy file at all", "corrupt or truncated"),
    ],
)
def test_read_npz_checks_a_member_before_loading_it(member, expected, tmp_path):
    path = tmp_path / "a.npz"
    _write_npz(path, {"x": member, "unused": _npy(header=HUGE, data=b"\0" * 64)})
    with pytest.raises(UsageError) as caught:
        inputs.read_npz(path, {"x": inputs.Member("f", (8,), max_size=64)})
    assert expected in _one_line(caught.value, path)


def test_read_npz_never_reads_a_member_not_asked_for(tmp_path):
    """An extra member claiming 8 TiB is left alone; only the members named are loaded."""
    path = tmp_path / "a.npz"
    _write_npz(path, {"x": _npy(np.arange(8.0)), "extra": _npy(header=HUGE, data=b"\0" * 64)})
    arrays = inputs.read_npz(path, {"x": inputs.Member("f", (8,))})
    assert list(arrays) == ["x"] and arrays["x"].tolist() == list(range(8))
    assert sorted(inputs.npz_names(path)) == ["extra", "x"]


# -- policies: policy.npz + manifest.json ------------------------------------------------------


def _policy(tmp_path):
    """A copy of the shipped `quick` (9 observation numbers, the geometry layout; 47 outputs)."""
    run = tmp_path / "policy"
    shutil.copytree(shipped.SHIPPED_DIR / "quick", run)
    return run


def _edit_manifest(run, edit) -> None:
    doc = json.loads((run / "manifest.json").read_text())
    edit(doc)
    (run / "manifest.json").write_text(json.dumps(doc))


def _edit_npz(run, **members) -> None:
    blobs = _members(run / "policy.npz")
    blobs.update(members)
    _write_npz(run / "policy.npz", blobs)


POLICY_DAMAGE = {
    "config is a list": (lambda r: _edit_manifest(r, lambda d: d.update(config=[1])),
                         "manifest.json: config is not an object"),
    "skill is a list": (lambda r: _edit_manifest(r, lambda d: d["config"].update(skill=["spiral"])),
                        "config.skill"),
    "no shapes": (lambda r: _edit_manifest(r, lambda d: d["config"].update(shapes=[])),
                  "config.shapes"),
    "shapes is a string": (lambda r: _edit_manifest(r, lambda d: d["config"].update(shapes="x")),
                           "config.shapes"),
    "nested 200,000 deep": (lambda r: (r / "manifest.json").write_text(DEEP),
                            "manifest.json is not a policy manifest (nested deeper"),
    "one-number layer": (lambda r: _edit_manifest(r, lambda d: d["network"].update(layers=[[8]])),
                         "network.layers holds [8]"),
    "layers do not chain": (lambda r: _edit_manifest(r, lambda d: d["network"].update(
        layers=[[9, 64], [32, 47]])), "layer 1 takes 32 inputs"),
    "trials is text": (lambda r: _edit_manifest(r, lambda d: d.update(trials="many")),
                       "trials is not a count"),
    "manifest is a FIFO": (lambda r: ((r / "manifest.json").unlink(),
                                      os.mkfifo(r / "manifest.json")), "not a regular file"),
    "statistics as text": (lambda r: _edit_npz(r, obs_mean=_npy(np.array(["0"] * 8))),
                           "array 'obs_mean' holds <U1"),
    "statistics as dates": (lambda r: _edit_npz(r, obs_std=_npy(np.ones(8, "M8[D]"))),
                            "array 'obs_std' holds datetime64[D]"),
    "complex kernel": (lambda r: _edit_npz(r, layer0_kernel=_npy(np.ones((8, 64), complex))),
                       "array 'layer0_kernel' holds complex128"),
    "a member claims 8 TiB": (lambda r: _edit_npz(r, obs_mean=_npy(header=HUGE)),
                              "array 'obs_mean' has shape (1099511627776,)"),
    "NaN in a bias": (lambda r: _edit_npz(r, layer1_bias=_npy(np.full(64, np.nan, np.float32))),
                      "array 'layer1_bias' holds NaN"),
    "zero std": (lambda r: _edit_npz(r, obs_std=_npy(np.zeros(9, np.float32))),
                 "obs_std holds values <= 0"),
    "truncated npz": (lambda r: _truncate(r / "policy.npz", 900),
                      "policy.npz: is corrupt or truncated"),
    "npz is a directory": (lambda r: ((r / "policy.npz").unlink(), (r / "policy.npz").mkdir()),
                           "policy.npz: is a directory"),
}  # fmt: skip


@pytest.mark.parametrize("kind", POLICY_DAMAGE)
def test_a_damaged_policy_is_one_line_naming_its_file(kind, tmp_path):
    run = _policy(tmp_path)
    damage, expected = POLICY_DAMAGE[kind]
    damage(run)
    with pytest.raises(PolicyError) as caught:
        load_policy(run)
    assert expected in _one_line(caught.value, run), str(caught.value)


def test_a_policy_loads_only_the_arrays_its_manifest_names(tmp_path):
    run = _policy(tmp_path)
    _edit_npz(run, extra=_npy(header=HUGE, data=b"\0" * 64))
    policy = load_policy(run)
    assert len(policy.layers) == 3 and policy.shapes == ("circle", "square")


# -- the localizer: model.json + model.npz ----------------------------------------------------


def _localizer(tmp_path):
    model = tmp_path / "model"
    shutil.copytree(shipped.SHIPPED_DIR / "localizer", model)
    return model


def _edit_model(model, edit) -> None:
    doc = json.loads((model / "model.json").read_text())
    edit(doc)
    (model / "model.json").write_text(json.dumps(doc))


def _replace(path, name: str, array) -> None:
    _write_npz(path, {**_members(path), name: _npy(array)})


MODEL_DAMAGE = {
    "no arch": (lambda m: _edit_model(m, lambda d: d.pop("arch")), "model.json: it lacks 'arch'"),
    "arch with text": (lambda m: _edit_model(m, lambda d: d["arch"]["detector"].update(
        convs=[["a", 2]])), "detector.convs is not a list"),
    "views is a list": (lambda m: _edit_model(m, lambda d: d.update(views=[1])), "model.json:"),
    "views out of range": (lambda m: _edit_model(m, lambda d: d["views"].update(fine_size=10**9)),
                           "views.fine_size"),
    "nested 200,000 deep": (lambda m: (m / "model.json").write_text(DEEP), "nested deeper"),
    "truncated npz": (lambda m: _truncate(m / "model.npz", 5000),
                      "model.npz: is corrupt or truncated"),
    "a kernel of another shape": (
        lambda m: _replace(m / "model.npz", "regressor/out/kernel", np.zeros((128, 11), "f4")),
        "array 'regressor/out/kernel' has shape (128, 11), not (128, 12)"),
    "a complex bias": (
        lambda m: _replace(m / "model.npz", "detector/head/bias", np.zeros(3, np.complex64)),
        "complex64"),
}  # fmt: skip


@pytest.mark.parametrize("kind", MODEL_DAMAGE)
def test_a_damaged_localizer_is_one_line_naming_its_file(kind, tmp_path):
    model = _localizer(tmp_path)
    damage, expected = MODEL_DAMAGE[kind]
    damage(model)
    with pytest.raises(ModelError) as caught:
        Localizer.load(model)
    assert expected in _one_line(caught.value, model), str(caught.value)


# -- vision splits, calibrations, images -------------------------------------------------------


def _split(tmp_path, label) -> object:
    """A split of one image whose label is `label` (a JSON-able object) or made by `edit`."""
    split = tmp_path / "split"
    split.mkdir()
    config = dataset.SplitConfig(count=1, seed=0, width=320, height=240)
    doc = {"schema": dataset.SCHEMA, "config": config.to_json()}
    (split / dataset.MANIFEST).write_text(json.dumps(doc))
    if callable(label):
        label = label(dataset.make_label(*dataset.draw(config, 0)))
    (split / "000000.json").write_text(json.dumps(label))
    return split


LABEL_DAMAGE = {
    "an empty list": ([], "not a JSON object"),
    "no board": (lambda lb: {k: v for k, v in lb.items() if k != "board"}, "board is not an"),
    "a shape index out of range": (lambda lb: {**lb, "shape_class": 7}, "shape_class"),
    "hole_px as text": (lambda lb: {**lb, "hole_px": ["a", "b"]}, "hole_px is not two numbers"),
    "a calibration without intrinsics": (
        lambda lb: {**lb, "calibration": {**lb["calibration"], "intrinsics": 3}}, "intrinsics"),
}  # fmt: skip


@pytest.mark.parametrize("kind", LABEL_DAMAGE)
def test_a_damaged_split_label_is_one_line_naming_its_file(kind, tmp_path):
    label, expected = LABEL_DAMAGE[kind]
    split = _split(tmp_path, label)
    with pytest.raises(UsageError) as caught:
        dataset.split_items(split)
    assert expected in _one_line(caught.value, split / "000000.json")


def test_the_labels_the_dataset_makes_pass_the_check(tmp_path):
    split = _split(tmp_path, lambda lb: lb)
    ((png, label),) = dataset.split_items(split)
    assert png.name == "000000.png" and dataset.label_problem(label) is None


@pytest.mark.parametrize("kind", ["fifo", "directory", "deep"])
def test_a_calibration_or_image_that_is_not_a_file_is_refused_without_blocking(kind, tmp_path):
    path = tmp_path / "thing"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "directory":
        path.mkdir()
    else:
        path.write_text(DEEP)
    with pytest.raises(CalibrationError) as caught:
        CameraCalibration.load(path)
    _one_line(caught.value, path)
    if kind != "deep":
        with pytest.raises(UsageError) as caught:
            dataset.read_png(path)
        _one_line(caught.value, path)
