"""The layout: no import cycle, every module importable, and the pages that describe the
code (docs/architecture.md, the equation table of docs/theory.md) match it."""

import ast
import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "impactfv"


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def is_package(name: str) -> bool:
    return MODULES[name].name == "__init__.py"


def imports_of(name: str) -> set[str]:
    """The impactfv modules ``name`` imports, at any level (module body or function)."""
    tree = ast.parse(MODULES[name].read_text())
    package = name if is_package(name) else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.startswith("impactfv")}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if not target.startswith("impactfv"):
                continue
            for alias in node.names:
                sub = f"{target}.{alias.name}"
                found.add(sub if sub in MODULES else target)
    return {m for m in found if m in MODULES and m != name}


def test_no_import_cycle():
    graph = {m: imports_of(m) for m in MODULES}
    state, stack = {}, []

    def visit(m):
        state[m] = "open"
        stack.append(m)
        for n in sorted(graph[m]):
            if state.get(n) == "open":
                cycle = stack[stack.index(n):] + [n]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if n not in state:
                visit(n)
        stack.pop()
        state[m] = "done"

    for m in sorted(graph):
        if m not in state:
            visit(m)


def test_every_module_imports():
    for name in MODULES:
        importlib.import_module(name)


def test_steppers_never_import_the_pipeline():
    """Methods plug into the pipeline; they do not reach back up into it."""
    for name in MODULES:
        if name.startswith(("impactfv.scheme", "impactfv.fem", "impactfv.contact")):
            assert not any(m.startswith("impactfv.pipeline") for m in imports_of(name)), name


def layout_entries():
    """The modules listed in the tree of docs/architecture.md."""
    text = (ROOT / "docs" / "architecture.md").read_text()
    block = re.search(r"```text\n(src/impactfv/\n.*?)```", text, re.S).group(1)
    entries, folders = set(), []
    for line in block.splitlines()[1:]:
        if not line.strip():
            continue
        depth = (len(line) - len(line.lstrip())) // 2
        item = line.split()[0]
        folders = folders[:depth - 1]
        if item.endswith("/"):
            folders.append(item.rstrip("/"))
        else:
            entries.add("/".join(folders + [item]))
    return entries


def test_architecture_page_lists_every_module():
    listed = layout_entries()
    actual = {str(p.relative_to(PACKAGE)) for p in PACKAGE.rglob("*.py")}
    assert listed == actual, (sorted(actual - listed), sorted(listed - actual))


def equation_table():
    """Rows of the table "seed equation -> function" in docs/theory.md."""
    text = (ROOT / "docs" / "theory.md").read_text()
    rows = re.findall(r"^\| ([^|]+) \| ([^|]+) \| `([\w/.]+\.py)`: `(\w+)` \|$", text, re.M)
    assert len(rows) >= 10
    return rows


def test_every_equation_in_the_theory_table_has_its_function():
    for equation, what, path, function in equation_table():
        module = importlib.import_module(module_name(PACKAGE / path))
        f = getattr(module, function, None)
        assert callable(f), (equation, path, function)
        doc = " ".join((f.__doc__ or "").split())
        assert equation.strip() in doc, (function, equation, doc[:100])


def test_documents_cite_only_the_repository():
    """Docs and docstrings cite docs/ and the seed paper by title, never files that are not
    in the repository."""
    texts = [p for p in ROOT.rglob("*") if p.suffix in (".py", ".md", ".toml")
             and ".git" not in p.parts and "build" not in p.parts]
    for path in texts:
        text = path.read_text(errors="ignore")
        for name in ("numerics.md", "peers.md", "DESIGN.md", "../shared"):
            if path.name == "test_architecture.py":
                continue
            assert name not in text, (path, name)
