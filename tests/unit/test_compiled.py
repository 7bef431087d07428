"""The compiled cycle: AKARM_PURE=1 runs the pure-Python modules even beside compiled ones, an
install is compiled whole or not at all, and what this process runs is reported truly."""

from __future__ import annotations

import importlib.machinery
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from akarm import compiled

ROOT = Path(__file__).resolve().parents[2]

PROBE = """
import json, akarm.compiled as c
mods = {}
for name in c.MODULES:
    m = __import__(name, fromlist=["_"])
    mods[name] = m.__file__
print(json.dumps({"files": mods, "status": c.status(), "compiled": list(c.compiled_modules())}))
"""


def _environ(**env: str) -> dict[str, str]:
    """This process's environment without AKARM_PURE, with ``env``."""
    return {k: v for k, v in os.environ.items() if k != compiled.PURE_ENV} | env


def _probe(**env: str) -> dict:
    out = subprocess.run([sys.executable, "-c", PROBE], env=_environ(**env), capture_output=True, text=True,
                         timeout=120, check=True)
    return json.loads(out.stdout.splitlines()[-1])


def _built() -> list[str]:
    """The compiled modules beside the sources (an editable install builds them there)."""
    return [f for name in compiled.MODULES if (f := compiled.compiled_file(compiled.source_file(name))) is not None]


@pytest.mark.parametrize(("value", "pure"), [("1", True), ("yes", True), (" 1 ", True), ("0", False), ("", False),
                                             (" ", False), (None, False)])
def test_akarm_pure_is_asked_for_by_any_value_but_0_or_empty(value: str | None, pure: bool) -> None:
    environ = {} if value is None else {compiled.PURE_ENV: value}
    assert compiled.pure_requested(environ) is pure


def test_akarm_pure_loads_every_module_of_the_cycle_from_its_python_file() -> None:
    got = _probe(AKARM_PURE="1")
    assert got["compiled"] == []
    assert all(f.endswith(".py") for f in got["files"].values()), got["files"]
    assert set(got["files"]) == set(compiled.MODULES)
    assert got["status"] == "pure Python (AKARM_PURE=1)"


def test_the_cycle_runs_compiled_whole_or_pure_whole_and_says_which() -> None:
    got = _probe()
    if _built():  # an install that compiled: every module of the cycle runs compiled, none half
        assert sorted(got["compiled"]) == sorted(compiled.MODULES)
        assert got["status"].startswith("compiled (mypyc)")
        assert not any(f.endswith(".py") for f in got["files"].values())
    else:
        assert got["compiled"] == []
        assert got["status"].startswith("pure Python: nothing was compiled")


def test_every_module_of_the_cycle_is_a_python_file_in_the_package() -> None:
    for name in compiled.MODULES:
        assert (ROOT / Path(*name.split("."))).with_suffix(".py").is_file(), name
    assert compiled.GROUP.startswith("akarm.")
    # the codecs stay pure: their wrong-type arguments are named ArgumentErrors, not a compiled TypeError
    assert not [m for m in compiled.MODULES if m.startswith("akarm.protocol")]


def test_setup_can_read_the_list_before_akarm_is_installed() -> None:
    # setup.py runs the file alone, in a build environment holding mypy and nothing of akarm's
    code = ("import runpy, sys; n = runpy.run_path(sys.argv[1]); "
            "print(len(n['MODULES']), sorted(m for m in sys.modules if m.split('.')[0] in ('akarm', 'numpy')))")
    out = subprocess.run([sys.executable, "-c", code, str(ROOT / "akarm" / "compiled.py")], capture_output=True,
                         text=True, timeout=60, check=True)
    assert out.stdout.split() == [str(len(compiled.MODULES)), "[]"]


def test_version_names_the_cycle_it_runs() -> None:
    out = subprocess.run([sys.executable, "-m", "akarm", "--version"], env=_environ(AKARM_PURE="1"),
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0
    assert out.stdout.splitlines()[1] == "the control cycle: pure Python (AKARM_PURE=1)"


def test_a_compiled_module_older_than_its_source_is_stale(tmp_path: Path) -> None:
    suffix = importlib.machinery.EXTENSION_SUFFIXES[0]
    package = tmp_path / "akarm"
    for name in compiled.MODULES:
        source = Path(compiled.source_file(name, str(package)))
        source.parent.mkdir(parents=True, exist_ok=True)
        source.write_text("")
        built = source.with_name(source.stem + suffix)
        built.write_bytes(b"")
        os.utime(built, (1000.0, 1000.0))
        os.utime(source, (1000.0 + compiled.STALE_SLACK / 2, 1000.0 + compiled.STALE_SLACK / 2))  # a wheel's unpacking
    assert compiled.stale_modules(str(package)) == ()
    joints = package / "control" / "joints.py"
    os.utime(joints, (1060.0, 1060.0))  # edited a minute after the build
    assert compiled.stale_modules(str(package)) == ("akarm.control.joints",)
    (package / "control" / ("joints" + suffix)).unlink()  # not compiled at all: nothing stale to run
    assert compiled.stale_modules(str(package)) == ()


def test_every_compiled_class_is_over_akarms_or_the_standard_librarys_classes() -> None:
    # The build sees no installed package (setup.py: the same build on every install), so a class over
    # python-can's BusABC, say, would compile over a base it does not know: the local bus did, and the
    # process crashed (a segmentation fault) at its first frame. Such a module stays pure Python.
    import ast

    for name in compiled.MODULES:
        tree = ast.parse((ROOT / Path(*name.split("."))).with_suffix(".py").read_text())
        imported: dict[str, str] = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                imported |= {(a.asname or a.name).split(".")[0]: a.name for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                imported |= {a.asname or a.name: node.module for a in node.names}
        for cls in (n for n in ast.walk(tree) if isinstance(n, ast.ClassDef)):
            for base in cls.bases:
                root = base
                while isinstance(root, ast.Attribute):
                    root = root.value
                assert isinstance(root, ast.Name), (name, cls.name)
                origin = imported.get(root.id, name).split(".")[0]  # not imported: defined in the module
                assert origin == "akarm" or origin in sys.stdlib_module_names, \
                    f"{name}.{cls.name} is a class over {ast.unparse(base)}, from {origin}: keep it pure Python"
