"""The add-on's modules import only downward (issue 12): the import graph of addon/myoskin, read with ast
(nothing is imported, so no bpy is needed), has no cycle, no function-local import of an add-on module
(they only ever existed to break a cycle), and every import goes to the same or a lower layer."""
import ast
import os

import pytest

ADDON_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "addon", "myoskin")

# Bottom (0) to top. A new module must be placed here.
LAYERS = {
    # no add-on imports: the compiled core's loader, per-version Blender API, glTF, the runtime's owner
    # (re-entrancy guard, caches, callback dispatcher, errors)
    "core_loader": 0, "anim_compat": 0, "gltf_io": 0, "runtime": 0,
    # Blender <-> core arrays
    "blender_io": 1, "rig_io": 1, "truth": 1,
    # core data: the properties stored in the .blend
    "state": 2,
    # muscle and rig services
    "muscle_io": 3, "binding": 3, "core_skin": 2, "volume_keys": 2, "correctives": 3, "dynamics": 3,
    # runtime: application handlers and live update
    "live": 4, "handlers": 4,
    # operators, panels, preferences, the batch entry point
    "preferences": 5, "batch": 5,
    "operators": 5, "operators.character": 5, "operators.muscles": 5, "operators.rig": 5, "operators.correctives": 5,
    "operators.dynamics": 5,
    "panels": 5, "panels.common": 5, "panels.modifier": 5, "panels.sidebar": 5, "panels.correctives": 5,
    "panels.dynamics": 5,
    # the package: registers everything
    "": 6,
}
# Function-local imports of these names are not add-on modules (the compiled core, imported guarded).
NOT_MODULES = {"_core"}


def module_files(root):
    """{module name relative to the package ("" for __init__, "operators.rig"): path}."""
    found = {}
    for folder, _dirs, files in os.walk(root):
        rel = os.path.relpath(folder, root)
        parts = [] if rel == "." else rel.split(os.sep)
        if "__pycache__" in parts:
            continue
        for f in files:
            if f.endswith(".py"):
                name = parts + ([] if f == "__init__.py" else [f[:-3]])
                found[".".join(name)] = os.path.join(folder, f)
    return found


def _package_of(module, path):
    parts = module.split(".") if module else []
    return parts if path.endswith("__init__.py") else parts[:-1]


def _ancestors(module):
    parts = module.split(".") if module else []
    return {".".join(parts[:k]) for k in range(len(parts))}


def import_graph(root):
    """({module: set of add-on modules it imports}, [(module, line, target) of function-local imports]).
    An import of a submodule also runs its package's __init__ (unless the importer is inside it)."""
    modules = module_files(root)
    graph = {m: set() for m in modules}
    local = []
    for module, path in modules.items():
        tree = ast.parse(open(path, encoding="utf-8").read(), path)
        package = _package_of(module, path)
        top_level = set(map(id, tree.body))
        for node in ast.walk(tree):
            if not isinstance(node, ast.ImportFrom) or not node.level:
                continue  # absolute imports are not the add-on's (it imports itself relatively)
            base = package[:len(package) - (node.level - 1)] if node.level > 1 else package
            base_name = ".".join(base + (node.module.split(".") if node.module else []))
            targets = []
            if node.module:
                targets.append(base_name)
            for alias in node.names:
                sub = ".".join(filter(None, [base_name, alias.name]))
                if sub in modules:
                    targets.append(sub)
                elif not node.module and alias.name not in NOT_MODULES:
                    targets.append(base_name)  # a name from the package's __init__
            for target in targets:
                if target not in modules:
                    continue
                for t in {target} | (_ancestors(target) - _ancestors(module) - {module}):
                    if t != module:
                        graph[module].add(t)
                if id(node) not in top_level:
                    local.append((module, node.lineno, target))
    return graph, local


def find_cycle(graph):
    """One import cycle as a list of modules [a, b, ..., a], or None."""
    state = {}
    stack = []

    def visit(m):
        state[m] = "open"
        stack.append(m)
        for n in sorted(graph.get(m, ())):
            if state.get(n) == "open":
                return stack[stack.index(n):] + [n]
            if n not in state:
                cycle = visit(n)
                if cycle:
                    return cycle
        stack.pop()
        state[m] = "done"
        return None

    for m in sorted(graph):
        if m not in state:
            cycle = visit(m)
            if cycle:
                return cycle
    return None


def _name(m):
    return m or "__init__"


def test_no_import_cycle():
    graph, _ = import_graph(ADDON_DIR)
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(map(_name, cycle))


def test_no_function_local_imports_of_addon_modules():
    _, local = import_graph(ADDON_DIR)
    assert not local, "function-local imports (import at module level, downward only): " + ", ".join(
        f"{_name(m)}:{line} imports {_name(t)}" for m, line, t in local)


def test_imports_go_downward():
    graph, _ = import_graph(ADDON_DIR)
    unplaced = sorted(set(graph) - set(LAYERS))
    assert not unplaced, f"place these modules in LAYERS: {unplaced}"
    upward = [(m, t) for m, targets in graph.items() for t in targets if LAYERS[t] > LAYERS[m]]
    assert not upward, "imports going up a layer: " + ", ".join(f"{_name(m)} -> {_name(t)}" for m, t in upward)


def test_state_imports_neither_runtime_work_nor_services():
    graph, _ = import_graph(ADDON_DIR)
    assert graph["state"] == {"runtime"}, graph["state"]
    assert graph["muscle_io"] <= {"state", "blender_io", "core_loader"}, graph["muscle_io"]


# ------------------------------------------------------------------------------------------------
# The checker itself catches what it must (a synthetic package)
# ------------------------------------------------------------------------------------------------


def _package(tmp_path, files):
    for name, text in files.items():
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return str(tmp_path)


def test_checker_finds_cycles_and_local_imports(tmp_path):
    root = _package(tmp_path, {
        "__init__.py": "from . import a, ui\n",
        "a.py": "from .b import f\n",
        "b.py": "def f():\n    from . import a\n",
        "ui/__init__.py": "from . import panel\n",
        "ui/panel.py": "from .. import a\nfrom ..b import f\n",
        "c.py": "from .ui.panel import x\n",
    })
    graph, local = import_graph(root)
    assert graph["a"] == {"b"} and graph["b"] == {"a"}
    assert graph["ui.panel"] == {"a", "b"} and graph["ui"] == {"ui.panel"}
    assert graph["c"] == {"ui", "ui.panel"}  # the package's __init__ runs first
    assert graph[""] == {"a", "ui"}
    assert local == [("b", 2, "a")]
    assert find_cycle(graph) in (["a", "b", "a"], ["b", "a", "b"])
    (tmp_path / "b.py").write_text("def f():\n    pass\n")
    graph, local = import_graph(root)
    assert find_cycle(graph) is None and not local


def test_checker_reads_the_real_addon():
    graph, _ = import_graph(ADDON_DIR)
    if "live" not in graph:
        pytest.fail(f"no add-on found in {ADDON_DIR}")
    assert "runtime" in graph["live"] and "operators.rig" in graph["operators"]
