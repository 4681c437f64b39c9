"""The package's imports form no cycle: every module imports only modules below it (ARCHITECTURE.md)."""
import ast
import pathlib

import jaxpose

PACKAGE = pathlib.Path(jaxpose.__file__).parent


def _module_name(path):
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path, name):
    """Every jaxpose module that ``path`` imports, at any depth (function-level imports too)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith("jaxpose"))
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{base}.{node.module}" if node.module else base
            elif node.module and node.module.startswith("jaxpose"):
                base = node.module
            else:
                continue
            found.add(base)
            found.update(f"{base}.{a.name}" for a in node.names)  # "from . import x" names a module
    return found


def import_graph():
    modules = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    graph = {}
    for name, path in modules.items():
        targets = {t for t in _imports(path, name) if t in modules}
        # a package's __init__ is imported on the way to any of its modules: not an edge of the layout
        graph[name] = {t for t in targets if t != name and not name.startswith(t + ".") and t != "jaxpose"}
    return graph


def _cycles(graph):
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


# The layers, bottom to top (docs/design.md): a module imports only from its own layer or those below.
# A sub-package or top-level module not named here fails test_every_module_has_a_layer: give it one.
LAYERS = (
    ("errors", "_validate", "config", "_hyper", "geometry", "host", "sample", "orientation", "backend", "weighted"),
    ("io", "datasets"),  # datasets read folders of meshes through io
    ("depth",),  # the exact distance transform: the host solid's depth uses it too
    ("occupancy",),
    ("moments", "baselines"),
    ("pose",),
    ("rotation",),
    ("mesh",),
    ("batch", "evaluation", "tuning", "plot"),
    ("cli", "__main__"),
)
LAYER = {unit: level for level, units in enumerate(LAYERS) for unit in units}


def _unit(module):
    """jaxpose.pose.estimators -> "pose"; jaxpose.mesh -> "mesh"; the package itself -> None."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else None


def test_every_module_has_a_layer():
    assert sorted({_unit(m) for m in import_graph()} - set(LAYER) - {None}) == []


def test_no_import_runs_up_a_layer():
    up = sorted(f"{a} -> {b}" for a, targets in import_graph().items() for b in targets
                if _unit(a) and _unit(b) and LAYER.get(_unit(a), -1) < LAYER.get(_unit(b), -1))
    assert up == []


def test_the_import_graph_is_read():
    graph = import_graph()
    assert "jaxpose.orientation" in graph["jaxpose.pose.pose"]
    assert "jaxpose.pose.pose" in graph["jaxpose.pose.estimators"]  # a function-level import counts too
    assert {"jaxpose.geometry", "jaxpose.sample", "jaxpose.orientation"} <= graph["jaxpose.baselines"]


def test_no_module_imports_one_that_imports_it_back():
    assert _cycles(import_graph()) == []


def test_a_cycle_would_be_found():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


_DEFAULTS = {"gamma": 47.0, "gamma0": 47.0, "nu": 0.5, "nu0": 0.5, "power": 4.0}


def _restated_defaults(path, root=PACKAGE.parent):
    """Where a file writes one of the estimators' defaults as a literal: a parameter's or a field's
    default, or the fallback of ``options.get("gamma", 47.0)``."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        pairs = []
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            a = node.args
            positional = a.posonlyargs + a.args
            pairs += list(zip(positional[len(positional) - len(a.defaults):], a.defaults))
            pairs += [(arg, d) for arg, d in zip(a.kwonlyargs, a.kw_defaults) if d is not None]
            pairs = [(arg.arg, d) for arg, d in pairs]
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) and node.value is not None:
            pairs.append((node.target.id, node.value))
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "get"
              and len(node.args) == 2 and isinstance(node.args[0], ast.Constant)):
            pairs.append((node.args[0].value, node.args[1]))
        elif isinstance(node, ast.Call) and any(k.arg == "default" for k in node.keywords) and node.args:
            flag = node.args[0].value if isinstance(node.args[0], ast.Constant) else None
            if isinstance(flag, str) and flag.startswith("--"):
                default = next(k.value for k in node.keywords if k.arg == "default")
                pairs.append((flag[2:].replace("-", "_"), default))
        for name, value in pairs:
            if (name in _DEFAULTS and isinstance(value, ast.Constant) and not isinstance(value.value, bool)
                    and value.value == _DEFAULTS[name]):
                found.append(f"{path.relative_to(root)}:{value.lineno} {name}={value.value}")
    return found


def test_the_estimators_defaults_are_written_once():
    """gamma, nu and the robust power are written in jaxpose/config.py only; everything else reads them."""
    found = [hit for p in sorted(PACKAGE.rglob("*.py")) if p.name != "config.py" for hit in _restated_defaults(p)]
    assert found == []
    assert len(_restated_defaults(PACKAGE / "config.py")) == 3


def test_a_restated_default_would_be_found(tmp_path):
    path = tmp_path / "restated.py"
    path.write_text("def f(x, gamma=47.0, *, nu=0.5, power=4.5):\n    return o.get('power', 4.0)\n\n\n"
                    "p.add_argument('--nu', type=float, default=0.5)\n")
    assert sorted(hit.split()[1] for hit in _restated_defaults(path, tmp_path)) == [
        "gamma=47.0", "nu=0.5", "nu=0.5", "power=4.0"]  # not power=4.5
