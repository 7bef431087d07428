"""Option handling the verbs share: python-can keyword arguments, renamed options, output files checked
before anything moves, positional values that may be negative, and the argparse types of durations
and counts (refused while the command line is parsed, before anything is loaded, opened or sent)."""

from __future__ import annotations

import argparse
import math
import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

__all__ = ["MAX_SECONDS", "TELEMETRY_SUFFIXES", "add_bus_kwargs", "bitrate", "check_output", "count", "delay",
           "duration", "finite", "interface", "negative_values_are_positional", "renamed"]

#: s, the longest duration an option takes (a week): more than any wait or run a verb is given, and far
#: below what a sleep can take (``time.sleep(1e300)`` raises OverflowError)
MAX_SECONDS = 7 * 24 * 3600.0


def _seconds(text: str, at_least: float | None, above: float | None) -> float:
    from akarm.errors import ArgumentError, finite_number

    try:
        value = float(text)
    except ValueError:
        value = math.nan
    try:
        return finite_number(value, repr(text), at_least=at_least, above=above, at_most=MAX_SECONDS, unit="s")
    except ArgumentError as e:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a finite number of seconds, {'more than' if above is not None else 'at least'} 0 "
            f"and at most {MAX_SECONDS:g} (a week)") from e


def duration(text: str) -> float:
    """argparse type of a duration option (a time-out, an interval, a run's length): a finite number of
    seconds more than 0, at most :data:`MAX_SECONDS`."""
    return _seconds(text, None, 0.0)


def delay(text: str) -> float:
    """argparse type of a pause that may be none (a time to listen, to wait): a finite number of
    seconds, at least 0, at most :data:`MAX_SECONDS`."""
    return _seconds(text, 0.0, None)


def interface(text: str) -> str:
    """argparse type of ``-i/--interface``: a python-can interface, checked as a bus's interface is
    wherever it comes from (:func:`akarm.config.canconfig.interface_problem`)."""
    from akarm.config.canconfig import interface_problem

    if (problem := interface_problem(text)) is not None:
        raise argparse.ArgumentTypeError(f"{problem[0]} ({problem[1]})")
    return text


def bitrate(text: str) -> int:
    """argparse type of ``-b/--bitrate``: a whole number of bit/s in the range a bus may have
    (:func:`akarm.config.canconfig.bitrate_problem`)."""
    from akarm.config.canconfig import bitrate_problem

    try:
        value: int | str = int(text)
    except ValueError:
        value = text
    if (problem := bitrate_problem(value)) is not None:
        raise argparse.ArgumentTypeError(f"{problem[0]} ({problem[1]})")
    return int(value)


def finite(text: str) -> float:
    """argparse type of a value that may be any finite number (a coordinate, an angle)."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


def count(text: str) -> int:
    """argparse type of a count (readings, episodes): a whole number, at least 1."""
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number, at least 1")
    return n


class _BusKwargs(argparse.Action):
    """``--bus-kwargs KEY=VALUE ...`` → a dict, values cast as python-can casts them."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: str | Sequence[Any] | None, option_string: str | None = None) -> None:
        from can.util import cast_from_string

        out = dict(getattr(namespace, self.dest, None) or {})
        for item in values if isinstance(values, list) else [values]:
            m = re.match(r"^([A-Za-z_][A-Za-z0-9_]*)=(.*)$", str(item))
            if not m:
                parser.error(f"{option_string}: {item!r} is not KEY=VALUE (e.g. app_name=akarm serial=1234)")
            out[m.group(1)] = cast_from_string(m.group(2))
        setattr(namespace, self.dest, out)


def add_bus_kwargs(parser: argparse.ArgumentParser) -> None:
    """``--bus-kwargs KEY=VALUE ...``: keyword arguments for python-can's bus, as python-can's own tools take them."""
    parser.add_argument("--bus-kwargs", nargs="+", action=_BusKwargs, default={}, metavar="KEY=VALUE",
                        help="more keyword arguments for python-can's bus, e.g. --bus-kwargs app_name=akarm "
                             "serial=1234 (as python-can's tools take them; values are cast like python-can's)")


class _Renamed(argparse.Action):
    """A former option name: says the new one instead of 'unrecognized arguments'."""

    def __init__(self, option_strings: Sequence[str], dest: str, new: str = "", **kwargs: Any) -> None:
        super().__init__(option_strings, dest=argparse.SUPPRESS, nargs="?", default=argparse.SUPPRESS,
                         help=argparse.SUPPRESS)
        self.new = new

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: str | Sequence[Any] | None, option_string: str | None = None) -> None:
        parser.error(f"{option_string} is now {self.new}")


def renamed(parser: argparse.ArgumentParser, old: str, new: str, *more: str) -> None:
    """Accept ``old`` (and ``more`` spellings) only to say that it is now ``new`` (exit status 2)."""
    parser.add_argument(old, *more, action=_Renamed, new=new)


#: the telemetry log types ``--log`` writes (by suffix)
TELEMETRY_SUFFIXES = (".csv", ".npz", ".mcap")


def check_output(path: str | os.PathLike[str] | None, suffixes: Sequence[str], what: str) -> Path | None:
    """An output file named on the command line, checked before anything moves: a known suffix, and a
    place it can be written (:func:`akarm.files.check_writable`). ``None`` passes through.

    Raises:
        RecordingError: naming the file, what is wrong and the fix.
    """
    from akarm.errors import RecordingError
    from akarm.files import check_writable

    if path is None:
        return None
    p = Path(path)
    if p.suffix.lower() not in suffixes:
        raise RecordingError(f"cannot save {what} as {str(p)!r}: the name must end in {' or '.join(suffixes)}",
                             fix=f"use a {' or '.join(suffixes)} file name")
    return check_writable(p)


#: a negative number, or comma-separated numbers starting with one ("-0.1", "-1e-3,0.2", "-.5,-.5")
_NEGATIVE_VALUES = re.compile(r"^-\.?\d[\d.eE+-]*(,[-+]?\.?\d[\d.eE+-]*)*$")


def negative_values_are_positional(parser: argparse.ArgumentParser) -> None:
    """Let ``-0.1`` and ``-0.1,0.2`` be positional values: argparse otherwise takes them for options.

    argparse treats a word that starts with ``-`` as an option unless it looks like a negative number
    and the parser has no option that does; comma-separated numbers do not look like one to it. The
    parser's options never look like numbers, so widening what counts as a number is safe.
    """
    if hasattr(parser, "_negative_number_matcher"):
        parser._negative_number_matcher = _NEGATIVE_VALUES  # private-ok: argparse offers no public setting for it
