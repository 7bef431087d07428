"""The control socket's operations and their arguments, checked before anything runs.

An operation of the server is a method ``_op_NAME(self, arg: TYPE = DEFAULT, ...)``. Its signature
is the operation's contract: :class:`Operation` reads it once (names, annotations, defaults) and
checks every request against it, so a missing, unexpected or wrong-typed argument is refused with
an :class:`~akarm.ArgumentError` that names it, whatever the method does with it afterwards::

    move = Operation("move", ArmServerCore._op_move)
    move.check({"target": "home", "speed": 0.5})   # the arguments, as the method takes them
    move.check({"target": 5})                       # ArgumentError: argument 'target' of 'move' must be ...

The JSON types a request can carry map onto these annotations: ``float`` (a finite number: NaN and
infinities are refused), ``int`` (a whole number), ``str``, ``bool``, ``None``, ``list[X]`` /
``Sequence[X]`` (a JSON array), ``dict[str, X]`` / ``Mapping[str, X]`` (a JSON object) and unions
of them. A parameter named ``client`` is the server's own (which connection asks) and cannot be
given by a request.
"""

from __future__ import annotations

import collections.abc
import inspect
import math
import types
import typing
from collections.abc import Callable, Mapping
from typing import Any, Union

from akarm.errors import ArgumentError

__all__ = ["MAX_TEXT", "Operation", "describe"]

MAX_TEXT = 4096  #: characters a text argument may have (a path, a pose name, a keyframe name)
_INT_RANGE = 1 << 53  # whole numbers a JSON number carries exactly
_SERVER_SIDE = frozenset({"self", "client"})


def _origin(tp: Any) -> Any:
    return typing.get_origin(tp)


def _members(tp: Any) -> tuple[Any, ...]:
    """The members of a union (``X | Y``, ``Optional[X]``), or ``(tp,)``."""
    if _origin(tp) in (Union, types.UnionType):
        return typing.get_args(tp)
    return (tp,)


def _is_list(tp: Any) -> bool:
    return _origin(tp) in (list, collections.abc.Sequence)


def _is_map(tp: Any) -> bool:
    return _origin(tp) in (dict, collections.abc.Mapping)


def describe(tp: Any) -> str:
    """``tp`` in the words of a JSON request: ``"a number"``, ``"a list of numbers"``, ..."""
    members = _members(tp)
    if len(members) > 1:
        words = [describe(m) for m in members]
        return ", ".join(words[:-1]) + " or " + words[-1]
    if tp is Any:
        return "any JSON value"
    if tp is float:
        return "a number"
    if tp is int:
        return "a whole number"
    if tp is bool:
        return "true or false"
    if tp is str:
        return "text"
    if tp is type(None) or tp is None:
        return "null"
    if _is_list(tp):
        (item,) = typing.get_args(tp) or (Any,)
        return f"a list of {_plural(item)}"
    if _is_map(tp):
        args = typing.get_args(tp)
        return f"an object of {_plural(args[1] if len(args) == 2 else Any)}"
    return getattr(tp, "__name__", str(tp))


def _plural(tp: Any) -> str:
    return {float: "numbers", int: "whole numbers", str: "texts", bool: "true/false values"}.get(tp, describe(tp))


def _json_kind(value: object) -> str:
    """What a JSON value is, in the same words."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(value)[:40]
    if isinstance(value, str):
        return "text"
    if isinstance(value, list):
        return "a list"
    if isinstance(value, dict):
        return "an object"
    return type(value).__name__


def _scalar_problem(value: object, tp: Any) -> str | None:
    """Why ``value`` is not the scalar ``tp`` (float, int, bool, str, None), or ``None``."""
    if tp is float or tp is int:
        whole = tp is int
        if isinstance(value, bool) or not isinstance(value, int if whole else (int, float)):
            return f"must be {describe(tp)}, not {_json_kind(value)}"
        if whole:
            return None if -_INT_RANGE <= value <= _INT_RANGE else f"must be a whole number within ±2**53, not {value}"
        return None if math.isfinite(value) else f"must be a finite number, not {value!r}"
    if tp is str:
        if not isinstance(value, str):
            return f"must be text, not {_json_kind(value)}"
        if len(value) > MAX_TEXT:
            return f"must be at most {MAX_TEXT} characters, not {len(value)}"
        return None if "\x00" not in value else "must not hold a NUL character (no name or path does)"
    if tp is bool:
        return None if isinstance(value, bool) else f"must be true or false, not {_json_kind(value)}"
    if tp is type(None) or tp is None:
        return None if value is None else f"must be null, not {_json_kind(value)}"
    raise TypeError(f"an operation's parameter cannot be annotated {tp!r}")  # a bug of the server, at start


def _container_problem(value: object, tp: Any) -> str | None:
    """Why ``value`` is not the list or object type ``tp``, or ``None`` (each item checked)."""
    if _is_list(tp):
        if not isinstance(value, list):
            return f"must be {describe(tp)}, not {_json_kind(value)}"
        (item,) = typing.get_args(tp) or (Any,)
        items: list[tuple[str, object]] = [(f"item {k}", x) for k, x in enumerate(value)]
    else:
        if not isinstance(value, dict):
            return f"must be {describe(tp)}, not {_json_kind(value)}"
        args = typing.get_args(tp)
        item = args[1] if len(args) == 2 else Any
        items = [(f"entry {str(key)[:40]!r}", x) for key, x in value.items()]
    for where, x in items:
        p = _problem(x, item)
        if p is not None:
            return f"{where} {p}"
    return None


def _same_kind(value: object, tp: Any) -> bool:
    """True when ``value`` is the JSON kind ``tp`` describes (whatever its contents or size)."""
    if isinstance(value, list):
        return _is_list(tp)
    if isinstance(value, dict):
        return _is_map(tp)
    if isinstance(value, bool):
        return tp is bool
    if isinstance(value, int | float):
        return tp in (int, float)
    return isinstance(value, str) and tp is str


def _problem(value: object, tp: Any) -> str | None:
    """Why ``value`` is not a ``tp`` (a phrase), or ``None`` when it is one."""
    members = _members(tp)
    if len(members) > 1:
        problems = [_problem(value, m) for m in members]
        if any(p is None for p in problems):
            return None
        # the member of the same kind (a list for a list type, text for str): its own, more precise, problem
        for m, p in zip(members, problems, strict=True):
            if _same_kind(value, m):
                return p
        return f"must be {describe(tp)}, not {_json_kind(value)}"
    if tp is Any:
        return None
    if _is_list(tp) or _is_map(tp):
        return _container_problem(value, tp)
    return _scalar_problem(value, tp)


class Operation:
    """The operation ``name`` carried out by ``method`` (see the module's docstring).

    Attributes:
        name: the operation's name in requests.
        params: per argument, its annotation and whether a request must give it.
    """

    def __init__(self, name: str, method: Callable[..., Any]) -> None:
        self.name = name
        hints = typing.get_type_hints(method)
        self.params: dict[str, tuple[Any, bool]] = {}
        for p in inspect.signature(method).parameters.values():
            if p.name in _SERVER_SIDE:
                continue
            if p.kind not in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY):
                raise TypeError(f"operation {name!r}: parameter {p.name!r} must be a plain named one")
            tp = hints.get(p.name, Any)
            _problem(None, tp)  # refuses, now, an annotation a request could not carry
            self.params[p.name] = (tp, p.default is inspect.Parameter.empty)

    def check(self, args: Mapping[str, Any]) -> dict[str, Any]:
        """``args`` as keyword arguments for the method, once each is known, given when required and of
        its type. Raises :class:`~akarm.ArgumentError` naming the first argument that is not."""
        for key in args:
            if key not in self.params:
                known = ", ".join(self.params) or "none"
                raise ArgumentError(f"operation {self.name!r} has no argument {str(key)[:40]!r}",
                                    fix=f"its arguments are: {known}")
        for key, (tp, required) in self.params.items():
            if key not in args:
                if required:
                    raise ArgumentError(f"operation {self.name!r} needs the argument {key!r} ({describe(tp)})")
                continue
            problem = _problem(args[key], tp)
            if problem is not None:
                raise ArgumentError(f"argument {key!r} of {self.name!r} {problem}",
                                    fix=f"give {key!r} as {describe(tp)}")
        return dict(args)

    def describe(self) -> dict[str, str]:
        """Each argument and what it takes, for a client that asks (``optional`` where it may be left out)."""
        return {k: describe(tp) + ("" if required else " (optional)") for k, (tp, required) in self.params.items()}
