"""Test hygiene (issue 15 item 6), a static check of the Python and Blender tests read with ast (nothing is
imported): a test must not pass vacuously because a collection it loops over came back empty.

What it checks, in every `test_*` function (and the helpers they share) of tests/python/*.py,
tests/blender/*.py and tests/blender/gui/*.py:

1. Loops. A `for` loop whose body asserts something (an `assert`, or a call of `assert*`/`np.testing.assert_*`)
   and that iterates over a named collection (a name, an attribute or a subscript such as `muscles`,
   `state.muscles` or `out["surfaces"]`, also inside enumerate/zip/sorted/reversed/list and `.items()`,
   `.keys()`, `.values()`) must have that collection asserted outside the loop: some `assert` of the
   function mentions it (`assert muscles`, `assert len(rows) == 4`, `assert crossing, "..."`). Loops over
   literals, range(...), or the result of a call are not checked (their length is not a name to assert).
2. all(). `assert all(... for x in <collection>)` passes on an empty collection: the same collection must be
   mentioned by an assert outside the generator (`assert crossing and all(... for m in crossing)`).

A collection bound to a non-empty literal (`POSES = [...]` at module level, `cases = {...}` in the function)
needs no assert. Loops in helpers count too (a helper's loop over its argument must assert the argument).

Mark a deliberate exception with a comment `# hygiene: <why>` on the `for`/`assert` line.
The checker's own tests below run it on inline samples of the pattern (it must fail on them) and on the
tree (it must pass)."""
import ast
import os

import pytest

TESTS_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
CHECKED = ["python", "blender", os.path.join("blender", "gui")]

WRAPPERS = {"enumerate", "zip", "sorted", "reversed", "list", "tuple", "set"}
VIEWS = {"items", "keys", "values"}


def _collections(iter_node):
    """The named collections a loop or generator iterates over: unparsed texts, or [] when not checked."""
    node = iter_node
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in WRAPPERS:
        return [text for arg in node.args for text in _collections(arg)]
    if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in VIEWS
            and not node.args):
        node = node.func.value
    if isinstance(node, (ast.Name, ast.Attribute, ast.Subscript)) and not _has_call(node):
        return [ast.unparse(node)]
    return []


def _has_call(node):
    return any(isinstance(n, ast.Call) for n in ast.walk(node))


def _is_assertion(node):
    if isinstance(node, ast.Assert):
        return True
    if isinstance(node, ast.Call):
        f = node.func
        name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else ""
        return name.startswith("assert")
    return False


def _mentions(node, text, skip):
    """True if `node` holds a sub-expression whose source is `text`, not counting the nodes in `skip`."""
    for n in ast.walk(node):
        if id(n) in skip:
            continue
        if isinstance(n, (ast.Name, ast.Attribute, ast.Subscript)) and ast.unparse(n) == text:
            return True
    return False


def _marked(lines, node):
    return "# hygiene:" in lines[node.lineno - 1]


def _literal_names(scope):
    """Names bound in `scope`'s own statements to a non-empty list, tuple, set or dict literal."""
    out = set()
    for stmt in ast.walk(scope):
        if isinstance(stmt, ast.Assign) and isinstance(stmt.value, (ast.List, ast.Tuple, ast.Set, ast.Dict)):
            size = len(stmt.value.keys) if isinstance(stmt.value, ast.Dict) else len(stmt.value.elts)
            if size:
                out |= {t.id for t in stmt.targets if isinstance(t, ast.Name)}
    return out


def check_source(source, path="<sample>"):
    """[(path, line, message)] of the vacuous patterns in one file's source."""
    tree = ast.parse(source, path)
    lines = source.splitlines()
    problems = []
    module_literals = {t for stmt in tree.body for t in _literal_names(ast.Module(body=[stmt], type_ignores=[]))
                       if isinstance(stmt, ast.Assign)}
    for func in ast.walk(tree):
        if not isinstance(func, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        literals = module_literals | _literal_names(func)
        asserts = [n for n in ast.walk(func) if isinstance(n, ast.Assert)]
        nested = {id(n) for inner in ast.walk(func) if inner is not func and
                  isinstance(inner, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)) for n in ast.walk(inner)}
        for loop in ast.walk(func):
            if id(loop) in nested or not isinstance(loop, ast.For) or _marked(lines, loop):
                continue
            if not any(_is_assertion(n) for stmt in loop.body for n in ast.walk(stmt)):
                continue
            inside = {id(n) for n in ast.walk(loop)}
            for text in _collections(loop.iter):
                if text in literals:
                    continue
                if not any(_mentions(a, text, inside) for a in asserts if id(a) not in inside):
                    problems.append((path, loop.lineno, f"asserts inside a loop over `{text}` that may be empty "
                                                        f"(assert it is non-empty first)"))
        for a in asserts:
            if id(a) in nested or _marked(lines, a):
                continue
            for call in ast.walk(a.test):
                if not (isinstance(call, ast.Call) and isinstance(call.func, ast.Name) and call.func.id == "all"
                        and call.args and isinstance(call.args[0], (ast.GeneratorExp, ast.ListComp))):
                    continue
                gen = call.args[0]
                for g in gen.generators:
                    for text in _collections(g.iter):
                        if text in literals:
                            continue
                        skip = {id(n) for n in ast.walk(call)}
                        if not any(_mentions(other, text, skip) for other in asserts if id(other) not in nested):
                            problems.append((path, a.lineno, f"all(...) over `{text}` passes when it is empty "
                                                             f"(assert it is non-empty too)"))
    return problems


def tree_files():
    out = []
    for folder in CHECKED:
        full = os.path.join(TESTS_DIR, folder)
        out += sorted(os.path.join(full, f) for f in os.listdir(full) if f.endswith(".py"))
    return out


# ------------------------------------------------------------------------------------------------
# The tree passes
# ------------------------------------------------------------------------------------------------


def test_the_tests_have_no_vacuous_loops_or_all():
    files = tree_files()
    assert len(files) >= 20, files  # the checker reads the real test folders
    problems = []
    for path in files:
        problems += check_source(open(path, encoding="utf-8").read(), os.path.relpath(path, TESTS_DIR))
    assert not problems, "\n".join(f"{p}:{line}: {message}" for p, line, message in problems)


# ------------------------------------------------------------------------------------------------
# The checker catches the pattern (inline samples)
# ------------------------------------------------------------------------------------------------

VACUOUS = '''
def test_every_muscle_is_closed(core):
    muscles, _ = core.extract_muscles(character)
    for m in muscles:
        assert m.closed
'''

VACUOUS_NESTED = '''
def test_surfaces(rig):
    out = rig.evaluate()
    for i, s in enumerate(out["surfaces"]):
        np.testing.assert_allclose(s, rig.rest_surface(i))
'''

VACUOUS_ALL = '''
def test_straight(core):
    straight, _ = core.extract_muscles(character, joint_wrap=0.0)
    assert all(m.wrap_type == "none" for m in straight)
'''

GUARDED = '''
def test_every_muscle_is_closed(core):
    muscles, _ = core.extract_muscles(character)
    assert len(muscles) >= 4
    for m in muscles:
        assert m.closed
    crossing = [m for m in muscles if m.spans]
    assert crossing and all(m.wrapped for m in crossing)
    for label in ("elbow", "knee"):
        assert label
    for k in range(3):
        assert k >= 0
'''

GUARDED_AFTER = '''
def test_rows(core):
    rows = core.rows()
    for r in rows:
        assert r > 0
    assert len(rows) == 4
'''

LITERAL = '''
POSES = [{"forearm": 90}, {"forearm": 140}]

def test_poses(rig):
    cases = {"a": 1, "b": 2}
    for label, value in cases.items():
        assert value > 0, label
    for pose in POSES:
        assert rig.evaluate(pose)
'''

EMPTY_LITERAL = '''
def test_poses(rig):
    poses = []
    for pose in poses:
        assert rig.evaluate(pose)
'''

MARKED = '''
def test_rows(core):
    for r in core_rows:  # hygiene: core_rows is a module constant of four rows
        assert r > 0
'''


@pytest.mark.parametrize("sample, line, collection", [
    (VACUOUS, 4, "muscles"), (EMPTY_LITERAL, 4, "poses"), (VACUOUS_NESTED, 4, "out['surfaces']"), (VACUOUS_ALL, 4, "straight")])
def test_checker_fails_on_the_pattern(sample, line, collection):
    problems = check_source(sample)
    assert [(p[1], collection in p[2]) for p in problems] == [(line, True)], problems


@pytest.mark.parametrize("sample", [GUARDED, GUARDED_AFTER, LITERAL, MARKED])
def test_checker_passes_guarded_loops(sample):
    assert check_source(sample) == []
