"""Test hygiene (issue 15 item 6), a static check of the tests (the Python and Blender ones read with ast, the
C++ ones as text; nothing is imported or built): a test must not pass vacuously because a collection it loops
over came back empty.

What it checks, in every function (tests and the helpers they share) of tests/python/*.py, tests/blender/*.py
and tests/blender/gui/*.py, and in every TEST of tests/cpp/*.cpp:

1. Loops. A `for` loop whose body asserts something (an `assert`, or a call of `assert*`/`np.testing.assert_*`)
   and that iterates over a named collection (a name, an attribute or a subscript such as `muscles`,
   `state.muscles` or `out["surfaces"]`, also inside enumerate/zip/sorted/reversed/list and `.items()`,
   `.keys()`, `.values()`) must have that collection asserted outside the loop: some `assert` of the
   function mentions it (`assert muscles`, `assert len(rows) == 4`, `assert crossing, "..."`). Loops over
   literals, range(...), or the result of a call are not checked (their length is not a name to assert).
2. all(). `assert all(... for x in <collection>)` passes on an empty collection: the same collection must be
   mentioned by an assert outside the generator (`assert crossing and all(... for m in crossing)`).
3. C++ (tests/cpp/*.cpp, read as text with comments and literals blanked): a range-for loop in a TEST whose
   body holds an EXPECT_/ASSERT_ and whose range is a named collection (`r.muscles`, `profiles`, not a call or a
   braced list) must have the collection mentioned by an EXPECT_/ASSERT_ outside the loop, or increment a counter
   (`++checked`) that one of them asserts. Index loops (`for (int i = 0; ...)`) are not checked.

A collection bound to a non-empty literal (`POSES = [...]` at module level, `cases = {...}` in the function)
needs no assert. Loops in helpers count too (a helper's loop over its argument must assert the argument).

Mark a deliberate exception with a comment `# hygiene: <why>` (`// hygiene: <why>` in C++) on the `for`/`assert`
line.
The checker's own tests below run it on inline samples of the pattern (it must fail on them) and on the
tree (it must pass)."""
import ast
import glob
import os
import re

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
    if isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Slice):
        node = node.value  # energy[1:]: asserting on `energy` (its length) is what guards it
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


def _non_empty_literal(node):
    """True for a non-empty list, tuple, set or dict literal, or a sum with one (`[a, b] + list(rest)`)."""
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add):
        return _non_empty_literal(node.left) or _non_empty_literal(node.right)
    if isinstance(node, ast.Dict):
        return bool(node.keys)
    return isinstance(node, (ast.List, ast.Tuple, ast.Set)) and bool(node.elts)


def _literal_names(scope):
    """Names bound in `scope`'s own statements to a non-empty literal."""
    out = set()
    for stmt in ast.walk(scope):
        if isinstance(stmt, ast.Assign) and _non_empty_literal(stmt.value):
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


def strip_cpp(src):
    """C++ source with comments and string/char literals blanked (same length, newlines kept)."""
    out, i, n = [], 0, len(src)
    while i < n:
        if src.startswith("//", i):
            j = src.find("\n", i)
            j = n if j < 0 else j
        elif src.startswith("/*", i):
            j = src.find("*/", i + 2)
            j = n if j < 0 else j + 2
        elif src.startswith('R"(', i):
            j = src.find(')"', i + 3)
            j = n if j < 0 else j + 2
        elif src[i] in "\"'":
            j = i + 1
            while j < n and src[j] != src[i]:
                j += 2 if src[j] == "\\" else 1
            j += 1
        else:
            out.append(src[i])
            i += 1
            continue
        out.append(re.sub(r"[^\n]", " ", src[i:j]))
        i = j
    return "".join(out)


def _closing(s, i, open_, close):
    """Index of the bracket that closes the one at s[i]."""
    depth = 0
    for j in range(i, len(s)):
        depth += (s[j] == open_) - (s[j] == close)
        if depth == 0:
            return j
    return len(s) - 1


CPP_ASSERT = re.compile(r"\b(?:EXPECT|ASSERT)_\w+\s*\(")


def _statement_end(s, k):
    """Index of the end of the statement starting at s[k] (a block, or up to its ';' with nested headers)."""
    if s[k] == "{":
        return _closing(s, k, "{", "}")
    end = s.find(";", k)
    if re.match(r"(for|if|while)\b", s[k:]) and "{" in s[k:end]:
        return _closing(s, s.find("{", k), "{", "}")
    return end


def check_cpp_source(src, path="<sample>"):
    """[(path, line, message)] of GoogleTest range-for loops with assertions over a collection never asserted."""
    s = strip_cpp(src)
    lines = src.splitlines()
    problems = []
    for t in re.finditer(r"\bTEST(?:_F|_P)?\s*\(", s):
        body_open = s.find("{", _closing(s, t.end() - 1, "(", ")"))
        body_close = _closing(s, body_open, "{", "}")
        asserts = [(a.start(), _closing(s, a.end() - 1, "(", ")"))
                   for a in CPP_ASSERT.finditer(s, body_open, body_close)]
        for f in re.compile(r"\bfor\s*\(").finditer(s, body_open, body_close):
            header_close = _closing(s, f.end() - 1, "(", ")")
            parts = re.split(r"(?<!:):(?!:)", s[f.end():header_close])
            if len(parts) != 2:
                continue  # an index loop
            collection = parts[1].strip()
            if collection.startswith("{") or "(" in collection:
                continue  # a braced list, or the result of a call
            k = header_close + 1
            while s[k].isspace():
                k += 1
            end = _statement_end(s, k)
            line = s.count("\n", 0, f.start()) + 1
            if not CPP_ASSERT.search(s, k, end + 1) or "hygiene:" in lines[line - 1]:
                continue
            outside = [s[a0:a1] for a0, a1 in asserts if a1 < f.start() or a0 > end]
            counters = {a or b for a, b in re.findall(r"\+\+\s*(\w+)|(\w+)\s*(?:\+\+|\+=)", s[k:end + 1])}
            names = [re.escape(collection)] + [re.escape(c) for c in counters]
            if any(re.search(r"(?<![\w.])(?:" + "|".join(names) + r")(?!\w)", text) for text in outside):
                continue
            literal = re.compile(r"(?<![\w.])" + re.escape(collection) + r"\s*(?:\[\w*\])?\s*(?:=\s*)?\{\s*[^}\s]")
            if literal.search(s, body_open, f.start()) or literal.search(s, 0, t.start()):
                continue  # bound to a non-empty braced list
            problems.append((path, line, f"EXPECT/ASSERT inside a loop over `{collection}` that may be empty (assert "
                                         f"it is non-empty, or count the iterations and assert the count)"))
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


def test_the_cpp_tests_have_no_vacuous_loops():
    files = sorted(glob.glob(os.path.join(TESTS_DIR, "cpp", "test_*.cpp")))
    assert len(files) >= 15, files
    problems = []
    for path in files:
        problems += check_cpp_source(open(path, encoding="utf-8").read(), os.path.relpath(path, TESTS_DIR))
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
POINTS = [(0, 0, 0)] + list(more)

def test_poses(rig):
    cases = {"a": 1, "b": 2}
    for label, value in cases.items():
        assert value > 0, label
    for pose in POSES:
        assert rig.evaluate(pose)
    for p in POINTS:
        assert p
    energy = rig.trace()
    assert len(energy) >= 2 and all(b <= a for a, b in zip(energy, energy[1:]))
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
    (VACUOUS, 4, "muscles"), (EMPTY_LITERAL, 4, "poses"), (VACUOUS_NESTED, 4, "out['surfaces']"),
    (VACUOUS_ALL, 4, "straight")])
def test_checker_fails_on_the_pattern(sample, line, collection):
    problems = check_source(sample)
    assert [(p[1], collection in p[2]) for p in problems] == [(line, True)], problems


@pytest.mark.parametrize("sample", [GUARDED, GUARDED_AFTER, LITERAL, MARKED])
def test_checker_passes_guarded_loops(sample):
    assert check_source(sample) == []


CPP_VACUOUS = '''
TEST(Extraction, EveryMuscleIsClosed) {
  const ExtractionResult r = extractMuscles(arm);  // "for (const Muscle& m : r.muscles)" in a comment
  for (const Muscle& m : r.muscles) {
    EXPECT_TRUE(analyzeTopology(m.surface).closed()) << m.name;
  }
  for (const SkippedSection& s : r.report.skipped) EXPECT_FALSE(s.reason.empty());
}
'''

CPP_GUARDED = '''
const int kSeeds[] = {1, 2};

TEST(Extraction, EveryMuscleIsClosed) {
  const ExtractionResult r = extractMuscles(arm);
  ASSERT_GE(r.muscles.size(), 4u);
  for (const Muscle& m : r.muscles) EXPECT_TRUE(analyzeTopology(m.surface).closed()) << m.name;
  int open = 0;
  for (const SkippedSection& s : r.report.skipped)
    if (s.reason == "open") {
      ++open;
      EXPECT_FALSE(s.reason.empty());
    }
  EXPECT_GE(open, 1);
  for (int seed : kSeeds) EXPECT_GT(seed, 0);
  for (double k : {0.0, 1.0}) EXPECT_GE(k, 0.0);
  for (const Bump& b : findBumps(p)) EXPECT_GT(b.protrusion, 0.0);
  for (int i = 0; i < n; ++i) EXPECT_GT(i, -1);
  for (const Bone& b : sk.bones)  // hygiene: a skeleton has bones
    EXPECT_FALSE(b.name.empty());
}
'''


def test_cpp_checker_fails_on_the_pattern_and_passes_guarded_loops():
    problems = check_cpp_source(CPP_VACUOUS)
    assert [(line, message.split("`")[1]) for _p, line, message in problems] == \
        [(4, "r.muscles"), (7, "r.report.skipped")], problems
    assert check_cpp_source(CPP_GUARDED) == []
