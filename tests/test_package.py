"""The package's shape: one module per concept, documented, typed, with no import cycles."""

import ast
import importlib
import inspect
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "analogy"
MODULES = sorted(p for p in PACKAGE.rglob("*.py"))
#: Third-party modules heavy enough to import only where needed.
HEAVY = {"sympy", "scipy", "matplotlib", "PySpice", "mpmath", "schemdraw", "pandas", "tqdm", "distributed", "pint",
         "pyarrow", "dask", "yourdfpy", "pinocchio"}


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path):
    """(imported module, at top level?, for type checking only?) for every import of the module."""
    tree = ast.parse(path.read_text())
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    top = {id(n) for n in tree.body}
    # a module-level try around an import (a platform's optional module) is still the top
    top |= {id(n) for guard in tree.body if isinstance(guard, ast.Try) for n in guard.body}
    typing_only = set()
    for guard in (n for n in tree.body if isinstance(n, ast.If)):
        if "TYPE_CHECKING" in ast.unparse(guard.test):
            typing_only |= {id(n) for n in ast.walk(guard)}
    top |= typing_only
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(a.name, id(node) in top, id(node) in typing_only) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            if node.module is None or (node.level and not node.module):
                out += [(f"{target}.{a.name}", id(node) in top, id(node) in typing_only) for a in node.names]
            else:
                out.append((target, id(node) in top, id(node) in typing_only))
    return out


def graph():
    names = {module_name(p): p for p in MODULES}
    edges = {m: set() for m in names}
    for m, p in names.items():
        for target, _, typing_only in imports(p):
            if typing_only:
                continue
            while target and target not in names:
                target = target.rpartition(".")[0]
            if target and target != m:
                edges[m].add(target)
    return names, edges


def test_no_import_cycles():
    """Every import, at module top or in a function, follows one direction."""
    _, edges = graph()
    state, stack = {}, []

    def visit(m):
        state[m] = "open"
        stack.append(m)
        for t in sorted(edges[m]):
            if state.get(t) == "open":
                cycle = stack[stack.index(t):] + [t]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if t not in state:
                visit(t)
        stack.pop()
        state[m] = "done"
    for m in sorted(edges):
        if m not in state:
            visit(m)


def heavy_closure(module, names, edges, seen=None):
    """Heavy third-party modules *module* imports at its top level, directly or through others."""
    seen = set() if seen is None else seen
    if module in seen:
        return set()
    seen.add(module)
    found = set()
    for target, at_top, _ in imports(names[module]):
        if not at_top:
            continue
        if target.split(".")[0] in HEAVY:
            found.add(target.split(".")[0])
        t = target
        while t and t not in names:
            t = t.rpartition(".")[0]
        if t and t != module:
            found |= heavy_closure(t, names, edges, seen)
    return found


def test_imports_inside_functions_only_defer_heavy_dependencies():
    """An import inside a function defers a heavy dependency on purpose, or it belongs at the top.

    The one exception is the command line, where each command imports what it uses so
    that a quick command starts quickly.
    """
    names, edges = graph()
    bad = []
    for m, p in names.items():
        if m == "analogy.cli" or m.startswith("analogy.cli."):
            continue
        for target, at_top, _ in imports(p):
            if at_top:
                continue
            root = target.split(".")[0]
            if root in HEAVY:
                continue
            if root == "analogy":
                t = target
                while t and t not in names:
                    t = t.rpartition(".")[0]
                if t and heavy_closure(t, names, edges):
                    continue
            bad.append(f"{m} imports {target} inside a function")
    assert not bad, "imports that belong at module top:\n" + "\n".join(bad)


@pytest.mark.parametrize("path", MODULES, ids=lambda p: module_name(p))
def test_module_is_one_concept(path):
    """A one-line docstring, an __all__, no more than about 500 lines, and no function over 100."""
    tree = ast.parse(path.read_text())
    doc = ast.get_docstring(tree)
    assert doc and len(doc.splitlines()[0]) <= 120, "the module needs a one-line docstring"
    if path.name != "__main__.py":
        assert any(isinstance(n, (ast.Assign, ast.AnnAssign)) and "__all__" in ast.unparse(n)
                   for n in tree.body), "the module needs __all__"
    assert len(path.read_text().splitlines()) <= 520
    long = [f"{n.name} ({n.end_lineno - n.lineno + 1} lines)" for n in ast.walk(tree)
            if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)) and n.end_lineno - n.lineno >= 100]
    assert not long, "functions over 100 lines, docstring included: " + ", ".join(long)


def public_callables():
    for path in MODULES:
        name = module_name(path)
        if path.name == "__main__.py":
            continue
        module = importlib.import_module(name)
        for attr in getattr(module, "__all__", []):
            obj = getattr(module, attr, None)
            if inspect.isfunction(obj) and obj.__module__ == name:
                yield f"{name}.{attr}", obj, obj.__doc__
            elif inspect.isclass(obj) and obj.__module__ == name:
                for meth_name, meth in vars(obj).items():
                    if meth_name.startswith("_"):
                        continue        # __init__ is documented in the class docstring
                    func = meth.__func__ if isinstance(meth, (classmethod, staticmethod)) else meth
                    if inspect.isfunction(func):
                        yield f"{name}.{attr}.{meth_name}", func, inspect.getdoc(getattr(obj, meth_name))


def documented_parameters(doc: str) -> list[str] | None:
    lines = inspect.cleandoc(doc).splitlines()
    try:
        start = next(i for i, ln in enumerate(lines) if ln.strip() == "Parameters"
                     and i + 1 < len(lines) and set(lines[i + 1].strip()) == {"-"})
    except StopIteration:
        return None
    names = []
    for ln in lines[start + 2:]:
        if ln.strip() and set(ln.strip()) == {"-"}:
            names.pop()         # the previous line was the next section's title
            break
        if ln and not ln.startswith(" ") and ln.strip():
            for part in ln.split(":")[0].split(","):
                names.append(part.strip())
    return names


def test_public_functions_document_exactly_their_parameters():
    """Each public function's numpydoc Parameters section names exactly its parameters."""
    bad = []
    for qualname, func, doc in public_callables():
        params = [f"**{p.name}" if p.kind is p.VAR_KEYWORD else f"*{p.name}" if p.kind is p.VAR_POSITIONAL else p.name
                  for p in inspect.signature(func).parameters.values() if p.name not in ("self", "cls")]
        doc = doc or ""     # an override without a docstring inherits its base method's
        documented = documented_parameters(doc)
        if not params:
            if documented:
                bad.append(f"{qualname}: documents {documented} but takes none")
            continue
        if documented is None:
            bad.append(f"{qualname}: no Parameters section for {params}")
        elif documented != params:
            bad.append(f"{qualname}: documents {documented}, takes {params}")
    assert not bad, "\n".join(bad)


def test_typed_package():
    """A py.typed marker ships, and public functions annotate their return values."""
    assert (PACKAGE / "py.typed").exists()
    assert "py.typed" in (ROOT / "pyproject.toml").read_text()
    unannotated = [q for q, f, _ in public_callables() if "return" not in f.__annotations__]
    assert not unannotated, "no return annotation: " + ", ".join(unannotated)
