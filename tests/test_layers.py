"""The layers import one way: solvers <- model <- app <- studies (the CLI's ``handeye study`` aside).

Every module's imports are read with ``ast`` (module level and inside functions), so an import
against the order fails here before it ties the layers together. ``solvers`` knows nothing of
robots, ``model`` nothing of the application, the application nothing of the studies; the
package root (the public API) is part of the application layer.
"""
import ast
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
#: folder -> (layer name, rank); a module may import its own rank or lower ones
LAYERS = {"solvers": 0, "model": 1, "app": 2, "studies": 3}
#: the one allowed upward import: the CLI runs a study only when asked (``handeye study``)
ALLOWED_UPWARD = {("app/cli.py", "_study", "handeye.studies")}


def _modules():
    out = [ROOT / "__init__.py"]
    for folder in LAYERS:
        out += sorted((ROOT / folder).rglob("*.py"))
    return out


def _layer_of_module(name):
    """Rank of an imported module name, or None when it is not handeye's."""
    parts = name.split(".")
    if parts[0] != "handeye":
        return None
    if len(parts) == 1 or parts[1] not in LAYERS:
        return LAYERS["app"]  # the package root and its names are the public API: application layer
    return LAYERS[parts[1]]


def _imports(tree):
    """(imported module, enclosing function name or None) for every import in a module."""
    found = []

    def visit(node, function):
        for child in ast.iter_child_nodes(node):
            name = child.name if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)) else function
            if isinstance(child, ast.Import):
                found.extend((a.name, function) for a in child.names)
            elif isinstance(child, ast.ImportFrom):
                assert child.level == 0, "relative imports: use handeye.<layer>.<module>"
                if child.module == "handeye":  # from handeye import solvers (a layer) or calibrate (the API)
                    found.extend((f"handeye.{a.name}", function) for a in child.names)
                else:
                    found.append((child.module, function))
            visit(child, name)

    visit(tree, None)
    return found


def _own_rank(path):
    rel = path.relative_to(ROOT)
    return LAYERS["app"] if rel.parts == ("__init__.py",) else LAYERS[rel.parts[0]]


@pytest.mark.parametrize("path", _modules(), ids=lambda p: p.relative_to(ROOT).as_posix())
def test_imports_point_down_the_layers(path):
    rank = _own_rank(path)
    rel = path.relative_to(ROOT).as_posix()
    for name, function in _imports(ast.parse(path.read_text(), rel)):
        assert name.split(".")[0] not in ("model", "solvers", "studies", "app"), (
            f"{rel} imports {name!r}: the source folders install as handeye.<layer>, never top-level")
        target = _layer_of_module(name)
        if target is None or target <= rank:
            continue
        allowed = any(rel == f and function == fn and name.startswith(mod) for f, fn, mod in ALLOWED_UPWARD)
        assert allowed, f"{rel} imports {name} (inside {function or 'the module'}): against solvers <- model <- app <- studies"


def test_the_checker_sees_a_violation():
    """The test above would fail on an upward import (the checker is not vacuous)."""
    tree = ast.parse("def f():\n    from handeye.app import calibrate\n")
    assert _imports(tree) == [("handeye.app", "f")]
    assert _layer_of_module("handeye.app.engine.calibrate") > LAYERS["model"]
    assert _layer_of_module("handeye") == LAYERS["app"] == _layer_of_module("handeye.calibrate")
    assert _imports(ast.parse("from handeye import solvers")) == [("handeye.solvers", None)]
    assert _layer_of_module("numpy") is None


def test_importing_handeye_imports_no_study_and_no_sympy():
    """``import handeye`` is cheap and layered: no studies, no sympy, no casadi at import."""
    import subprocess
    import sys

    code = ("import sys, handeye; bad = sorted(m for m in sys.modules if m.startswith('handeye.studies') or "
            "m in ('sympy', 'casadi', 'matplotlib')); print(','.join(bad))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd="/")
    assert out.stdout.strip() == "", out.stdout


def test_importing_a_lower_layer_loads_nothing_above_it():
    """The package root is lazy (PEP 562): ``import handeye.solvers`` loads no model and no app,
    ``import handeye.model.calibration`` no app."""
    import subprocess
    import sys

    code = ("import sys, importlib; importlib.import_module(sys.argv[1]); "
            "print(','.join(sorted({m.split('.')[1] for m in sys.modules if m.startswith('handeye.')})))")
    for module, allowed in (("handeye.solvers", {"solvers"}), ("handeye.model.calibration", {"solvers", "model"})):
        out = subprocess.run([sys.executable, "-c", code, module], capture_output=True, text=True, check=True, cwd="/")
        assert set(filter(None, out.stdout.strip().split(","))) <= allowed, (module, out.stdout)


def _module_name(path):
    rel = path.relative_to(ROOT).with_suffix("")
    parts = ("handeye", *rel.parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _import_graph():
    """handeye module -> the handeye modules it imports (module level and inside functions).

    ``from handeye.x import y`` is an import of the module ``handeye.x.y`` when that is a module
    (a submodule), else of ``handeye.x``; a package's ``__init__`` is not implied by importing
    one of its modules (the usual convention of import linters)."""
    modules = {_module_name(p): p for p in _modules()}
    graph = {}
    for name, path in modules.items():
        deps = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                deps |= {a.name for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.module:
                subs = {f"{node.module}.{a.name}" for a in node.names} & set(modules)
                deps |= subs or {node.module}
        graph[name] = {d for d in deps if d in modules and d != name}
    return graph


def _cycles(graph):
    """Strongly connected components with more than one module (Tarjan), each sorted."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_import_circles():
    """No module imports itself through others, not even lazily inside a function (a circle
    ties modules that should be separable: the engine to its reports, the symbolic source to
    the numeric modules generated from it)."""
    assert _cycles(_import_graph()) == []


def test_the_circle_finder_sees_a_circle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert _cycles(graph) == [["a", "b", "c"]]
    assert "handeye.app.engine.calibrate" in _import_graph()["handeye.app.api"]
