"""Builds akarm's compiled cycle with mypyc, where it can: everything else is in pyproject.toml.

The modules the control loop runs every cycle (akarm/compiled.py's MODULES) are compiled to C: the
process's CPU per cycle falls by 10-25 % (README, Timing). Nothing is lost where they cannot be:
without a C compiler or Python's headers, or a mypyc that will not take them, akarm installs as
pure Python and says so (a warning here, which pip shows with -v; `akarm --version` afterwards).
AKARM_PURE=1 compiles nothing.
"""

from __future__ import annotations

import runpy
import sys
import traceback
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

HERE = Path(__file__).resolve().parent
COMPILED = runpy.run_path(str(HERE / "akarm" / "compiled.py"))  # stdlib only: akarm is not installed yet


def warn(what: str) -> None:
    bar = "!" * 78
    print(f"\n{bar}\nakarm: {what}\nakarm installs as pure Python: it works the same, its cycle costs "
          f"10-25 % more CPU.\n{bar}\n", file=sys.stderr)


class OptionalBuildExt(build_ext):
    """build_ext that falls back to pure Python, whole: a half-compiled cycle is never installed."""

    def finalize_options(self) -> None:
        # mypyc runs here, not when setup.py is read: pip reads it three times an install
        if self.distribution.ext_modules == [PLACEHOLDER]:
            self.distribution.ext_modules = cycle_extensions()
        super().finalize_options()

    def run(self) -> None:
        try:
            super().run()
        except Exception as e:  # a compiler missing or failing: CompileError, LinkError, PlatformError...
            for out in self.get_outputs():
                Path(out).unlink(missing_ok=True)
            warn(f"the compiled cycle did not build ({type(e).__name__}: {e})")
            self.extensions = self.distribution.ext_modules = []


def cycle_extensions() -> list:
    try:
        from mypyc.build import mypycify
    except ImportError:
        warn("mypyc is not installed in the build environment")
        return []
    paths = [str(Path(*name.split(".")).with_suffix(".py")) for name in COMPILED["MODULES"]]
    try:
        # The same build on every install: mypy sees none of the installed packages (a first install has
        # none of numpy, python-can and the rest yet; a second one would have them all), and reports
        # only what it finds in the modules it compiles (not in those they import: the ROS messages'
        # base classes are missing here too).
        options = ["--no-site-packages", "--ignore-missing-imports", "--follow-imports=silent",
                   "--no-warn-unused-ignores"]
        return mypycify([*options, *paths], opt_level="3", group_name=COMPILED["GROUP"])
    except BaseException as e:  # mypyc reports a type error by SystemExit
        if isinstance(e, KeyboardInterrupt):
            raise
        traceback.print_exc()
        warn(f"mypyc would not compile the cycle ({type(e).__name__})")
        return []


# one stand-in, so that setuptools builds a wheel for this platform and runs build_ext; build_ext puts
# mypyc's extensions in its place, or none
PLACEHOLDER = Extension(COMPILED["GROUP"] + "__mypyc", sources=[])
setup(ext_modules=[] if COMPILED["pure_requested"]() else [PLACEHOLDER], cmdclass={"build_ext": OptionalBuildExt})
