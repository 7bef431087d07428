"""The documentation site cannot drift from the code: the API reference lists every public name, the
command line's reference is every verb's ``--help`` as the parser prints it, and every page is in the
nav. (The robot file's reference: tests/unit/test_config.py; the code blocks run: tests/docs; the
site's strict build: .ci/run.)"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import pkgutil
import re
import sys
from types import ModuleType

import yaml

from .conftest import ROOT

DOCS = ROOT / "docs"
#: the modules whose public names the API reference documents, each with `::: module.NAME` lines
API_MODULES = ("akarm", "akarm.sim", "akarm.teleop", "akarm.datasets")


def documented() -> set[str]:
    """The objects the API pages render (their `::: dotted.name` lines)."""
    text = "\n".join(p.read_text(encoding="utf-8") for p in sorted((DOCS / "api").glob("*.md")))
    return set(re.findall(r"^::: ([\w.]+)\s*$", text, re.M))


def public_modules(package: ModuleType) -> list[str]:
    modules = pkgutil.iter_modules(package.__path__)
    return [f"{package.__name__}.{m.name}" for m in modules if not m.name.startswith("_")]


def test_the_api_reference_lists_every_public_name() -> None:
    names = documented()
    missing = [f"{module}.{name}" for module in API_MODULES for name in importlib.import_module(module).__all__
               if f"{module}.{name}" not in names]
    import akarm.testing

    missing += [m for m in public_modules(akarm.testing) if m not in names]  # no __all__: its modules, whole
    assert not missing, f"add `::: NAME` lines to docs/api/*.md for: {', '.join(missing)}"


def test_every_name_in_the_api_reference_exists_and_has_a_docstring() -> None:
    for dotted in sorted(documented()):
        module_name, _, attr = dotted.rpartition(".")
        try:
            obj = importlib.import_module(dotted)
        except ImportError:
            obj = getattr(importlib.import_module(module_name), attr)
        if inspect.isclass(obj) or inspect.isfunction(obj) or inspect.ismodule(obj):
            assert (inspect.getdoc(obj) or "").strip(), f"{dotted} has no docstring"


def test_the_api_reference_check_can_fail() -> None:
    import akarm

    assert "akarm.Arm" in documented() and "akarm.testing.rig" in documented()
    assert "akarm.NotAName" not in documented() and "Arm" in akarm.__all__


def cli_reference() -> ModuleType:
    spec = importlib.util.spec_from_file_location("cli_reference", DOCS / "tools" / "cli_reference.py")
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def comparable(help_text: str) -> str:
    """Help text as every Python since 3.10 prints it: whitespace (argparse wraps to the terminal) and
    3.13's ``-o, --output PNG`` for ``-o PNG, --output PNG`` do not count."""
    help_text = re.sub(r"(?<![\w-])(-\w) (\S+), (--[\w-]+) \2\b", r"\1, \3 \2", help_text)
    return " ".join(help_text.split())


def test_the_cli_reference_is_every_verbs_help() -> None:
    ref = cli_reference()
    page = (DOCS / "cli.md").read_text(encoding="utf-8")
    assert ref.MARK in page, "docs/cli.md lost its generated part: python docs/tools/cli_reference.py"
    written, now = page.split(ref.MARK, 1)[1], ref.generated().split(ref.MARK, 1)[1]
    assert comparable(written) == comparable(now), "the CLI changed: run python docs/tools/cli_reference.py"
    if sys.version_info[:2] == (3, 11):  # the Python that generated it prints it byte for byte
        assert written == now, "run python docs/tools/cli_reference.py"


def test_the_cli_reference_check_can_fail() -> None:
    ref = cli_reference()
    now = ref.generated()
    assert "## `akarm move`" in now and "--speed" in now
    assert comparable(now) != comparable(now.replace("--speed", "--sped", 1))
    assert comparable("-o PNG, --output PNG  where") == comparable("-o, --output PNG\n    where")


def test_the_cli_page_lists_every_verb() -> None:
    from akarm.cli import VERBS

    page = (DOCS / "cli.md").read_text(encoding="utf-8").split(cli_reference().MARK, 1)[0]
    for verb in VERBS:
        assert re.search(rf"^\| `akarm {verb}\b", page, re.M), verb


def nav_pages(entry: object) -> list[str]:
    if isinstance(entry, str):
        return [entry]
    if isinstance(entry, dict):
        return [p for value in entry.values() for p in nav_pages(value)]
    if isinstance(entry, list):
        return [p for value in entry for p in nav_pages(value)]
    return []


def test_every_page_is_in_the_nav() -> None:
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"))
    nav = nav_pages(config["nav"])
    pages = sorted(str(p.relative_to(DOCS)) for p in DOCS.rglob("*.md") if "tools" not in p.parts)
    assert sorted(nav) == pages, "docs/ and mkdocs.yml's nav differ"
    assert config["theme"]["font"] is False  # offline: no web fonts fetched at build or in the browser
