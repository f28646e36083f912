"""Every module of the package has its test module at the mirrored path:
mjx_peg/LAYER/NAME.py -> tests/LAYER/test_NAME.py (package entry points __init__ and __main__
excepted)."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "mjx_peg"
ENTRY_POINTS = {"__init__.py", "__main__.py"}


def missing_mirrors(package: Path = PACKAGE, tests: Path = ROOT / "tests") -> list[str]:
    """Modules of `package` (relative paths) without a test module at the mirrored path."""
    missing = []
    for module in sorted(package.rglob("*.py")):
        if module.name in ENTRY_POINTS:
            continue
        relative = module.relative_to(package)
        if not (tests / relative.parent / f"test_{module.name}").is_file():
            missing.append(str(relative))
    return missing


def test_every_module_has_its_test_module():
    assert missing_mirrors() == []


def test_a_module_without_its_test_module_is_named(tmp_path):
    package, tests = tmp_path / "pkg", tmp_path / "tests"
    for path in ("__init__.py", "__main__.py", "a.py", "layer/__init__.py", "layer/b.py",
                 "layer/c.py"):  # fmt: skip
        (package / path).parent.mkdir(parents=True, exist_ok=True)
        (package / path).write_text("")
    for path in ("test_a.py", "layer/test_b.py", "test_c.py"):  # c's test at the wrong depth
        (tests / path).parent.mkdir(parents=True, exist_ok=True)
        (tests / path).write_text("")
    assert missing_mirrors(package, tests) == ["layer/c.py"]
