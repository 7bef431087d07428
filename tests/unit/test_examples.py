"""The README and the examples agree with the repository: every example tested, the quick start is what
CI runs, every verb listed, the image is the demo's plot, the robot file example loads (the examples
run: tests/system/test_examples.py)."""

from __future__ import annotations

import re
from pathlib import Path

from ..sim.test_pick_and_place import SIM_EXAMPLES
from ..system.test_examples import EXAMPLES, NAMES, README, block
from .conftest import ROOT

#: the README and the MkDocs pages it is moving into (docs/): the user's documentation
DOCS = README + "".join(p.read_text(encoding="utf-8") for p in sorted((ROOT / "docs").glob("*.md")))


def test_every_example_is_tested() -> None:
    scripts = {p.stem for p in EXAMPLES.glob("*.py") if not p.name.startswith("_")}
    assert scripts == set(NAMES) | set(SIM_EXAMPLES)


def test_readme_quick_start_is_what_ci_runs() -> None:
    assert 'python3 -m venv .venv && .venv/bin/pip install -e ".[test,plot,data]" && .venv/bin/akarm demo' in README
    assert "\n.venv/bin/python -m pytest\n" in README
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert "\n.venv/bin/python -m pytest || exit 1" in ci
    assert '-e ".[test,plot,data]"' in ci
    # the second command, the system tier, is documented and CI runs it too
    assert "\n.venv/bin/python -m pytest tests/system" in README
    assert "\n.venv/bin/python -m pytest tests/system " in ci


def test_readme_lists_every_verb_and_every_example() -> None:
    from akarm.cli import VERBS

    for verb, (module, _) in VERBS.items():
        assert re.search(rf"^\| `akarm {verb}\b", DOCS, re.M), verb
        assert (ROOT / f"{module.replace('.', '/')}.py").is_file(), verb  # the README does not promise a missing verb
    for name in (*NAMES, *SIM_EXAMPLES):
        assert f"`examples/{name}.py`" in DOCS


def test_readme_image_is_the_demo_plot() -> None:
    assert "](docs/demo.png)" in README
    data = (ROOT / "docs" / "demo.png").read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 100_000


def test_readme_robot_file_example_loads(tmp_path: Path) -> None:
    import akarm

    text = block("yaml")
    assert "urdf: my_arm.urdf" in text
    (tmp_path / "my_arm.urdf").write_text((ROOT / "robots" / "planar2.urdf").read_text())  # joints shoulder, elbow
    (tmp_path / "my_arm.yaml").write_text(text)
    config = akarm.load_robot(tmp_path / "my_arm.yaml")
    shoulder, elbow = config.joints
    assert (shoulder.mode, elbow.mode) == ("mit", "servo")
    assert shoulder.motor.v_max == 25.64 and shoulder.motor.mit_temp_offset == 40
    assert shoulder.limits.torque == 10.0 and elbow.limits.velocity == 3.0  # own keys and `defaults:`
    assert elbow.status_rate_hz == 200 and set(config.buses) == {"arm", "aux", "usb"}
    assert config.buses["usb"].options == {"device_id": 2}  # passed through to python-can's PCAN bus
