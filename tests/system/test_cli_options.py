"""One command line: named-joint targets, names checked with a did-you-mean, output files checked
before anything moves, negative values without `--`, one word per meaning, `-i/-c/-b` everywhere."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from akarm.cli import VERBS, build_parser, main

from .conftest import ROBOTS, ROOT
from .test_cli import HANGING, PLANAR2, bus, frames_received, relaxed, simulated  # noqa: F401 (relaxed: a fixture)

ARM6 = str(ROBOTS / "arm6.yaml")


def parse(argv: list[str]):
    return build_parser().parse_args(argv)


# ----------------------------------------------------------------------------- move targets


def test_negative_values_need_no_double_dash_and_options_after_them_parse() -> None:
    for words in (["-0.1,0.2"], ["-0.1", "0.2"], ["-.5,-.5"], ["elbow=-0.2"], ["shoulder=-1e-3", "elbow=-0.2"]):
        args = parse(["move", PLANAR2, *words, "--speed", "0.5", "--hold", "1"])
        assert args.target == words and args.speed == 0.5 and args.hold == 1.0
    args = parse(["move", PLANAR2, "-1.2,0.3", "-i", "virtual", "-c", "x"])
    assert args.target == ["-1.2,0.3"] and args.interface == "virtual"


def test_targets_are_read_as_poses_values_or_named_joints() -> None:
    from akarm.cli.move import parse_target
    from akarm.errors import ConfigError, LimitError
    from akarm.robotfile.load import load_robot

    arm6 = load_robot(ARM6)
    assert parse_target(["ready"], arm6) == "ready"
    assert parse_target(["0,0.1,0.2,0,0,-0.3"], arm6) == [0, 0.1, 0.2, 0, 0, -0.3]
    assert parse_target(["0", "0.1", "0.2", "0", "0", "-0.3"], arm6) == [0, 0.1, 0.2, 0, 0, -0.3]
    assert parse_target(["elbow=0.5", "wrist_pitch=-0.2"], arm6) == {"elbow": 0.5, "wrist_pitch": -0.2}
    ready = list(arm6.pose("ready"))
    ready[2] = 1.0
    assert parse_target(["ready", "elbow=1.0"], arm6) == ready
    with pytest.raises(ConfigError, match=r"no pose named 'redy' \(did you mean 'ready'\?\)"):
        parse_target(["redy"], arm6)
    with pytest.raises(LimitError, match=r"no joint named 'elbw' \(did you mean 'elbow'\?\)"):
        parse_target(["elbw=0.5"], arm6)
    with pytest.raises(LimitError, match="'x' is not a number"):
        parse_target(["elbow=x"], arm6)
    with pytest.raises(LimitError, match="2 value"):
        parse_target(["0.1,0.2"], arm6)


def test_move_named_joints_moves_those_and_keeps_the_others(channel: str, relaxed: str,  # noqa: F811
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    with simulated(relaxed, channel, q0=HANGING) as sim:
        assert main(["move", relaxed, *bus(channel), "elbow=-0.3", "--speed", "0.8"]) == 0
        q = sim.q.copy()
    assert q[1] == pytest.approx(-0.3, abs=0.02)  # measured while damped and disabled: a little sag
    assert q[0] == pytest.approx(HANGING[0], abs=0.05)  # the shoulder stayed where it hung
    out = capsys.readouterr().out
    assert "moving to elbow=-0.3 [" in out and "arrived" in out


@pytest.mark.parametrize(("words", "message"), [
    (["hme"], "no pose named 'hme' (did you mean 'home'?)"),
    (["elbw=0.2"], "no joint named 'elbw' (did you mean 'elbow'?)"),
    (["home", "--log", "run.txt"], "cannot save telemetry as 'run.txt': the name must end in .csv or .npz"),
    (["home", "--log", "robot.yaml/run.csv"], "cannot create directory robot.yaml: robot.yaml is not a directory"),
    (["elbow=3.0"], "target +3.0000 rad is outside"),
])
def test_bad_names_and_output_files_are_refused_before_anything_moves(
        words: list[str], message: str, channel: str, relaxed: str,  # noqa: F811
        capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "robot.yaml").write_text("a file, not a folder")
    with simulated(relaxed, channel, q0=HANGING) as sim:
        assert main(["move", relaxed, *bus(channel), *words]) == 1
        assert frames_received(sim) == 0  # not a frame sent
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_replay_checks_its_log_file_first(channel: str, relaxed: str, tmp_path: Path,  # noqa: F811
                                          capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "k.yaml"
    path.write_text("robot: planar2\njoints: [shoulder, elbow]\nkeyframes:\n  - {q: [0.1, 0.1]}\n")
    with simulated(relaxed, channel, q0=HANGING) as sim:
        assert main(["replay", relaxed, *bus(channel), str(path), "--log", str(tmp_path / "x.png")]) == 1
        assert frames_received(sim) == 0
    assert "cannot save telemetry as" in capsys.readouterr().err


# ----------------------------------------------------------------------------- option names


@pytest.mark.parametrize(("argv", "new"), [
    (["sim", PLANAR2, "--duration", "1"], "--seconds"),
    (["sim", PLANAR2, "--rate", "1000"], "--plant-rate"),
    (["check", PLANAR2, "--rate", "250"], "--loop-rate"),
    (["check", PLANAR2, "-r", "250"], "--loop-rate"),
    (["bench", PLANAR2, "--rate", "250"], "--loop-rate"),
    (["teach", PLANAR2, "out.csv", "--rate", "20"], "--sample-rate"),
])
def test_former_option_names_say_the_new_one(argv: list[str], new: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2 and f"is now {new}" in capsys.readouterr().err


def test_one_word_per_meaning_across_verbs() -> None:
    options = {verb: {o for a in build_parser()._subparsers._group_actions[0].choices[verb]._actions  # type: ignore
                      for o in a.option_strings if a.help != "==SUPPRESS=="} for verb in VERBS}
    everything = set().union(*options.values())
    assert "--duration" not in everything and "--rate" not in everything
    for verb in ("sim", "enable", "teach", "bench"):
        assert "--seconds" in options[verb]
    assert "--loop-rate" in options["check"] and "--loop-rate" in options["bench"]
    assert "--sample-rate" in options["teach"] and "--plant-rate" in options["sim"]
    # every verb that takes a robot file takes the bus overrides, bench included
    for verb in VERBS:
        if verb in ("demo", "plot", "init"):
            continue
        assert {"-i", "-c", "-b", "--bus-kwargs"} <= options[verb], verb


def test_bench_runs_on_the_bus_it_is_given(channel: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", PLANAR2, "--seconds", "1", "--in-process", "-i", "virtual", "-c", channel]) == 0
    assert "moves in" in capsys.readouterr().out


# ----------------------------------------------------------------------------- the checkout


def test_the_demo_plot_is_not_left_in_a_clean_checkout() -> None:
    """`akarm demo` writes akarm-demo.png into the current folder (the README's quick start: the clone)."""
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    r = subprocess.run(["git", "check-ignore", "-q", "akarm-demo.png"], cwd=ROOT)
    assert r.returncode == 0, "akarm-demo.png is not ignored by git"
    r = subprocess.run(["git", "check-ignore", "-q", "docs/demo.png"], cwd=ROOT)
    assert r.returncode == 1  # the README's image itself stays tracked
