"""The import graph of a source tree, read with `ast` (nothing is imported or run).

Every import counts, wherever it is written (module level, inside a function, under
``if TYPE_CHECKING``): ``import a.b``, ``from a import b``, ``from ..a import b`` and
``importlib.import_module("a.b")`` / ``__import__("a.b")`` with a literal name.  The add-on's
``bridge.module("film.passes")`` strings are edges too, to the tracer package (``via="bridge"``).

Used by tests/test_architecture.py (layers, cycles, the bridge, no bpy in the tracer) and by its
negative controls, which run the same functions on small packages written to a temporary directory.
"""
import ast
import os
from dataclasses import dataclass


@dataclass(frozen=True)
class Edge:
    importer: str        # dotted name of the importing module ("engine.scene.model")
    target: str          # dotted name of the module it reaches; for outside modules the name as written
    path: str            # the importer's file
    line: int
    via: str = "import"  # "import", "import_module" (a literal string) or "bridge"

    def __str__(self):
        how = "" if self.via == "import" else f" (via {self.via})"
        return f"{self.path}:{self.line}: {self.importer} -> {self.target}{how}"


def module_files(root, packages):
    """{dotted module name: file} for every .py file of the given top-level packages under root.
    A package's ``__init__.py`` is the module named for the package."""
    found = {}
    for package in packages:
        for base, dirs, files in os.walk(os.path.join(root, package)):
            dirs[:] = sorted(d for d in dirs if d != "__pycache__")
            rel = os.path.relpath(base, root).split(os.sep)
            for name in sorted(files):
                if name.endswith(".py"):
                    stem = name[:-3]
                    found[".".join(rel if stem == "__init__" else rel + [stem])] = os.path.join(base, name)
    return found


def _package_of(module, path):
    return module if os.path.basename(path) == "__init__.py" else module.rpartition(".")[0]


def _absolute(name, level, package):
    """``from <level dots><name> import ...`` written in ``package`` -> the absolute module name."""
    if level == 0:
        return name
    parts = package.split(".")
    if level - 1 > len(parts) - 1:
        raise ValueError(f"relative import beyond the top-level package ({'.' * level}{name} in {package})")
    base = ".".join(parts[:len(parts) - (level - 1)])
    return f"{base}.{name}" if name else base


def _literal(node):
    return node.value if isinstance(node, ast.Constant) and isinstance(node.value, str) else None


def raw_imports(path, module, bridge_base=None):
    """[(name as absolute dotted path, line, via, names imported from it or None)] of one file.
    ``bridge_base``: the package that ``bridge.module("x")`` / ``module("x")`` strings are relative to
    (only for the add-on)."""
    with open(path, encoding="utf-8") as fh:
        tree = ast.parse(fh.read(), filename=path)
    package = _package_of(module, path)
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(alias.name, node.lineno, "import", None) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = _absolute(node.module or "", node.level, package)
            out.append((base, node.lineno, "import", [alias.name for alias in node.names]))
        elif isinstance(node, ast.Call) and node.args:
            func = node.func
            name = func.attr if isinstance(func, ast.Attribute) else func.id if isinstance(func, ast.Name) else None
            target = _literal(node.args[0])
            if target is None:
                continue
            if name in ("import_module", "__import__"):
                level = len(target) - len(target.lstrip("."))
                if level and not (len(node.args) > 1 and isinstance(node.args[1], ast.Name)
                                  and node.args[1].id == "__package__"):
                    continue                    # relative to a package we cannot know statically
                out.append((_absolute(target[level:], level, package), node.lineno, "import_module", None))
            elif name == "module" and bridge_base is not None and (
                    isinstance(func, ast.Name) or (isinstance(func.value, ast.Name) and func.value.id == "bridge")):
                out.append((f"{bridge_base}.{target}", node.lineno, "bridge", None))
    return out


def build_graph(root, packages, bridge_package=None, bridge_base=None):
    """(edges, unresolved) of every module of ``packages`` under ``root``.

    edges: one Edge per imported module; imports of modules outside ``packages`` keep the name as
    written (``bpy``, ``numpy.linalg``).  ``from pkg import name`` is an edge to ``pkg.name`` when that
    is a module, else to ``pkg`` (its ``__init__``).  Importing ``a.b.c`` is an edge to ``a.b.c`` only:
    the parent packages' ``__init__`` files it also runs are not counted (a module may import its
    own package's submodules without a cycle being reported for the package).
    unresolved: Edges naming a module of ``packages`` that does not exist (a stale string path)."""
    modules = module_files(root, packages)
    edges, unresolved = [], []
    tops = set(packages)
    for module, path in modules.items():
        base = bridge_base if bridge_package and module.split(".")[0] == bridge_package else None
        rel = os.path.relpath(path, root)
        for name, line, via, names in raw_imports(path, module, base):
            targets = [f"{name}.{n}" for n in names if n != "*"] if names else []
            hits = [t for t in targets if t in modules]
            if names and hits:
                found = hits + ([name] if len(hits) < len(targets) else [])
            else:
                found = [name]
            for target in found:
                if target.split(".")[0] not in tops:
                    edges.append(Edge(module, target, rel, line, via))
                    continue
                if target not in modules:
                    unresolved.append(Edge(module, target, rel, line, via))
                elif target != module:
                    edges.append(Edge(module, target, rel, line, via))
    return edges, unresolved


def cycles(edges, nodes):
    """Import cycles among ``nodes``: one list of Edges per strongly connected component (Tarjan),
    each a closed path through the component, so the message shows where every step is written."""
    graph = {}
    for e in edges:
        if e.importer in nodes and e.target in nodes:
            graph.setdefault(e.importer, {}).setdefault(e.target, e)
    index, low, stack, on_stack, components = {}, {}, [], set(), []

    def connect(v):                                   # iterative Tarjan: no recursion limit
        work = [(v, iter(sorted(graph.get(v, {}))))]
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        while work:
            node, children = work[-1]
            for child in children:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, {})))))
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        component.append(w)
                        if w == node:
                            break
                    if len(component) > 1:
                        components.append(set(component))

    for v in sorted(graph):
        if v not in index:
            connect(v)
    return [_closed_path(graph, component) for component in components]


def _closed_path(graph, component):
    """A shortest cycle through the component's first node (breadth-first), as Edges."""
    start = min(component)
    previous = {start: None}
    queue = [start]
    while queue:
        node = queue.pop(0)
        for child, edge in sorted(graph.get(node, {}).items()):
            if child == start:
                path = [edge]
                while previous[node] is not None:
                    path.append(previous[node])
                    node = previous[node].importer
                return path[::-1]
            if child in component and child not in previous:
                previous[child] = edge
                queue.append(child)
    raise AssertionError("a strongly connected component without a cycle")
