"""One command line, parsed: negative values without `--`, targets as poses, values or named joints,
former option names, one word per meaning (the verbs run: tests/system/test_cli_options.py)."""

from __future__ import annotations

import math

import pytest

from akarm.cli import VERBS, build_parser, main

from .conftest import ROBOTS

PLANAR2 = str(ROBOTS / "planar2.yaml")
ARM6 = str(ROBOTS / "arm6.yaml")


def parse(argv: list[str]):
    return build_parser().parse_args(argv)


def test_negative_values_need_no_double_dash_and_options_after_them_parse() -> None:
    for words in (["-0.1,0.2"], ["-0.1", "0.2"], ["-.5,-.5"], ["elbow=-0.2"], ["shoulder=-1e-3", "elbow=-0.2"]):
        args = parse(["move", PLANAR2, *words, "--speed", "0.5", "--hold", "1"])
        assert args.target == words and args.speed == 0.5 and args.hold == 1.0
    args = parse(["move", PLANAR2, "-1.2,0.3", "-i", "virtual", "-c", "x"])
    assert args.target == ["-1.2,0.3"] and args.interface == "virtual"


def test_targets_are_read_as_poses_values_or_named_joints() -> None:
    from akarm.cli.move import parse_target
    from akarm.errors import ArgumentError
    from akarm.robotfile.load import load_robot

    arm6 = load_robot(ARM6)
    assert parse_target(["ready"], arm6) == "ready"
    assert parse_target(["0,0.1,0.2,0,0,-0.3"], arm6) == [0, 0.1, 0.2, 0, 0, -0.3]
    assert parse_target(["0", "0.1", "0.2", "0", "0", "-0.3"], arm6) == [0, 0.1, 0.2, 0, 0, -0.3]
    assert parse_target(["elbow=0.5", "wrist_pitch=-0.2"], arm6) == {"elbow": 0.5, "wrist_pitch": -0.2}
    ready = list(arm6.pose("ready"))
    ready[2] = 1.0
    assert parse_target(["ready", "elbow=1.0"], arm6) == ready
    with pytest.raises(ArgumentError, match=r"no pose named 'redy' \(did you mean 'ready'\?\)"):
        parse_target(["redy"], arm6)
    with pytest.raises(ArgumentError, match=r"no joint named 'elbw' \(did you mean 'elbow'\?\)"):
        parse_target(["elbw=0.5"], arm6)
    with pytest.raises(ArgumentError, match="'x' is not a number"):
        parse_target(["elbow=x"], arm6)
    with pytest.raises(ArgumentError, match="2 value"):
        parse_target(["0.1,0.2"], arm6)


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
    # every verb that runs a control loop takes the watchdog's stall limit; the simulator runs none
    for verb in ("move", "enable", "teach", "replay", "serve", "teleop", "demo", "bench"):
        assert "--stall-limit" in options[verb], verb
    assert "--stall-limit" not in options["sim"]
    assert "--sample-rate" in options["teach"] and "--plant-rate" in options["sim"]
    # every verb that takes a robot file takes the bus overrides, bench included
    for verb in VERBS:
        if verb in ("demo", "plot", "init"):
            continue
        assert {"-i", "-c", "-b", "--bus-kwargs"} <= options[verb], verb


def test_the_stall_limit_reaches_the_arm_with_the_profile() -> None:
    from akarm.cli.common import loop_options

    args = build_parser().parse_args(["move", "robots/arm6.yaml", "ready", "--stall-limit", "0.5", "--profile", "slow"])
    assert loop_options(args) == {"timing": "slow", "stall_limit": 0.5}
    args = build_parser().parse_args(["replay", "robots/arm6.yaml", "x.yaml"])
    assert loop_options(args) == {"timing": "normal", "stall_limit": None}  # None: the profile's


def test_the_arm_id_names_the_physical_arm_on_verbs_that_drive_one() -> None:
    """Issue 39: the remembered positions are the physical arm's (``--id``, as LeRobot's --robot.id);
    teleop drives two arms, each keyed by its own buses and channels."""
    from akarm.cli.common import loop_options

    options = {verb: {o for a in build_parser()._subparsers._group_actions[0].choices[verb]._actions  # type: ignore
                      for o in a.option_strings} for verb in VERBS}
    for verb in ("move", "enable", "teach", "replay", "serve", "demo", "bench"):
        assert "--id" in options[verb], verb
    assert "--id" not in options["teleop"] and "--id" not in options["sim"]
    args = build_parser().parse_args(["enable", "robots/arm6.yaml", "--id", "left_follower"])
    assert loop_options(args) == {"timing": "normal", "stall_limit": None, "arm_id": "left_follower"}


# ----------------------------------------------------------------------------- values: durations, coordinates, buses


@pytest.mark.parametrize(("argv", "message"), [
    (["zero", PLANAR2, "elbow", "--wait", "nan"], "argument --wait: 'nan' is not a finite number of seconds, at "
                                                  "least 0"),
    (["zero", PLANAR2, "elbow", "--wait", "inf"], "argument --wait: 'inf' is not a finite number of seconds"),
    (["zero", PLANAR2, "elbow", "--wait", "-1"], "argument --wait: '-1' is not a finite number of seconds"),
    (["zero", PLANAR2, "elbow", "--timeout", "0"], "argument --timeout: '0' is not a finite number of seconds, more "
                                                    "than 0"),
    (["zero", PLANAR2, "elbow", "--timeout", "nan"], "argument --timeout: 'nan' is not a finite number of seconds"),
    (["status", PLANAR2, "--watch", "--interval", "inf"], "argument --interval: 'inf' is not a finite number of "
                                                          "seconds, more than 0"),
    (["status", PLANAR2, "--watch", "--interval", "1e300"], "argument --interval: '1e300' is not a finite number of "
                                                            "seconds, more than 0 and at most 604800"),
    (["status", PLANAR2, "--timeout", "nan"], "argument --timeout: 'nan' is not a finite number of seconds"),
    (["status", PLANAR2, "--timeout", "-1"], "argument --timeout: '-1' is not a finite number of seconds"),
    (["status", PLANAR2, "--watch", "--count", "0"], "argument --count: '0' is not a whole number, at least 1"),
    (["status", PLANAR2, "--watch", "--count", "-1"], "argument --count: '-1' is not a whole number, at least 1"),
    (["scan", "--timeout", "nan"], "argument --timeout: 'nan' is not a finite number of seconds, at least 0"),
    (["scan", "--timeout", "inf"], "argument --timeout: 'inf' is not a finite number of seconds"),
    (["scan", "--listen", "nan"], "argument --listen: 'nan' is not a finite number of seconds"),
    (["disable", PLANAR2, "--timeout", "-1"], "argument --timeout: '-1' is not a finite number of seconds, more "
                                              "than 0"),
    (["disable", PLANAR2, "--timeout", "nan"], "argument --timeout: 'nan' is not a finite number of seconds"),
    (["move", PLANAR2, "home", "-b", "-5"], "argument -b/--bitrate: bitrate must be a whole number within "
                                            "10000..1000000, got -5 (AK drivers use 1000000 bit/s)"),
    (["check", PLANAR2, "-b", "0"], "argument -b/--bitrate: bitrate must be a whole number within 10000..1000000, "
                                    "got 0"),
    (["status", PLANAR2, "-b", "1e6"], "argument -b/--bitrate: bitrate must be a whole number within 10000..1000000, "
                                       "got '1e6'"),
    (["check", PLANAR2, "-i", "nosuchiface"], "argument -i/--interface: 'nosuchiface' is not a python-can interface "
                                              "(python-can interfaces: "),
    (["move", PLANAR2, "home", "-i", "socketcn"], "argument -i/--interface: 'socketcn' is not a python-can interface "
                                                  "(did you mean 'socketcan'?)"),
    (["teleop", PLANAR2, PLANAR2, "-b", "-1"], "argument -b/--bitrate: bitrate must be a whole number"),
    # every verb's durations (--hold inf held for ever after the move; --zero-silence -1 was taken)
    (["move", PLANAR2, "up", "--hold", "inf"], "argument --hold: 'inf' is not a finite number of seconds, at least 0"),
    (["move", PLANAR2, "up", "--stall-limit", "nan"], "argument --stall-limit: 'nan' is not a finite number"),
    (["sim", PLANAR2, "--zero-silence", "-1"], "argument --zero-silence: '-1' is not a finite number of seconds"),
    (["sim", PLANAR2, "--servo-release", "nan"], "argument --servo-release: 'nan' is not a finite number"),
    (["sim", PLANAR2, "--seconds", "-1"], "argument --seconds: '-1' is not a finite number of seconds"),
    (["enable", PLANAR2, "--seconds", "inf"], "argument --seconds: 'inf' is not a finite number of seconds"),
    (["bench", PLANAR2, "--seconds", "0"], "argument --seconds: '0' is not a finite number of seconds, more than 0"),
    (["teach", PLANAR2, "out.yaml", "--seconds", "nan"], "argument --seconds: 'nan' is not a finite number"),
    (["identify", PLANAR2, "--seconds", "inf"], "argument --seconds: 'inf' is not a finite number"),
    (["serve", PLANAR2, "--feedback-timeout", "0"], "argument --feedback-timeout: '0' is not a finite number of "
                                                     "seconds, more than 0"),
    (["move", PLANAR2, "--xyz", "nan", "0", "0.3"], "argument --xyz: 'nan' is not a finite number"),
    (["move", PLANAR2, "--xyz", "0.3", "0", "0.3", "--rpy", "0", "inf", "0"], "argument --rpy: 'inf' is not a finite "
                                                                             "number"),
])
def test_bad_option_values_are_refused_while_parsing(argv: list[str], message: str,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """Refused by argparse: before the robot file is read, a bus opened or a frame sent."""
    with pytest.raises(SystemExit) as e:
        main(argv)
    err = capsys.readouterr().err
    assert e.value.code == 2 and message in err and "Traceback" not in err


def test_a_zero_wait_is_a_duration_the_probe_checks_too() -> None:
    from akarm.control.probe import Probe
    from akarm.errors import ArgumentError
    from akarm.robotfile.load import load_robot

    config = load_robot(PLANAR2).with_bus(interface="virtual", channel="zero-args")
    with Probe(config, ["elbow"]) as probe:
        with pytest.raises(ArgumentError, match=r"zero wait must be a finite number \(s\), at least 0, got inf"):
            probe.zero("elbow", wait=math.inf)
        with pytest.raises(ArgumentError, match=r"zero timeout must be a finite number \(s\), more than 0, got nan"):
            probe.zero("elbow", timeout=math.nan)


@pytest.mark.parametrize(("options", "message"), [
    (["--amplitude", "nan"], r"--amplitude must be a finite number \(rad\), more than 0 and at most 3.14159, got nan"),
    (["--amplitude", "4"], r"--amplitude must be a finite number \(rad\), more than 0 and at most 3.14159, got 4.0"),
    (["--seconds", "5"], r"--seconds must be a finite number \(s\), at least 8 and at most 600, got 5.0"),
    # issue 41: a torque scale needs a known weight (else a lighter link and a stronger motor are the same data)
    (["--torque-scale"], r"--torque-scale needs a known weight"),
    (["--torque-scale", "--weight", "0"], r"--weight must be a finite number \(kg\), more than 0"),
    (["--torque-scale", "--weight", "0.5", "--weight-com", "0.1,0"], r"--weight-com must be three numbers"),
    (["--weight", "0.5"], r"--weight is for --torque-scale"),
    (["--reach", "0,0.6,0.9"], r"--reach is for --torque-scale"),
    (["--torque-scale", "--weight", "0.5", "--reach", "0,x"], r"--reach must be a pose's name or joint positions"),
    (["--center", "0,x"], r"--center must be a pose's name or joint positions"),
])
def test_identify_checks_its_excitation_before_opening_the_arm(options: list[str], message: str,
                                                                capsys: pytest.CaptureFixture[str],
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    import re

    from akarm.arm import Arm

    def refuse(self: Arm) -> Arm:
        raise AssertionError("the arm was opened (and would be enabled) before the options were checked")

    monkeypatch.setattr(Arm, "open", refuse)
    assert main(["identify", PLANAR2, "-i", "virtual", "-c", "identify-options", *options]) == 1
    err = capsys.readouterr().err
    assert re.search(message, err) and "(fix: " in err and "Traceback" not in err
