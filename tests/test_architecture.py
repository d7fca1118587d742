"""The layout of the package, as ``docs/architecture.md`` describes it: packages by concern in
layers, no import circle, no import inside a function but of an optional library, short modules,
demos that are stories nothing imports. Read from the source (``ast``), nothing is run."""

import ast
from collections import defaultdict
from pathlib import Path


ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "fxcontact"
#: libraries a function may import where it uses them: optional (pictures) or followed on their
#: first import (gmsh, see ``fxcontact.compat.import_gmsh``)
LOCAL_OK = ("matplotlib", "pyvista", "gmsh", "dolfinx.io")


def _modules():
    out = {}
    for f in sorted(PKG.rglob("*.py")):
        parts = f.relative_to(ROOT).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = f
    return out


def _imports(name, path, modules):
    """(target module, inside a function?, line) of every fxcontact import of a module."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    top = {id(n) for n in tree.body}
    for n in tree.body:     # `if TYPE_CHECKING:` blocks count as the module's own imports
        if isinstance(n, (ast.If, ast.Try)):
            top |= {id(m) for m in ast.walk(n)}
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package.split(".")[: len(package.split(".")) - node.level + 1]
                                + ([base] if base else []))
            subs = [f"{base}.{a.name}" for a in node.names]
            targets = [t for t in subs if t in modules] or [base]
        else:
            continue
        for t in targets:
            yield t, id(node) not in top, node.lineno


def test_no_circle_and_no_local_import():
    modules = _modules()
    graph = defaultdict(set)
    local = []
    for name, path in modules.items():
        for target, in_function, line in _imports(name, path, modules):
            if in_function and not target.startswith(LOCAL_OK):
                local.append(f"{path.relative_to(ROOT)}:{line} imports {target}")
            while target and target not in modules:
                target = target.rpartition(".")[0]
            if target and target != name and target != "fxcontact":
                graph[name].add(target)
            elif (target == "fxcontact" and name != "fxcontact"
                  and not name.startswith("fxcontact.processes")):
                local.append(f"{path.relative_to(ROOT)}:{line} imports the package itself")
    assert not local, "\n".join(local)
    # a package's __init__ that hands on its modules' names is not a circle with them
    state, stack = {}, []

    def visit(m):
        state[m] = 1
        stack.append(m)
        for t in sorted(graph[m]):
            if t.startswith(m + ".") and (PKG / Path(*m.split(".")[1:]) / "__init__.py").exists():
                continue
            if state.get(t) == 1:
                raise AssertionError("import circle: " + " -> ".join(stack[stack.index(t):] + [t]))
            if t not in state:
                visit(t)
        stack.pop()
        state[m] = 2

    for m in sorted(modules):
        if m not in state:
            visit(m)


def test_sizes():
    """At most 20 modules at the package's root, none over 800 lines."""
    root = sorted(p.name for p in PKG.glob("*.py"))
    assert len(root) <= 20, root
    long = {str(p.relative_to(ROOT)): n for p in PKG.rglob("*.py")
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > 800}
    assert not long, long


def test_core_loads_no_process():
    """No module outside ``fxcontact.processes`` imports one of it."""
    modules = _modules()
    bad = [f"{name} -> {t}" for name, path in modules.items()
           if not name.startswith("fxcontact.processes")
           for t, _, _ in _imports(name, path, modules) if t.startswith("fxcontact.processes")]
    assert not bad, bad


def test_demos_are_stories():
    """Every demo is at most 250 lines, is run as a script by ``tests/test_demos.py``, and no
    test, benchmark or demo imports one."""
    demos = sorted(p.stem for p in (ROOT / "demos").glob("demo_*.py"))
    assert demos
    long = {d: n for d in demos
            if (n := len((ROOT / "demos" / f"{d}.py").read_text().splitlines())) > 250}
    assert not long, long
    runner = (ROOT / "tests" / "test_demos.py").read_text()
    assert not [d for d in demos if d not in runner], "demos not run by tests/test_demos.py"
    users = []
    for folder in ("tests", "benchmarks", "demos"):
        for f in (ROOT / folder).glob("*.py"):
            text = f.read_text(encoding="utf-8")
            for d in demos:
                if f"import {d}" in text or f'"{d}"' in text and "spec_from_file" in text:
                    users.append(f"{f.relative_to(ROOT)} loads {d}")
            if f.name not in ("test_demos.py", "test_architecture.py") and "sys.path" in text \
                    and '"demos"' in text:
                users.append(f"{f.relative_to(ROOT)} puts demos/ on sys.path")
    assert not users, users
