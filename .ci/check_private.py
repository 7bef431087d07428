"""Fail when a module reaches another module's private names.

Flags, in the given files: an attribute ``x._name`` read or written on anything but ``self``/``cls``
(or ``type(self)``/``super()``), and ``from module import _name`` of a name private to another module.
Dunders are public. A line may opt out with ``# private-ok: reason`` when the private name belongs to
a third-party library (e.g. ``os._exit``).
"""
from __future__ import annotations

import ast
import sys
from pathlib import Path

OWNERS = {"self", "cls"}


def _is_private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _owner_ok(node: ast.expr) -> bool:
    if isinstance(node, ast.Name) and node.id in OWNERS:
        return True
    return isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in {"super", "type"}


def check(path: Path) -> list[str]:
    text = path.read_text()
    lines = text.splitlines()
    problems = []
    for node in ast.walk(ast.parse(text, str(path))):
        line = lines[node.lineno - 1] if hasattr(node, "lineno") else ""
        if "private-ok" in line:
            continue
        if isinstance(node, ast.Attribute) and _is_private(node.attr) and not _owner_ok(node.value):
            problems.append(f"{path}:{node.lineno}: {ast.unparse(node)} reaches a private name of another object")
        elif isinstance(node, ast.ImportFrom) and node.module != "__future__":
            for alias in node.names:
                if _is_private(alias.name):
                    problems.append(f"{path}:{node.lineno}: imports {alias.name} private to {node.module or '.'}")
    return problems


def main(argv: list[str]) -> int:
    roots = [Path(a) for a in argv] or [Path("akarm")]
    files = [p for r in roots for p in ([r] if r.is_file() else sorted(r.rglob("*.py")))]
    problems = [p for f in files for p in check(f)]
    print("\n".join(problems) if problems else f"no private names reached across modules in {len(files)} files")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
