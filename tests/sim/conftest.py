"""Sim tests: the simulator or a bus in this process, in lock step (tests/conftest.py).

The shared helpers, for ``from .conftest import ...`` in this folder's tests.
"""

from ..conftest import *  # noqa: F403
from ..conftest import __all__ as __all__
