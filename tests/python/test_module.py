"""The _core module: build info, arrays in and out, validation errors as ValueError."""
import os
import sys

import numpy as np
import pytest

from conftest import MUSCULAR, shared


def test_build_info_matches_this_interpreter(core):
    info = core.build_info()
    assert info["python_version"] == f"{sys.version_info.major}.{sys.version_info.minor}"
    assert info["myoskin_version"] == core.__version__


def test_numpy_is_the_one_this_tier_runs_under(core):
    """The numpy-2 tier (tests/CMakeLists.txt) puts numpy 2 first on the path: that it really does, and that the
    module was built with a pybind11 that reads numpy 2's arrays (2.12 or newer; 2.10 crashed on the first array)."""
    expected = os.environ.get("MYOSKIN_EXPECT_NUMPY_MAJOR")
    if expected:
        assert np.__version__.split(".")[0] == expected, (
            f"numpy {np.__version__} from {np.__file__}, where this tier expects {expected}.x "
            "(./myoskin.sh setup installs it into the build folder)")
    version = tuple(int(x) for x in core.build_info()["pybind11_version"].split(".")[:2])
    assert version >= (2, 12), f"built with pybind11 {version}: numpy 2 arrays would crash the interpreter"


def _tetra_arrays():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.int32)
    rest = np.eye(4)[None].repeat(1, axis=0)
    return dict(name="tet", vertices=v, triangles=f, bone_names=["root"], bone_parents=np.array([-1], np.int32),
                bone_heads=np.zeros((1, 3)), bone_tails=np.array([[0.0, 1.0, 0.0]]), bone_rest=rest,
                weight_joints=np.zeros((4, 1), np.int32), weight_values=np.ones((4, 1)))


def test_character_from_arrays_round_trip(core):
    a = _tetra_arrays()
    c = core.character_from_arrays(**a)
    np.testing.assert_array_equal(c.vertices, a["vertices"])
    np.testing.assert_array_equal(c.triangles, a["triangles"])
    np.testing.assert_array_equal(c.bone_rest, a["bone_rest"])
    topo = c.topology()
    assert topo["closed"] and topo["manifold"] and topo["oriented"] and topo["components"] == 1
    assert c.volume() == pytest.approx(1.0 / 6.0, rel=1e-12)
    # Views are read-only: nobody can corrupt the core's data from Python by accident.
    with pytest.raises(ValueError):
        c.vertices[0, 0] = 5.0


@pytest.mark.parametrize("change, message", [
    (lambda a: a["vertices"].__setitem__((2, 1), np.nan), "vertex 2"),
    (lambda a: a["triangles"].__setitem__((1, 2), 9), "triangle 1"),
    (lambda a: a["bone_tails"].__setitem__((0, 1), 0.0), "zero length"),
    (lambda a: a["weight_values"].__setitem__((3, 0), -0.5), "vertex 3"),
    (lambda a: a["weight_joints"].__setitem__((1, 0), 4), "vertex 1"),
])
def test_bad_arrays_raise_value_error_naming_the_item(core, change, message):
    a = _tetra_arrays()
    change(a)
    with pytest.raises(ValueError, match=message):
        core.character_from_arrays(**a)


def test_mismatched_shapes_raise_value_error(core):
    a = _tetra_arrays()
    a["weight_values"] = np.ones((3, 1))
    with pytest.raises(ValueError):
        core.character_from_arrays(**a)
    a = _tetra_arrays()
    a["bone_rest"] = np.eye(4)
    with pytest.raises(ValueError, match="4 by 4"):
        core.character_from_arrays(**a)


def test_topology_of_open_mesh(core):
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=np.float64)
    f = np.array([[0, 1, 2]], dtype=np.int32)
    topo = core.analyze_topology(v, f)
    assert topo["boundary_edges"] == 3 and not topo["closed"]


def test_load_character_releases_data_as_numpy(core):
    c = core.load_character(shared(MUSCULAR))
    assert c.vertices.shape == (13380, 3) and c.vertices.dtype == np.float64
    assert c.triangles.shape == (26756, 3) and c.triangles.dtype == np.int32
    assert c.num_bones == 163 and len(c.bone_names) == 163
    sums = c.weight_values.sum(axis=1)
    np.testing.assert_allclose(sums, 1.0, atol=1e-5)


def test_load_errors_are_value_errors(core, tmp_path):
    with pytest.raises(ValueError, match="nothing.glb"):
        core.load_character(str(tmp_path / "nothing.glb"))
    bad = tmp_path / "bad.glb"
    bad.write_text("this is not a glTF file")
    with pytest.raises(ValueError):
        core.load_character(str(bad))
