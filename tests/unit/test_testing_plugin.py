"""The pytest plugin is registered and adds its options and fixtures, and nothing else (projects of its
own using it: tests/system/test_testing_plugin.py)."""

from __future__ import annotations

from importlib.metadata import entry_points

import pytest


def test_the_plugin_is_registered_through_the_pytest11_entry_point() -> None:
    found = [ep for ep in entry_points(group="pytest11") if ep.value == "akarm.testing.plugin"]
    assert [ep.name for ep in found] == ["akarm"], "reinstall akarm (pip install -e .) to register its entry point"


def test_the_plugin_adds_options_and_fixtures_and_nothing_else(pytestconfig: pytest.Config) -> None:
    # this run of akarm's own tests has it loaded too: its options are there, unset
    assert pytestconfig.pluginmanager.has_plugin("akarm")
    for key in ("robot", "interface", "channel", "profile", "pose"):
        assert pytestconfig.getoption(f"akarm_{key}") is None
    import akarm.testing.plugin

    hooks = sorted(n for n in vars(akarm.testing.plugin) if n.startswith("pytest_"))
    assert hooks == ["pytest_addoption", "pytest_report_header"]
