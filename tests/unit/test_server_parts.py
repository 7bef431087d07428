"""Where the server keeps its lock files and sockets, and a runtime directory others could write in
refused (the parts across processes: tests/system/test_server_parts.py)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from akarm.buses import ownership as registry
from akarm.errors import StateError


def test_the_lock_files_live_in_one_place_whatever_the_environment(monkeypatch, tmp_path):
    first = registry.runtime_dir()
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))
    monkeypatch.setenv("TMPDIR", str(tmp_path))  # a service and a shell may differ in both
    assert registry.runtime_dir() == first and first.name == f"akarm-{os.getuid()}"
    assert first.parent == Path("/tmp") and (first.stat().st_mode & 0o777) == 0o700


def test_a_runtime_directory_others_could_write_in_is_refused(monkeypatch, tmp_path):
    monkeypatch.setattr(registry, "BASE", tmp_path)
    planted = tmp_path / f"akarm-{os.getuid()}"
    planted.mkdir(mode=0o777)
    planted.chmod(0o777)  # made by someone else first (mkdir's mode is masked by the umask)
    with pytest.raises(StateError, match="not a private directory") as e:
        registry.runtime_dir()
    assert "chmod 700" in e.value.fix
    planted.chmod(0o700)
    assert registry.runtime_dir() == planted
