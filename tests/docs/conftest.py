"""Docs tests: every fenced ``python`` block of README.md and docs/ runs, in lock step against the
simulator (tests/docs/test_code_blocks.py). Not in the README's test command (pyproject's testpaths):
CI runs them in a step of their own, with the site's strict build (.ci/run).

The shared helpers, for ``from .conftest import ...`` in this folder's tests.
"""

from ..conftest import *  # noqa: F403
from ..conftest import __all__ as __all__
