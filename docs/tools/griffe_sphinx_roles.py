"""A griffe extension for the API reference: akarm's docstrings use reStructuredText's roles and
literals (``:class:`~akarm.Arm` ``, ````text````), which Markdown would show as they are; this turns
them into Markdown code spans before mkdocstrings renders them (a role's ``~`` keeps the last name)."""

from __future__ import annotations

import re
from typing import Any

import griffe

ROLE = re.compile(r":(?:py:)?(?:class|meth|func|mod|attr|data|exc|obj|const|ref|term):`(~?)([^`]+)`")
LITERAL = re.compile(r"``(.+?)``", re.S)


def _role(match: re.Match[str]) -> str:
    tilde, target = match.groups()
    target = re.sub(r"\s*<.*>$", "", target)  # :ref:`text <target>`: the text
    return f"`{target.rsplit('.', 1)[-1] if tilde else target}`"


def markdown(text: str) -> str:
    """``text`` with reStructuredText's roles and double-backtick literals as Markdown code spans."""
    text = ROLE.sub(_role, text).replace("`\\ ", "`")  # ":class:`Arm`\\ s": reST's escaped space
    return LITERAL.sub(lambda m: f"`{m.group(1)}`", text)


class SphinxRoles(griffe.Extension):
    def on_object(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = markdown(obj.docstring.value)
