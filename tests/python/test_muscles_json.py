"""The muscles JSON contract (DESIGN.md section 7): round trip and validation."""
import json

import numpy as np
import pytest


def _muscle(core, name="biceps"):
    m = core.Muscle()
    m.name = name
    m.region = "upper_arm"
    m.origin_bone, m.origin = "upper_arm", np.array([0.2, 0.0, 0.03])
    m.insertion_bone, m.insertion = "forearm", np.array([0.5, 0.0, 0.02])
    m.root_curve = np.array([[0.2, 0.0, 0.03], [0.35, 0.0, 0.05], [0.5, 0.0, 0.02]])
    for u, x in ((-0.5, 0.3), (0.0, 0.35), (0.5, 0.4)):
        m.add_section(u, np.array([x, 0.0, 0.04]), np.array([0.0, 1.0, 0.0]), 0.02, 0.015, np.array([1.0, 0, 0]))
    m.bulge, m.joints = 1.5, 6
    return m


def test_round_trip_keeps_every_field(core, tmp_path):
    m = _muscle(core)
    m.wrap_type, m.wrap_bone, m.wrap_radius, m.wrap_side = "bone", "upper_arm", 0.03, -1
    path = str(tmp_path / "muscles.json")
    core.write_muscles(path, [m, _muscle(core, "triceps")])
    doc = json.load(open(path))
    assert doc["format"] == "myoskin.muscles" and doc["version"] == 1
    assert [x["name"] for x in doc["muscles"]] == ["biceps", "triceps"]
    back = core.read_muscles(path)[0]
    np.testing.assert_array_equal(back.root_curve, m.root_curve)
    np.testing.assert_array_equal(back.section_centers, m.section_centers)
    np.testing.assert_array_equal(back.section_a, m.section_a)
    assert (back.wrap_type, back.wrap_bone, back.wrap_radius, back.wrap_side) == ("bone", "upper_arm", 0.03, -1)
    assert (back.bulge, back.joints, back.origin_bone, back.insertion_bone) == (1.5, 6, "upper_arm", "forearm")


def test_extra_fields_are_allowed(core):
    doc = json.loads(core.muscles_to_json([_muscle(core)]))
    doc["generator"] = "someone else"
    doc["muscles"][0]["colour"] = [1, 0, 0]
    assert core.muscles_from_json(json.dumps(doc))[0].name == "biceps"


@pytest.mark.parametrize("edit, message", [
    (lambda d: d.__setitem__("format", "other"), "format"),
    (lambda d: d.__setitem__("format", 111111111111100043064661329824513), "format"),  # found by fuzz_muscles_json
    (lambda d: d.__setitem__("version", 2), "version"),
    (lambda d: d.__setitem__("version", 2**32 + 1), "version"),  # not read as 1 through an int
    (lambda d: d["muscles"][0].pop("root_curve"), "root_curve"),
    (lambda d: d["muscles"][0]["sections"][1].__setitem__("u", 3.0), "u outside"),
    (lambda d: d["muscles"][0]["sections"][1].__setitem__("a", -1.0), "positive"),
    (lambda d: d["muscles"][0]["wrap"].__setitem__("type", "spiral"), "spiral"),
    (lambda d: d["muscles"][0]["origin"].__setitem__("position", [0, "x", 0]), "origin"),
])
def test_invalid_documents_are_rejected_with_the_field_named(core, edit, message):
    doc = json.loads(core.muscles_to_json([_muscle(core)]))
    edit(doc)
    with pytest.raises(ValueError, match=message):
        core.muscles_from_json(json.dumps(doc))


def test_not_json_is_a_value_error(core):
    with pytest.raises(ValueError, match="not valid JSON"):
        core.muscles_from_json("{nope")
