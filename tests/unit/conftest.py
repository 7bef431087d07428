"""Unit tests: pure logic, no simulator, bus, thread or process (tests/conftest.py).

The shared helpers, for ``from .conftest import ...`` in this folder's tests.
"""

from ..conftest import *  # noqa: F403
from ..conftest import __all__ as __all__
