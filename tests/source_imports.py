"""The modules a package's source imports (imports inside functions too), read from its
files: for the layering test and the declared-dependencies test."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def source_imports(package: str):
    """(file relative to the repository, line, imported module) for every absolute import."""
    for path in sorted((ROOT / package).rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module] if isinstance(node, ast.ImportFrom) and node.module and node.level == 0 else []
            for name in names:
                yield path.relative_to(ROOT), node.lineno, name
