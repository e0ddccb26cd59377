"""User control after extraction: re-attaching a muscle to moved origin/insertion points, welding seams."""
import numpy as np
import pytest


@pytest.fixture(scope="module")
def arm(core):
    character, _truth = core.make_synthetic_arm(seed=1)
    return character


@pytest.fixture(scope="module")
def muscles(core, arm):
    found, _ = core.extract_muscles(arm)
    assert found
    return found


def test_reattach_unchanged_reproduces_the_extraction(core, arm, muscles):
    assert muscles
    for m in muscles:
        again = core.reattach_muscle(m, character=arm)  # kept inside the skin like the extraction's surfaces
        assert np.abs(np.asarray(again.root_curve) - np.asarray(m.root_curve)).max() < 1e-12
        assert np.abs(np.asarray(again.section_u) - np.asarray(m.section_u)).max() < 1e-12
        assert np.abs(np.asarray(again.surface_vertices) - np.asarray(m.surface_vertices)).max() < 1e-12


def test_reattach_moves_the_ends_and_keeps_the_sections(core, muscles):
    m = muscles[0]
    moved = core.muscles_from_json(core.muscles_to_json([m]))[0]
    moved.insertion = np.asarray(m.insertion) + [0.0, 0.0, 0.03]
    out = core.reattach_muscle(moved)
    curve = np.asarray(out.root_curve)
    assert np.abs(curve[-1] - np.asarray(moved.insertion)).max() < 1e-12
    assert np.abs(curve[0] - np.asarray(m.origin)).max() < 1e-12
    assert np.array_equal(np.asarray(out.section_centers), np.asarray(m.section_centers))
    u = np.asarray(out.section_u)
    assert np.all(np.diff(u) > 0) and u[0] > -1 and u[-1] < 1
    v, t = np.asarray(out.surface_vertices), np.asarray(out.surface_triangles)
    assert len(t) == 2 * len(v) - 4  # still closed
    assert np.linalg.norm(v - np.asarray(moved.insertion), axis=1).min() < 1e-12  # the cap's pole
    # the input is not modified
    assert np.abs(np.asarray(moved.root_curve) - np.asarray(m.root_curve)).max() < 1e-12


def test_reattach_bad_input(core, muscles):
    bad = core.muscles_from_json(core.muscles_to_json([muscles[0]]))[0]
    bad.origin = [np.nan, 0.0, 0.0]
    with pytest.raises(ValueError, match="not finite"):
        core.reattach_muscle(bad)
    with pytest.raises(ValueError, match="ring_vertices"):
        core.reattach_muscle(muscles[0], ring_vertices=2)
    with pytest.raises(ValueError, match="no sections"):
        core.reattach_muscle(core.Muscle())


def test_weld_mesh_merges_seams(core):
    # two triangles of a quad with the shared edge's vertices duplicated (a UV seam)
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
    f = np.array([[0, 1, 2], [3, 4, 5]], dtype=np.int32)
    wv, wf, weld_map = core.weld_mesh(v, f, 1e-6)
    assert len(wv) == 4 and len(wf) == 2
    assert weld_map[1] == weld_map[3] and weld_map[2] == weld_map[5] and len(set(weld_map)) == 4
    assert np.abs(np.asarray(wv)[weld_map] - v).max() == 0.0
    with pytest.raises(ValueError):
        core.weld_mesh(v, f, -1.0)
