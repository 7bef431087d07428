"""The compiled cycle: which of akarm's modules are compiled at install, and which this process runs.

The modules the control loop runs every cycle (the loop, the controller, the joints, the supervisor,
the collision reflex, the feed-forward, telemetry) are compiled to C with mypyc when
akarm is installed (``setup.py``), if the machine has a C compiler and Python's headers. The same
Python files stay beside them and are what runs wherever nothing was compiled: one source, two ways
to run it, and the tests pass both ways.

- ``AKARM_PURE=1`` while installing: nothing is compiled.
- ``AKARM_PURE=1`` while running: the pure-Python modules are loaded even where compiled ones are
  installed (a debugger, a profiler or coverage sees into them; a bug is told apart from the compiler).
- A compiled module older than its source (edited since the install compiled it) would run the old
  code: then the whole cycle runs pure Python, with a warning, until akarm is installed again.
- :func:`status` says which of the two this process runs; ``akarm --version`` and ``akarm bench``
  print it.

This module imports nothing of akarm's, and nothing outside the standard library: ``setup.py`` reads
:data:`MODULES` from it before anything is installed.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import os
import sys
import warnings
from collections.abc import Mapping, Sequence
from types import ModuleType

__all__ = ["GROUP", "MODULES", "PURE_ENV", "STALE_SLACK", "choose_at_import", "compiled_file", "compiled_modules",
           "pure_reason", "pure_requested", "source_file", "stale_modules", "status"]

#: the modules compiled at install: those the control cycle runs, each whole (mypyc compiles a module
#: or not). The codecs stay pure Python (their public functions take a caller's values of any type and
#: name a wrong one in an ArgumentError, where a compiled signature would raise TypeError first); so
#: does the local bus, whose class is python-can's BusABC's: the build does not see python-can
#: (setup.py), and a compiled class over a base it cannot see crashes the process
#: (tests/unit/test_compiled.py keeps every class here over akarm's or the standard library's)
MODULES: tuple[str, ...] = (
    "akarm.timing",
    "akarm.telemetry.log",
    "akarm.buses.frames",
    "akarm.dynamics.model",
    "akarm.control.modes",
    "akarm.control.reading",
    "akarm.control.turns",
    "akarm.control.joints",
    "akarm.control.safety",
    "akarm.control.collision",
    "akarm.control.feedforward",
    "akarm.control.busset",
    "akarm.control.loop",
    "akarm.control.controller",
)

#: the compiled modules share one C library, ``akarm/_cycle__mypyc…so``
GROUP = "akarm._cycle"

#: the environment variable that asks for pure Python: at install (compile nothing) and when running
PURE_ENV = "AKARM_PURE"


def pure_requested(environ: Mapping[str, str] | None = None) -> bool:
    """Whether ``AKARM_PURE`` asks for pure Python (set, and not ``0`` or empty)."""
    value = (os.environ if environ is None else environ).get(PURE_ENV, "")
    return value.strip() not in ("", "0")


class PureFinder(importlib.abc.MetaPathFinder):
    """Finds each of :data:`MODULES` as its ``.py`` file, ahead of a compiled module beside it."""

    def find_spec(self, fullname: str, path: Sequence[str] | None,
                  target: ModuleType | None = None) -> importlib.machinery.ModuleSpec | None:
        if fullname not in MODULES or not path:
            return None
        leaf = fullname.rpartition(".")[2] + ".py"
        for folder in path:
            source = os.path.join(folder, leaf)
            if os.path.isfile(source):
                return importlib.util.spec_from_file_location(fullname, source)
        return None


#: a source newer than its compiled module by more than this, s, was edited after the build (a wheel
#: unpacks both within moments of each other, in any order)
STALE_SLACK = 2.0

_reason: list[str] = []  # why this process runs pure Python though compiled modules may be there


def install_pure_finder(reason: str) -> None:
    """Put :class:`PureFinder` first on ``sys.meta_path`` (once), saying why. Called by
    ``akarm/__init__.py`` before any of :data:`MODULES` is imported."""
    if not any(isinstance(f, PureFinder) for f in sys.meta_path):
        sys.meta_path.insert(0, PureFinder())
        _reason.append(reason)


def pure_reason() -> str | None:
    """Why this process runs the cycle pure Python on purpose (``AKARM_PURE=1``, or compiled modules
    older than their sources), or ``None``."""
    return _reason[0] if _reason else None


def source_file(name: str, package_dir: str | None = None) -> str:
    """The Python file of module ``name`` (``akarm.…``) in the ``akarm`` package at ``package_dir``
    (default this one's), found without importing it."""
    root = os.path.dirname(os.path.abspath(__file__)) if package_dir is None else package_dir
    return os.path.join(root, *name.split(".")[1:]) + ".py"


def compiled_file(source: str) -> str | None:
    """The compiled module beside the Python file ``source`` (any of this Python's extension
    suffixes), or ``None``."""
    stem = source[:-len(".py")]
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        if os.path.isfile(stem + suffix):
            return stem + suffix
    return None


def stale_modules(package_dir: str | None = None) -> tuple[str, ...]:
    """Those of :data:`MODULES` whose compiled module is older than its source (looked up beside the
    sources of the ``akarm`` package in ``package_dir``, default this one's; nothing imported)."""
    stale = []
    for name in MODULES:
        source = source_file(name, package_dir)
        built = compiled_file(source)
        try:
            if built is not None and os.path.getmtime(source) > os.path.getmtime(built) + STALE_SLACK:
                stale.append(name)
        except OSError:
            continue
    return tuple(stale)


def choose_at_import() -> None:
    """Run the cycle pure Python where ``AKARM_PURE=1`` asks, or where a compiled module is older than
    its source (warning then: running the old code would be worse than running slower). Called by
    ``akarm/__init__.py`` before any of :data:`MODULES` is imported."""
    if pure_requested():
        install_pure_finder(f"{PURE_ENV}=1")
        return
    stale = stale_modules()
    if stale:
        install_pure_finder(f"the compiled modules are older than their sources: {', '.join(stale)}; install "
                            "akarm again (pip install -e .) to compile them")
        warnings.warn(f"akarm: the cycle runs pure Python: {pure_reason()}", RuntimeWarning, stacklevel=3)


def _is_compiled(module: ModuleType) -> bool:
    return isinstance(getattr(module, "__loader__", None), importlib.machinery.ExtensionFileLoader)


def compiled_modules() -> tuple[str, ...]:
    """Which of :data:`MODULES` this process runs compiled (imports them all)."""
    return tuple(name for name in MODULES if _is_compiled(importlib.import_module(name)))


def status() -> str:
    """One line: whether this process runs the cycle compiled, and why not if it does not."""
    done = compiled_modules()
    if len(done) == len(MODULES):
        return f"compiled (mypyc): all {len(MODULES)} modules of the cycle"
    reason = pure_reason()
    if reason is not None:
        return f"pure Python ({reason})"
    if done:
        return (f"partly compiled: {len(done)} of {len(MODULES)} modules (an install left half done? "
                f"reinstall akarm)")
    return ("pure Python: nothing was compiled at install (no C compiler or Python headers, or "
            f"{PURE_ENV}=1 then); the cycle costs 10-25 % more CPU")
