"""The layers hold: import-linter's contracts (pyproject.toml) pass, and reversing any one of them fails;
no module reaches another module's private names."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
LINT_IMPORTS = Path(sys.executable).with_name("lint-imports")


def lint_imports(tree: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(LINT_IMPORTS), "--config", str(tree / "pyproject.toml"), "--no-cache"], cwd=tree,
                          env={"PYTHONPATH": str(tree), "PATH": "/usr/bin:/bin"}, capture_output=True, text=True,
                          timeout=120)


@pytest.fixture(scope="module")
def copy_of_the_package(tmp_path_factory: pytest.TempPathFactory) -> Path:
    tree = tmp_path_factory.mktemp("layout")
    shutil.copytree(ROOT / "akarm", tree / "akarm", ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    shutil.copy(ROOT / "pyproject.toml", tree / "pyproject.toml")
    return tree


def test_the_import_contracts_hold() -> None:
    result = lint_imports(ROOT)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "0 broken" in result.stdout


@pytest.mark.parametrize(("module", "line", "contract"), [
    ("akarm/sim/faults.py", "import akarm.control.controller", "never imports the controller"),
    ("akarm/protocol/servo.py", "import akarm.config", "import nothing of akarm's but errors"),
    ("akarm/dynamics/model.py", "import akarm.motion.trajectory", "a package imports only the ones below it"),
    ("akarm/control/safety.py", "import akarm.arm", "a package imports only the ones below it"),
    ("akarm/cli/served.py", "import akarm.cli.move", "No import circles"),
])
def test_an_import_against_a_contract_fails_the_check(copy_of_the_package: Path, module: str, line: str,
                                                       contract: str) -> None:
    path = copy_of_the_package / module
    original = path.read_text()
    path.write_text(original + f"\n{line}  # planted by the test\n")
    try:
        result = lint_imports(copy_of_the_package)
    finally:
        path.write_text(original)
    assert result.returncode != 0, result.stdout
    broken = result.stdout.split("Broken contracts", 1)[-1]
    assert contract in broken, result.stdout


def check_private(*paths: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, str(ROOT / ".ci" / "check_private.py"), *map(str, paths)],
                          capture_output=True, text=True, timeout=60)


def test_no_module_reaches_another_modules_private_names() -> None:
    result = check_private(ROOT / "akarm", ROOT / "benchmarks", ROOT / "examples")
    assert result.returncode == 0, result.stdout


def test_a_reach_into_a_private_name_is_found(tmp_path: Path) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text("from akarm.cli.demo import session_steps\nfrom akarm.x import _hidden\n\n"
                   "def f(arm):\n    return arm._ctl, self._fine\n")
    result = check_private(bad)
    assert result.returncode == 1
    assert "imports _hidden" in result.stdout and "arm._ctl" in result.stdout and "_fine" not in result.stdout


def test_the_architecture_doc_shows_the_contracts_layers() -> None:
    tomllib = pytest.importorskip("tomllib")  # Python 3.11+

    layers = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"][0]["layers"]
    doc = (ROOT / "docs" / "architecture.md").read_text()
    table = doc.split("| layer (top to bottom) | what it is |", 1)[1].split("\n\n", 1)[0]
    rows = [line.split(" | ", 1)[0].strip("| ") for line in table.strip().splitlines()[1:]]
    shown = [" | ".join(part.strip().strip("`") for part in row.split("\\|")) for row in rows]
    assert shown == layers
