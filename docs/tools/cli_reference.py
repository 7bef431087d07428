"""The command line's reference: every verb's ``akarm VERB --help``, as argparse prints it, written
into docs/cli.md below its hand-written part, so that the page cannot drift from the parser
(tests/unit/test_docs_site.py compares them).

    python docs/tools/cli_reference.py          # rewrite docs/cli.md's generated part
"""

from __future__ import annotations

import contextlib
import io
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "cli.md"
MARK = "<!-- generated below by docs/tools/cli_reference.py: edit the parser, then run it -->"
WIDTH = "100"  # argparse wraps to $COLUMNS


def help_text(args: list[str]) -> str:
    """What ``akarm ARGS`` prints (``--help``), at a fixed width."""
    from akarm.cli import build_parser

    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = WIDTH
    out = io.StringIO()
    try:
        with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit):
            build_parser().parse_args(args)
    finally:
        if old is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = old
    return out.getvalue().rstrip() + "\n"


def generated() -> str:
    """The generated part of docs/cli.md: ``akarm --help``, then each verb's."""
    from akarm.cli import VERBS

    parts = [MARK, "", "## `akarm`", "", "```text", help_text(["--help"]).rstrip(), "```"]
    for verb in VERBS:
        parts += ["", f"## `akarm {verb}`", "", "```text", help_text([verb, "--help"]).rstrip(), "```"]
    return "\n".join(parts) + "\n"


def page(current: str) -> str:
    """docs/cli.md with its generated part made anew (its hand-written part as it is)."""
    return current.split(MARK, 1)[0].rstrip("\n") + "\n\n" + generated()


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    PAGE.write_text(page(PAGE.read_text(encoding="utf-8")), encoding="utf-8")
    print(f"wrote {PAGE.relative_to(ROOT)}")
