"""The control socket's requests checked against their operations, its errors carried across, and a
latched stop's refusal: pure logic (no socket, no server running)."""

from __future__ import annotations

import contextlib
import json
import math
import sys
import traceback
from collections.abc import Mapping

import pytest

from akarm.errors import (
    AkarmError,
    ArgumentError,
    ConfigError,
    ConfigProblem,
    FeedbackTimeout,
    MotorFault,
    StopLatched,
)
from akarm.server.ops import Operation
from akarm.server.server import ArmServerCore, LatchedStop, copy_error
from akarm.server.socket import error_doc, rebuild_error


def _op(target: str | list[float] | Mapping[str, float], speed: float = 1.0, client: int | None = None) -> None:
    """A stand-in operation with the server's kinds of arguments."""


def _wait(id: int, name: str | None = None, flag: bool = False) -> None:
    """Another."""


MOVE = Operation("move", _op)
WAIT = Operation("wait", _wait)


@pytest.mark.parametrize(("args", "message"), [
    ({}, "operation 'move' needs the argument 'target'"),
    ({"target": "home", "sped": 1.0}, "operation 'move' has no argument 'sped'"),
    ({"target": "home", "client": 3}, "has no argument 'client'"),  # the server's own: not a request's
    ({"target": 5}, "argument 'target' of 'move' must be text, a list of numbers or an object of numbers, not 5"),
    ({"target": [0.1, "x"]}, "argument 'target' of 'move' item 1 must be a number, not text"),
    ({"target": [[0.1]]}, "argument 'target' of 'move' item 0 must be a number, not a list"),
    ({"target": {"elbow": None}}, "argument 'target' of 'move' entry 'elbow' must be a number, not null"),
    ({"target": "home", "speed": "fast"}, "argument 'speed' of 'move' must be a number, not text"),
    ({"target": "home", "speed": True}, "argument 'speed' of 'move' must be a number, not true"),
    ({"target": "home", "speed": math.nan}, "argument 'speed' of 'move' must be a finite number, not nan"),
    ({"target": "home", "speed": math.inf}, "argument 'speed' of 'move' must be a finite number, not inf"),
    ({"target": "x" * 5000}, "argument 'target' of 'move' must be at most 4096 characters"),
])
def test_a_bad_argument_is_an_argument_error_that_names_it(args, message):
    with pytest.raises(ArgumentError) as e:
        MOVE.check(args)
    assert message in str(e.value)
    for internal in ("TypeError", "KeyError", "JSONDecodeError"):
        assert internal not in str(e.value)


def test_whole_numbers_booleans_and_null_are_told_apart():
    assert WAIT.check({"id": 3, "name": None, "flag": False}) == {"id": 3, "name": None, "flag": False}
    with pytest.raises(ArgumentError, match=r"argument 'id' of 'wait' must be a whole number, not 1\.5"):
        WAIT.check({"id": 1.5})
    with pytest.raises(ArgumentError, match="argument 'id' of 'wait' must be a whole number, not true"):
        WAIT.check({"id": True})
    with pytest.raises(ArgumentError, match="within ±2\\*\\*53"):
        WAIT.check({"id": 2**70})
    with pytest.raises(ArgumentError, match="argument 'flag' of 'wait' must be true or false, not 1"):
        WAIT.check({"id": 1, "flag": 1})


def test_good_arguments_pass_as_they_are():
    assert MOVE.check({"target": [0.1, -2]}) == {"target": [0.1, -2]}
    assert MOVE.check({"target": {"elbow": 0.5}, "speed": 0.5}) == {"target": {"elbow": 0.5}, "speed": 0.5}
    assert MOVE.describe() == {"target": "text, a list of numbers or an object of numbers",
                               "speed": "a number (optional)"}


def test_every_server_operation_has_a_contract_a_request_can_meet():
    from akarm.server.server import _operations

    ops = _operations(ArmServerCore)  # built from the signatures: an annotation JSON cannot carry fails here
    assert {"state", "status", "move", "wait", "sleep", "ready", "enable", "disable", "describe"} <= set(ops)
    with pytest.raises(ArgumentError, match="argument 'seconds' of 'sleep' must be a finite number, not nan"):
        ops["sleep"].check({"seconds": math.nan})
    assert "client" not in ops["wait"].params and "client" not in ops["teach"].params


def test_errors_cross_the_socket_with_their_class_text_and_attributes():
    sent = FeedbackTimeout("no feedback for 21 ms (limit 20 ms)", age=0.021, limit=0.02, joint="elbow", fix="wiring")
    doc = json.loads(json.dumps(error_doc(sent), allow_nan=False))
    got = rebuild_error(doc)
    assert type(got) is FeedbackTimeout and str(got) == str(sent)
    assert (got.age, got.limit, got.joint, got.fix) == (0.021, 0.02, "elbow", "wiring")
    fault = rebuild_error(error_doc(MotorFault("over-temperature", code=1, joint="elbow")))
    assert type(fault) is MotorFault and fault.code == 1
    bad = ConfigError([ConfigProblem("arm.yaml", 3, "no motor", "add one")])
    assert str(rebuild_error(error_doc(bad))) == str(bad)  # a constructor of its own: rebuilt all the same
    unknown = rebuild_error({"type": "NoSuchError", "what": "x"})
    assert type(unknown) is AkarmError and str(unknown) == "x"


def test_a_private_error_class_crosses_as_its_public_parent():
    class _Mine(ArgumentError):
        pass

    assert error_doc(_Mine("bad"))["type"] == "ArgumentError"


def _raised(e: BaseException) -> BaseException:
    try:
        raise e
    except BaseException as caught:
        return caught


def test_a_latched_stop_is_refused_with_a_new_error_each_time_and_the_stop_never_grows():
    stop = FeedbackTimeout("no feedback for 500 ms (limit 500 ms); the arm was damped and disabled", age=0.5,
                           limit=0.5, joint="elbow", fix="check the motor's power")
    latched = LatchedStop(stop, 1_700_000_000.25, 1)
    first, second = latched.refusal(), latched.refusal()
    assert first is not second and isinstance(first, StopLatched)
    assert (first.stop, first.time, first.joint) == ("FeedbackTimeout", 1_700_000_000.25, "elbow")
    assert "FeedbackTimeout: no feedback for 500 ms" in str(first) and "latched" in str(first)
    assert "akarm enable" in first.fix and "akarm/enable" in first.fix and "check the motor's power" in first.fix
    assert latched.as_dict()["error"] == "FeedbackTimeout" and latched.as_dict()["joint"] == "elbow"
    for _ in range(50):  # what each refusal and each waiting client gets: copies; the stop itself is never raised
        _raised(latched.refusal())
        copy = _raised(latched.copy())
    assert type(copy) is FeedbackTimeout and str(copy) == str(stop) and copy.age == 0.5
    assert stop.__traceback__ is None, "the kept stop was never raised, so it holds no frames"
    assert len(traceback.extract_tb(copy.__traceback__)) == 1, "each copy has only its own raise"


def test_raising_one_exception_again_grows_its_traceback_so_the_server_copies_it():
    """Why copies: the behaviour the issue saw (~2 KB per refused trajectory)."""
    kept = FeedbackTimeout("x", age=1.0)

    def again() -> None:
        raise kept

    for _ in range(20):
        with contextlib.suppress(FeedbackTimeout):
            again()
    assert len(traceback.extract_tb(kept.__traceback__)) >= 20
    assert len(traceback.extract_tb(_raised(copy_error(kept)).__traceback__)) == 1
    assert sys.getrefcount(kept) >= 2
