"""The layout: no import cycle, no import up the floors of docs/architecture.md, every
module importable, functions of a readable size, and the pages that describe the code
(docs/architecture.md, the equation table of docs/theory.md) match it."""

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
    """Rows (equation, what, [(path, function), ...]) of the table "seed equation ->
    function" in docs/theory.md; a row may name several functions."""
    text = (ROOT / "docs" / "theory.md").read_text()
    entry = r"`[\w/.]+\.py`: `\w+`"
    rows = re.findall(rf"^\| ([^|]+) \| ([^|]+) \| ({entry}(?:, {entry})*) \|$", text, re.M)
    assert len(rows) >= 10
    return [(eq, what, re.findall(r"`([\w/.]+\.py)`: `(\w+)`", cell)) for eq, what, cell in rows]


def test_every_equation_in_the_theory_table_has_its_function():
    for equation, what, entries in equation_table():
        for path, function in entries:
            module = importlib.import_module(module_name(PACKAGE / path))
            f = getattr(module, function, None)
            assert callable(f), (equation, path, function)
            doc = " ".join((f.__doc__ or "").split())
            assert equation.strip() in doc, (function, equation, doc[:100])


def test_the_loops_call_the_bodies_the_theory_table_names():
    """The loop bodies the table names are the ones both backends compile: each appears in
    the CPU loops (compiled.point) and the CUDA kernels (compiled.device)."""
    bodies = {function for _, _, entries in equation_table() for path, function in entries
              if path == "scheme/bodies.py"}
    assert len(bodies) >= 4
    for backend, wrapper in (("cpu", "point"), ("cuda", "device")):
        text = (PACKAGE / "backends" / f"{backend}.py").read_text()
        for function in bodies:
            assert f"{wrapper}(B.{function})" in text, (backend, function)


def documented_functions():
    """(dotted name, the modules it may refer to, attribute path) for every `module.name`
    that docs/architecture.md writes, ``module`` the last part(s) of a module of the package
    (`cpu.rk_update` for impactfv.backends.cpu.rk_update)."""
    text = (ROOT / "docs" / "architecture.md").read_text()
    found = []
    for dotted in sorted(set(re.findall(r"`([A-Za-z_]+(?:\.[A-Za-z_]+)+)`", text))):
        if "impactfv." + dotted in MODULES:
            continue                        # a module, not a function
        parts = dotted.split(".")
        for cut in range(len(parts) - 1, 0, -1):
            tail = "." + ".".join(parts[:cut])
            modules = [m for m in MODULES if m.endswith(tail)]
            if modules:
                found.append((dotted, modules, parts[cut:]))
                break
    return found


def test_every_function_the_architecture_page_names_exists():
    named = documented_functions()
    assert len(named) >= 20
    for dotted, modules, attributes in named:
        def resolves(module):
            target = importlib.import_module(module)
            for attribute in attributes:
                target = getattr(target, attribute, None)
            return target is not None
        assert any(resolves(m) for m in modules), (dotted, modules)


def floors():
    """The table "floors" of docs/architecture.md: module prefix -> floor number."""
    text = (ROOT / "docs" / "architecture.md").read_text()
    table = {}
    for floor, cell in re.findall(r"^\| (\d) \| ([^|]+) \|", text, re.M):
        for prefix in re.findall(r"`([\w.]+)`", cell):
            table["impactfv" if prefix == "impactfv" else f"impactfv.{prefix}"] = int(floor)
    assert len(set(table.values())) >= 5
    return table


def floor_of(module, table):
    parts = module.split(".")
    for cut in range(len(parts), 0, -1):
        prefix = ".".join(parts[:cut])
        if prefix in table:
            return table[prefix]
    raise AssertionError(f"{module} is on no floor of docs/architecture.md")


def test_no_import_runs_up_the_floors():
    table = floors()
    for name in MODULES:
        mine = floor_of(name, table)
        for target in imports_of(name):
            assert floor_of(target, table) <= mine, f"{name} (floor {mine}) imports {target}"


def test_the_ground_floor_stands_alone():
    """The numba toolkit imports nothing of impactfv; the physics imports only physics, and
    no compiler (its point functions are plain Python for any backend)."""
    assert not imports_of("impactfv.compiled")
    for name, path in MODULES.items():
        if name.startswith("impactfv.physics"):
            assert all(m.startswith("impactfv.physics") for m in imports_of(name)), name
            assert not re.search(r"^\s*(import|from) numba", path.read_text(), re.M), name


#: functions longer than 80 lines or with more than 15 arguments today, each with why; the
#: list may only shrink (a function that leaves it must be removed from it)
LONG_OR_WIDE = {
    "backends/cuda.py:_make_kernels": "the CUDA kernels as closures over their compile-time "
                                      "constants (d, m, limiter, flux options)",
    "mesh/abaqus.py:read_inp": "one pass over the keyword lines of an .inp file",
    "pipeline/run.py:_run_stepper": "the time loop with its schedule and signals",
    "mesh/core.py:validate_and_orient": "mesh checks with their messages",
    "backends/cpu.py:rk_update_last": "the fused last stage: update, time step, checks, "
                                      "monitors and the carried stress in one pass",
    "backends/cuda.py:rk_update": "a CUDA kernel takes arrays, not bundles",
    "backends/cuda.py:boundary_fluxes": "a CUDA kernel takes arrays, not bundles",
    "backends/cuda.py:limited_gradient": "a CUDA kernel takes arrays, not bundles",
    "scheme/bodies.py:boundary_face_flux": "a body reads its face's rows by index (no views)",
    "scheme/bodies.py:node_update": "a body reads its node's rows by index (no views)",
    "scheme/bodies.py:edge_flux": "a body reads its edge's rows by index (no views)",
    "physics/contact_laws.py:contact_state": "both sides' states and scratch of one pair",
    "backends/cpu.py:_interior_fluxes": "the edge flux's inputs and the node-run sums",
}


def test_functions_are_short_and_take_few_arguments():
    found = set()
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            a = node.args
            count = len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) + bool(a.vararg) \
                + bool(a.kwarg) - bool(a.args and a.args[0].arg in ("self", "cls"))
            if node.end_lineno - node.lineno + 1 > 80 or count > 15:
                found.add(f"{path.relative_to(PACKAGE)}:{node.name}")
    assert found <= set(LONG_OR_WIDE), sorted(found - set(LONG_OR_WIDE))
    assert set(LONG_OR_WIDE) <= found, ("no longer long or wide: remove from the list",
                                        sorted(set(LONG_OR_WIDE) - found))


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
