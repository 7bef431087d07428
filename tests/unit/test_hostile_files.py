"""Files that try to hurt (issue 26): every reader refuses past its limits with its own error naming
the limit, before it spends the memory; files within the limits still read. The CLI on the issue's
hostile files, timed and measured in processes of their own: tests/system/test_hostile_files.py."""

from __future__ import annotations

import io
import re
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from akarm import ConfigError, ConfigWarning, RecordingError
from akarm.config import urdf as urdf_mod
from akarm.config.urdf import MAX_URDF_JOINTS, MAX_URDF_LINKS, read_urdf
from akarm.files import number
from akarm.motion import bounds
from akarm.motion import recording as rec
from akarm.protocol import motors
from akarm.robotfile.load import load_robot
from akarm.robotfile.nodes import MAX_JOINTS, MAX_ROBOT_FILE_BYTES
from akarm.robotfile.save import save_values
from akarm.robotfile.starter import suggest
from akarm.telemetry import log as telemetry

from .test_files import billion_laughs

ROOT = Path(__file__).resolve().parents[2]
PLANAR2 = ("shoulder", "elbow")


def chain_urdf(path: Path, joints: int, *, joints_first: bool = False) -> Path:
    """A URDF of ``joints`` revolute joints in one chain about vertical axes (no gravity torque), link k
    then joint k (or every joint first)."""
    inertial = ('<inertial><origin xyz="0 0 0.01"/><mass value="0.1"/><inertia ixx="1e-4" iyy="1e-4" izz="1e-4" '
                'ixy="0" ixz="0" iyz="0"/></inertial>')
    links = [f'<link name="l{k}">{inertial}</link>' for k in range(joints + 1)]
    elements = [f'<joint name="j{k}" type="revolute"><parent link="l{k - 1}"/><child link="l{k}"/>'
                f'<origin xyz="0 0 0.02"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="10" velocity="1"/>'
                f"</joint>" for k in range(1, joints + 1)]
    body = elements + links if joints_first else [links[0]] + [x for pair in zip(links[1:], elements, strict=True)
                                                                 for x in pair]
    path.write_text('<?xml version="1.0"?>\n<robot name="chain">\n' + "\n".join(body) + "\n</robot>\n")
    return path


def chain_robot(folder: Path, joints: int, driven: int = 1) -> Path:
    """A robot file driving the first ``driven`` joints of a :func:`chain_urdf`."""
    chain_urdf(folder / "chain.urdf", joints)
    entries = "".join(f"  - {{name: j{k}, can_id: {k}, motor: AK80-9}}\n" for k in range(1, driven + 1))
    robot = folder / "chain.yaml"
    robot.write_text("name: chain\nurdf: chain.urdf\ndefaults:\n  limits: {velocity: 1, acceleration: 1, jerk: 10}\n"
                     "  gains: {kp: 10, kd: 1}\njoints:\n" + entries)
    return robot


def problem_naming(e: ConfigError, limit: str) -> str:
    found = [p for p in e.problems if f"({limit})" in p.message]
    assert found, [p.message for p in e.problems]
    return found[0].message


# ---- URDF ----------------------------------------------------------------------------------------
def test_a_urdf_of_2000_chained_joints_is_refused_naming_the_limit(tmp_path: Path) -> None:
    urdf, problems = read_urdf(chain_urdf(tmp_path / "c.urdf", 2000))
    assert urdf is None
    (p,) = problems
    n = number(MAX_URDF_LINKS)
    assert p.message == f"the URDF has more than {n} links, over the limit of {n} links (MAX_URDF_LINKS)"
    assert p.line == 2 * MAX_URDF_LINKS + 2  # the link past the limit: nothing after it is read
    _, problems = read_urdf(chain_urdf(tmp_path / "j.urdf", 2000, joints_first=True))
    assert "(MAX_URDF_JOINTS)" in problems[0].message and problems[0].line == MAX_URDF_JOINTS + 3


def test_check_and_init_refuse_the_2000_joint_chain(tmp_path: Path) -> None:
    with pytest.raises(ConfigError) as info:
        load_robot(chain_robot(tmp_path, 2000))
    assert info.value.problems[0].file == str((tmp_path / "chain.urdf").resolve())
    problem_naming(info.value, "MAX_URDF_LINKS")
    with pytest.raises(ConfigError) as info:
        suggest(tmp_path / "chain.urdf", tmp_path / "out.yaml")
    problem_naming(info.value, "MAX_URDF_LINKS")


def test_a_chain_at_the_limits_is_walked_without_recursion(tmp_path: Path) -> None:
    urdf, problems = read_urdf(chain_urdf(tmp_path / "c.urdf", MAX_URDF_LINKS - 1))
    assert urdf is not None and not problems
    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(100)  # chain_order walked one frame per link before: 999 of them
    try:
        order = urdf.chain_order()
    finally:
        sys.setrecursionlimit(limit)
    assert order == [f"j{k}" for k in range(1, MAX_URDF_LINKS)]
    with pytest.warns(ConfigWarning, match="held at"):  # `akarm check`: 998 joints held (each warned of), one driven
        config = load_robot(chain_robot(tmp_path, MAX_URDF_LINKS - 1))
    assert config.joint_names == ("j1",) and len(config.locked) == MAX_URDF_LINKS - 2


def test_init_refuses_more_driven_joints_than_a_robot_file_may_have(tmp_path: Path) -> None:
    with pytest.raises(ConfigError) as info:
        suggest(chain_urdf(tmp_path / "c.urdf", MAX_JOINTS + 1), tmp_path / "out.yaml")
    (p,) = info.value.problems
    assert p.message == (f"the URDF has {MAX_JOINTS + 1} revolute and continuous joints for motors to drive, over "
                         f"the limit of {MAX_JOINTS} joints (MAX_JOINTS)")


def test_a_urdf_past_its_size(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = chain_urdf(tmp_path / "c.urdf", 3)
    monkeypatch.setattr(urdf_mod, "MAX_URDF_BYTES", 100)
    _, (p,) = read_urdf(path)
    assert p.message == f"the URDF is {number(path.stat().st_size)} bytes, over the limit of 100 bytes (MAX_URDF_BYTES)"


# ---- robot files and motor files -----------------------------------------------------------------
def test_an_alias_bomb_in_a_robot_file_is_refused_at_the_alias(tmp_path: Path) -> None:
    robot = tmp_path / "bomb.yaml"
    robot.write_text((ROOT / "robots" / "planar2.yaml").read_text().replace("urdf: planar2.urdf", f"urdf: "
                     f"{ROOT / 'robots' / 'planar2.urdf'}") + "\nmotors:\n  " + billion_laughs().replace("\n", "\n  "))
    with pytest.raises(ConfigError) as info:
        load_robot(robot)
    (p,) = info.value.problems
    assert "alias *a4 repeats 66 430 values" in p.message and "(MAX_ROBOT_FILE_NODES)" in p.message
    assert p.line == robot.read_text().splitlines().index(next(x for x in robot.read_text().splitlines()
                                                              if "&a4" in x)) + 2
    with pytest.raises(ConfigError, match="MAX_ROBOT_FILE_NODES"):  # identify's save goes the same way
        save_values(robot, check=lambda _: None)


def test_a_robot_file_past_its_size_or_depth(tmp_path: Path) -> None:
    robot = tmp_path / "big.yaml"
    robot.write_text("name: x\n" + "#" * MAX_ROBOT_FILE_BYTES + "\n")
    with pytest.raises(ConfigError) as info:
        load_robot(robot)
    problem_naming(info.value, "MAX_ROBOT_FILE_BYTES")
    robot.write_text("name: x\nbuses:\n  arm: {interface: virtual, channel: x, extra: " + "[" * 40 + "]" * 40 + "}\n")
    with pytest.raises(ConfigError) as info:
        load_robot(robot)
    assert info.value.problems[0].line == 3
    problem_naming(info.value, "MAX_YAML_DEPTH")


def test_a_robot_file_of_more_joints_than_the_limit(tmp_path: Path) -> None:
    with pytest.raises(ConfigError) as info:
        load_robot(chain_robot(tmp_path, MAX_JOINTS + 1, driven=MAX_JOINTS + 1))
    message = problem_naming(info.value, "MAX_JOINTS")
    assert message == f"`joints:` lists {MAX_JOINTS + 1} joints, over the limit of {MAX_JOINTS} joints (MAX_JOINTS)"


def test_an_alias_bomb_in_a_motor_file(tmp_path: Path) -> None:
    path = tmp_path / "motors.yaml"
    path.write_text(billion_laughs())
    before = motors.default_catalogue()
    with pytest.raises(ConfigError) as info:
        motors.load(path)
    problem_naming(info.value, "MAX_MOTOR_FILE_NODES")
    assert motors.default_catalogue() is before


# ---- recordings ----------------------------------------------------------------------------------
def test_a_keyframe_file_with_an_alias_bomb_is_refused_before_it_expands(tmp_path: Path) -> None:
    path = tmp_path / "bomb.yaml"
    path.write_text("joints: [shoulder, elbow]\n" + billion_laughs() + "keyframes:\n  - {q: *a8}\n")
    with pytest.raises(RecordingError) as info:
        rec.load(path, PLANAR2)
    assert "(MAX_KEYFRAME_FILE_NODES)" in info.value.what and "alias bomb" in info.value.fix
    assert f"{path}: line 7: the alias *a4 repeats 66 430 values" in info.value.what


def keyframe_text(n: int) -> str:
    return "robot: planar2\njoints: [shoulder, elbow]\nunits: rad\nkeyframes:\n" + "- q: [0.1, -0.2]\n" * n


def test_100_000_keyframes_are_refused_at_the_one_past_the_limit(tmp_path: Path) -> None:
    path = tmp_path / "k.yaml"
    path.write_text(keyframe_text(100_000))
    with pytest.raises(RecordingError) as info:
        rec.load(path, PLANAR2)
    n = number(bounds.MAX_KEYFRAMES)
    assert info.value.what == (f"{path}: line {bounds.MAX_KEYFRAMES + 5}: the list from line 5 has more than {n} "
                               f"keyframes, over the limit of {n} keyframes (MAX_KEYFRAMES)")


def test_keyframes_up_to_the_limit_load(tmp_path: Path) -> None:
    path = tmp_path / "k.yaml"
    path.write_text(keyframe_text(bounds.MAX_KEYFRAMES))
    assert len(rec.load(path, PLANAR2).frames) == bounds.MAX_KEYFRAMES


def test_a_path_with_two_samples_1e9_s_apart_is_refused_naming_the_duration(tmp_path: Path) -> None:
    path = tmp_path / "gap.csv"
    path.write_text("t [s],shoulder [rad],elbow [rad]\n0.0,0.0,0.0\n1000000000.0,0.1,0.1\n")
    with pytest.raises(RecordingError) as info:
        rec.load(path, PLANAR2)
    assert info.value.what == (f"{path}: the path lasts 1e+09 s (row 3 comes 1e+09 s after row 2), over the limit "
                               f"of 14 400 s (MAX_DURATION)")


def test_a_path_past_the_sample_limit_is_refused_before_any_row_is_read(tmp_path: Path) -> None:
    path = tmp_path / "long.csv"
    with path.open("w") as f:  # rows that are not even numbers: counted, never parsed
        f.write("t [s],shoulder [rad],elbow [rad]\n")
        f.write("x\n" * (bounds.MAX_PATH_SAMPLES + 1))
    with pytest.raises(RecordingError, match=r"more than 2 000 000 samples, over the limit of 2 000 000 samples "
                                             r"\(MAX_PATH_SAMPLES\)"):
        rec.load(path, PLANAR2)


def test_a_path_at_the_sample_limit_loads(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(rec, "MAX_PATH_SAMPLES", 1000)
    path = rec.PathRecording(PLANAR2, np.arange(1000) * 0.002, np.zeros((1000, 2))).save(tmp_path / "p.csv")
    assert len(rec.load(path, PLANAR2).t) == 1000
    rec.PathRecording(PLANAR2, np.arange(1001) * 0.002, np.zeros((1001, 2))).save(path)
    with pytest.raises(RecordingError, match="MAX_PATH_SAMPLES"):
        rec.load(path, PLANAR2)


# ---- telemetry -----------------------------------------------------------------------------------
def small_log(cycles: int = 5) -> telemetry.TelemetryLog:
    t = np.arange(cycles) * 0.002
    rng = np.random.default_rng(1)
    return telemetry.TelemetryLog(PLANAR2, t, *(rng.normal(size=(cycles, 2)) for _ in telemetry.FIELDS))


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_telemetry_reads_back_and_is_refused_past_its_values(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                             suffix: str) -> None:
    path = small_log().save(tmp_path / f"log{suffix}")
    back = telemetry.load(path)
    np.testing.assert_allclose(back.tau_ext, small_log().tau_ext, rtol=1e-8)
    monkeypatch.setattr(telemetry, "MAX_TELEMETRY_VALUES", 5 * 15 - 1)  # 5 cycles of 1 + 7 x 2 values
    with pytest.raises(RecordingError, match="over the limit of 74 values \\(MAX_TELEMETRY_VALUES\\)"):
        telemetry.load(path)


def test_an_npz_whose_header_promises_more_than_it_holds_is_refused_before_allocating(tmp_path: Path) -> None:
    path = small_log().save(tmp_path / "log.npz")
    with zipfile.ZipFile(path) as z:
        members = {name: z.read(name) for name in z.namelist()}
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": (10 ** 12,)})
    members["t.npy"] = header.getvalue() + members["t.npy"][len(header.getvalue()):]  # 8 TB promised
    with zipfile.ZipFile(path, "w") as z:
        for name, data in members.items():
            z.writestr(name, data)
    with pytest.raises(RecordingError, match=r"its array 't\.npy' is not what its header says"):
        telemetry.load(path)


def test_telemetry_that_is_not_telemetry(tmp_path: Path) -> None:
    path = tmp_path / "x.csv"
    path.write_text("t [s],a,b\n0,1,2\n")
    with pytest.raises(RecordingError, match="not an akarm telemetry CSV"):
        telemetry.load(path)
    path = tmp_path / "x.npz"
    path.write_bytes(b"PK not a zip")
    with pytest.raises(RecordingError, match="cannot read the telemetry file"):
        telemetry.load(path)


def test_a_telemetry_file_of_no_joint_or_too_many_is_refused(tmp_path: Path) -> None:
    for joints in (0, 65):
        names = tuple(f"j{k}" for k in range(joints))
        z = np.zeros((3, joints))
        log = telemetry.TelemetryLog(names, np.arange(3) * 0.002, z, z, z, z, z, z, z)
        for suffix in (".csv", ".npz"):
            path = log.save(tmp_path / f"{joints}{suffix}")
            what = "has no joints" if joints == 0 else \
                "has 65 joints, over the limit of 64 joints (MAX_TELEMETRY_JOINTS)"
            with pytest.raises(RecordingError, match=f"{path.name}: the telemetry file {re.escape(what)}"):
                telemetry.load(path)


# ---- the limits, documented in one place ---------------------------------------------------------
def test_the_readmes_limits_table_holds_every_limit_with_its_value() -> None:
    from akarm import files
    from akarm.datasets import lerobot
    from akarm.robotfile import nodes
    from akarm.telemetry import mcap
    from akarm.teleop import pairing

    constants = {name: getattr(module, name) for module in (files, nodes, urdf_mod, motors, rec, bounds, telemetry)
                 for name in dir(module) if name.startswith("MAX_") and isinstance(getattr(module, name), int | float)}
    constants.pop("MAX_TRAJECTORY_POINTS")  # a planner's bound (akarm.motion.bounds), not a file's
    constants["MAX_PARQUET_BYTES"] = lerobot.MAX_PARQUET_BYTES
    constants.update(MAX_MAP_BYTES=pairing.MAX_MAP_BYTES, MAX_MAP_NODES=pairing.MAX_MAP_NODES)
    constants.update(MAX_MCAP_BYTES=mcap.MAX_MCAP_BYTES, MAX_MCAP_CHUNK_BYTES=mcap.MAX_MCAP_CHUNK_BYTES)
    text = (ROOT / "docs" / "file-limits.md").read_text(encoding="utf-8")
    rows = text.split("<!-- limits:", 1)[1].split("\n\n", 1)[0].splitlines()[3:]  # after the comment and header
    units = {"MiB": 1 << 20, "h": 3600}
    table = {}
    for row in rows:
        _, _, limit, name = (cell.strip() for cell in row.strip("|").split("|"))
        amount, unit = (limit.rsplit(" ", 1) if limit.split()[-1] in units else (limit, ""))
        table[name.strip("`")] = float(amount.replace(" ", "")) * units.get(unit, 1)
    assert table == constants
