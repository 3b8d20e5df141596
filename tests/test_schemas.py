"""Validation: every rule of the format is enforced and every error names its place."""

import json
import pickle

import pytest

import schemas

from helpers import EXAMPLES, scene_dict


def minimal(**extra):
    data = {"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]}, "image": {"width": 4, "height": 3}}
    data.update(extra)
    return data


def problems(data):
    with pytest.raises(schemas.SceneError) as info:
        schemas.validate_scene(data)
    return [schemas.format_problem(p) for p in info.value.problems]


@pytest.mark.parametrize("name", EXAMPLES)
def test_examples_are_valid(name):
    schemas.validate_scene(scene_dict(name))


def test_defaults_follow_the_contract():
    s = schemas.validate_scene(
        minimal(
            materials={"m": {}}, lights=[{"type": "spot", "color": 1, "position": [0, 1, 0], "direction": [0, -1, 0]}]
        )
    )
    assert s.version == 1 and s.camera.type == "perspective" and s.camera.fov == 60 and s.camera.up == (0, 1, 0)
    assert s.image.samples == 1 and s.image.max_depth == 4 and s.image.background == (0, 0, 0)
    m = s.materials["m"]
    assert (m.ambient, m.diffuse, m.specular) == ((0.3,) * 3, (0.5,) * 3, (0.8,) * 3)
    assert (m.shininess, m.reflectance, m.transmittance, m.ior) == (100, 0, 0, 1.5)
    spot = s.lights[0]
    assert spot.cutoff == 45 and spot.inner == 45 and spot.exponent == 1 and spot.attenuation == (1, 0, 0)


def test_single_number_colour_means_grey():
    s = schemas.validate_scene(minimal(materials={"m": {"diffuse": 0.25}}))
    assert s.materials["m"].diffuse == (0.25, 0.25, 0.25)


@pytest.mark.parametrize(
    "patch, expected",
    [
        (
            {"objects": [{"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 0}]},
            "objects[0].radius: must be > 0",
        ),
        (
            {"objects": [{"type": "sphere", "material": "gold", "center": [0, 0, 0], "radius": 1}]},
            "objects[0].material: unknown material 'gold'",
        ),
        ({"objects": [{"type": "cube", "material": "m"}]}, "objects[0].type: unknown type 'cube'"),
        (
            {"objects": [{"type": "sphere", "material": "m", "center": [0, 0], "radius": 1}]},
            "objects[0].center: has 2 elements, expected 3",
        ),
        (
            {"objects": [{"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 1, "colour": 1}]},
            "objects[0].colour: unknown key",
        ),
        (
            {"objects": [{"type": "plane", "material": "m", "point": [0, 0, 0], "normal": [0, 0, 0]}]},
            "objects[0].normal: must be non-zero",
        ),
        (
            {"objects": [{"type": "triangle", "material": "m", "vertices": [[0, 0, 0], [1, 1, 1], [2, 2, 2]]}]},
            "objects[0].vertices: must not be collinear",
        ),
        (
            {
                "objects": [
                    {
                        "type": "triangle",
                        "material": "m",
                        "vertices": [[1.7976931348623157e308, 0, 0], [0, 0, 0], [-1e292, 0, 0]],
                    }
                ]
            },
            "objects[0].vertices: are too far apart",
        ),
        (
            {
                "objects": [
                    {
                        "type": "mesh",
                        "material": "m",
                        "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
                        "faces": [[0, 1, 3]],
                    }
                ]
            },
            "objects[0].faces[0][2]: index 3 out of range",
        ),
        (
            {
                "objects": [
                    {
                        "type": "mesh",
                        "material": "m",
                        "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
                        "faces": [[0, 1, 2]],
                        "normals": [[0, 0, 1]],
                    }
                ]
            },
            "objects[0].normals: must have one normal per vertex",
        ),
        (
            {
                "objects": [
                    {
                        "type": "mesh",
                        "material": "m",
                        "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
                        "faces": [[0, 1, 2]],
                        "normals": [[0, 0, 1], [0, 0, 0], [0, 0, 1]],
                    }
                ]
            },
            "objects[0].normals[1]: must be non-zero",
        ),
        (
            {"objects": [{"type": "mesh", "material": "m", "vertices": [[0, 0, 0]], "faces": [[0, -1, 0]]}]},
            "objects[0].faces[0][1]: must be ≥ 0",
        ),
        ({"materials": {"m": {"shininess": -1}}}, "materials.m.shininess: must be ≥ 0"),
        ({"materials": {"m": {"reflectance": 1.5}}}, "materials.m.reflectance: must be ≤ 1"),
        ({"materials": {"m": {"transmittance": -0.1}}}, "materials.m.transmittance: must be ≥ 0"),
        ({"materials": {"m": {"ior": 0}}}, "materials.m.ior: must be > 0"),
        ({"materials": {"m": {"diffuse": [0.1, -0.1, 0]}}}, "materials.m.diffuse[1]: must be ≥ 0"),
        (
            {"materials": {"m": {"checker": {"size": 1, "material": "nope"}}}},
            "materials.m.checker.material: unknown material 'nope'",
        ),
        (
            {
                "materials": {
                    "m": {"checker": {"size": 1, "material": "n"}},
                    "n": {"checker": {"size": 1, "material": "m"}},
                }
            },
            "materials.m.checker.material: material 'n' has a checker itself",
        ),
        ({"materials": {"m": {"checker": {"size": 0, "material": "m"}}}}, "materials.m.checker.size: must be > 0"),
        (
            {"lights": [{"type": "point", "color": 1, "position": [0, 0, 0], "attenuation": [0, 0, 0]}]},
            "lights[0].attenuation: coefficients must not all be zero",
        ),
        (
            {"lights": [{"type": "point", "color": 1, "position": [0, 0, 0], "attenuation": [1, -1, 0]}]},
            "lights[0].attenuation[1]: must be ≥ 0",
        ),
        (
            {"lights": [{"type": "directional", "color": 1, "direction": [0, 0, 0]}]},
            "lights[0].direction: must be non-zero",
        ),
        (
            {
                "lights": [
                    {
                        "type": "spot",
                        "color": 1,
                        "position": [0, 0, 0],
                        "direction": [0, -1, 0],
                        "cutoff": 20,
                        "inner_cutoff": 30,
                    }
                ]
            },
            "lights[0].inner_cutoff: must be ≤ cutoff",
        ),
        (
            {"lights": [{"type": "spot", "color": 1, "position": [0, 0, 0], "direction": [0, -1, 0], "cutoff": 95}]},
            "lights[0].cutoff: must be ≤ 90",
        ),
        (
            {"lights": [{"type": "spot", "color": 1, "position": [0, 0, 0], "direction": [0, -1, 0], "exponent": -1}]},
            "lights[0].exponent: must be ≥ 0",
        ),
        (
            {"lights": [{"type": "area", "color": 1, "corner": [0, 0, 0], "edge_u": [1, 0, 0], "edge_v": [2, 0, 0]}]},
            "lights[0].edge_v: must not be parallel to edge_u",
        ),
        (
            {
                "lights": [
                    {
                        "type": "area",
                        "color": 1,
                        "corner": [0, 0, 0],
                        "edge_u": [1, 0, 0],
                        "edge_v": [0, 1, 0],
                        "samples": [0, 4],
                    }
                ]
            },
            "lights[0].samples[0]: must be ≥ 1",
        ),
        ({"lights": [{"type": "point", "color": [1, 1, 1]}]}, "lights[0].position: required"),
        ({"lights": [{"color": 1}]}, "lights[0].type: 'type' is required"),
        ({"version": 2}, "version: must be 1"),
        ({"extra": 1}, "extra: unknown key"),
    ],
)
def test_rule_is_enforced_at_its_place(patch, expected):
    data = minimal(materials={"m": {}})
    data.update(patch)
    assert any(p.startswith(expected) for p in problems(data)), problems(data)


@pytest.mark.parametrize(
    "camera, expected",
    [
        ({"position": [0, 0, 0], "look_at": [0, 0, 0]}, "camera.look_at: must differ from camera.position"),
        ({"position": [0, 0, 0], "look_at": [0, 5, 0]}, "camera.up: must not be parallel"),
        ({"position": [0, 0, 5], "look_at": [0, 0, 0], "fov": 180}, "camera.fov: must be < 180"),
        ({"position": [0, 0, 5], "look_at": [0, 0, 0], "fov": 0}, "camera.fov: must be > 0"),
        (
            {"position": [0, 0, 5], "look_at": [0, 0, 0], "type": "orthographic", "height": -1},
            "camera.height: must be > 0",
        ),
        ({"position": [0, 0, 5], "look_at": [0, 0, 0], "type": "fisheye"}, "camera.type: must be"),
    ],
)
def test_camera_rules(camera, expected):
    assert any(p.startswith(expected) for p in problems(minimal(camera=camera)))


def test_fov_is_range_checked_for_orthographic_too():
    cam = {"type": "orthographic", "position": [0, 0, 5], "look_at": [0, 0, 0], "fov": 200}
    assert "camera.fov: must be < 180" in problems(minimal(camera=cam))


@pytest.mark.parametrize(
    "image, expected",
    [
        ({"width": 160.0, "height": 120}, "image.width: must be an integer"),
        ({"width": True, "height": 120}, "image.width: must be an integer"),
        ({"width": 0, "height": 120}, "image.width: must be ≥ 1"),
        ({"width": 4, "height": 3, "samples": 0}, "image.samples: must be ≥ 1"),
        ({"width": 4, "height": 3, "max_depth": -1}, "image.max_depth: must be ≥ 0"),
        ({"width": 4}, "image.height: required"),
    ],
)
def test_image_rules(image, expected):
    assert expected in problems(minimal(image=image))


def test_booleans_are_not_numbers():
    assert "materials.m.shininess: must be a number" in problems(minimal(materials={"m": {"shininess": True}}))


def test_every_problem_is_reported_not_just_the_first():
    data = minimal(
        materials={"m": {}},
        objects=[
            {"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": -1},
            {"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": -2},
        ],
    )
    data["image"]["width"] = 0
    assert len(problems(data)) == 3


def test_cross_references_come_in_the_same_answer_as_field_errors():
    data = minimal(
        materials={"gold": {}},
        objects=[
            {"type": "sphere", "material": "glod", "center": [0, 0, 0], "radius": -1},
            {"type": "mesh", "material": "gold", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "faces": [[0, 1, 7]]},
        ],
    )
    assert problems(data) == [
        "objects[0].radius: must be > 0",
        "objects[0].material: unknown material 'glod' (did you mean 'gold'?)",
        "objects[1].faces[0][2]: index 7 out of range (the mesh has 3 vertices)",
    ]


@pytest.mark.parametrize(
    "patch, expected",
    [
        (
            {"camera": {"position": [0, 0, 5], "look_At": [0, 0, 0]}},
            "camera.look_At: unknown key (did you mean 'look_at'?)",
        ),
        (
            {"objects": [{"type": "spher", "material": "m"}]},
            "objects[0].type: unknown type 'spher' (did you mean 'sphere'?) (expected one of 'sphere', 'plane', 'triangle', "
            "'mesh')",
        ),
        (
            {"lights": [{"type": "point", "colour": 1, "position": [0, 0, 0]}]},
            "lights[0].colour: unknown key (did you mean 'color'?)",
        ),
        ({"camera": {"position": [0, 0], "look_at": [0, 0, 0]}}, "camera.position: has 2 elements, expected 3"),
        ({"camera": {"position": [0, 0, 5, 1], "look_at": [0, 0, 0]}}, "camera.position: has 4 elements, expected 3"),
        (
            {
                "lights": [
                    {
                        "type": "area",
                        "color": 1,
                        "corner": [0, 0, 0],
                        "edge_u": [1, 0, 0],
                        "edge_v": [0, 1, 0],
                        "samples": [2],
                    }
                ]
            },
            "lights[0].samples: has 1 element, expected 2",
        ),
    ],
)
def test_misspellings_get_a_suggestion_and_counts_say_what_was_expected(patch, expected):
    assert expected in problems(minimal(materials={"m": {}}, **patch))


def test_cross_references_are_all_reported():
    data = minimal(
        objects=[
            {"type": "sphere", "material": "a", "center": [0, 0, 0], "radius": 1},
            {"type": "sphere", "material": "b", "center": [0, 0, 0], "radius": 1},
        ]
    )
    assert problems(data) == ["objects[0].material: unknown material 'a'", "objects[1].material: unknown material 'b'"]


def test_zero_area_mesh_face_is_allowed():
    schemas.validate_scene(
        minimal(
            materials={"m": {}},
            objects=[
                {"type": "mesh", "material": "m", "vertices": [[0, 0, 0], [1, 0, 0], [2, 0, 0]], "faces": [[0, 1, 2]]}
            ],
        )
    )


@pytest.mark.parametrize(
    "text, expected",
    [
        ('{"a": NaN}', "NaN is not a JSON number"),
        ('{"a": Infinity}', "Infinity is not a JSON number"),
        ('{"a": -Infinity}', "-Infinity is not a JSON number"),
        ('{"a": 1, "a": 2}', "duplicate key 'a'"),
        ('{"a": ', "invalid JSON"),
        ("[1, 2]", "a scene must be a JSON object"),
        (b"\xff\xfe", "invalid JSON"),
        ('{"a": 1}'.encode("utf-16"), "invalid JSON: the document is UTF-16 or UTF-32 text; send it as UTF-8"),
        ('{"a": 1}'.encode("utf-32-le"), "invalid JSON: the document is UTF-16 or UTF-32 text; send it as UTF-8"),
        ('{"image": {"width": 1' + "0" * 5000 + "}}", "invalid JSON: a whole number of more than 4300 digits"),
    ],
)
def test_malformed_documents(text, expected):
    with pytest.raises(schemas.SceneError) as info:
        schemas.load_scene(text)
    assert expected in str(info.value)


def test_numbers_too_large_for_float64_are_rejected():
    data = json.loads(json.dumps(minimal(materials={"m": {}})))
    text = json.dumps(data).replace('"look_at": [0, 0, 0]', '"look_at": [0, 0, 1e400]')
    with pytest.raises(schemas.SceneError) as info:
        schemas.load_scene(text)
    assert "camera.look_at[2]: must be a finite number" in str(info.value)


def _scaled(data: dict, k: float) -> dict:
    """A scene with every coordinate and length times ``k`` (its attenuation scaled with it)."""
    out = json.loads(json.dumps(data))

    def times(v):  # noqa: ANN001, ANN202
        return [times(x) for x in v] if isinstance(v, list) else v * k

    out["camera"].update(position=times(out["camera"]["position"]), look_at=times(out["camera"]["look_at"]))
    for obj in out["objects"]:
        for key in ("center", "point", "vertices", "radius"):
            if key in obj:
                obj[key] = times(obj[key])
    for light in out["lights"]:
        for key in ("position", "corner", "edge_u", "edge_v"):
            if key in light:
                light[key] = times(light[key])
    return out


@pytest.mark.parametrize("k", [1e-30, 1e30])
def test_every_scale_the_format_asks_for_is_valid(k):
    for name in EXAMPLES:
        schemas.validate_scene(_scaled(scene_dict(name), k))


def test_a_coordinate_beyond_what_renders_exactly_is_refused_at_its_place():
    """Beyond 1e60 the tracer's squares and products overflow (a mesh's grid failed from 1e77): refused, named at
    the largest value, not rendered wrong."""
    data = scene_dict("05_mesh")
    data["objects"][1]["vertices"][2][1] = -3e70
    assert problems(data) == [
        "objects[1].vertices[2][1]: 3e+70 is too large: phongray renders coordinates and sizes of at most 1e60 "
        "(scale the scene down)"
    ]
    data = scene_dict("01_three_spheres")
    data["objects"][1]["radius"] = 1e61
    assert [p.split(":")[0] for p in problems(data)] == ["objects[1].radius"]


def test_a_whole_scene_too_small_is_refused_but_one_tiny_value_is_not():
    assert problems(_scaled(scene_dict("05_mesh"), 1e-70))[0].startswith(
        "camera.position[2]: the scene's largest coordinate or size is "
    )
    data = scene_dict("01_three_spheres")
    data["objects"][1]["radius"] = 1e-200  # (a tiny ball in a scene of ordinary size)
    data["objects"][1]["center"] = [1e-300, 0, 0]
    schemas.validate_scene(data)


def test_deep_nesting_is_an_error_not_a_crash():
    with pytest.raises(schemas.SceneError):
        schemas.load_scene("[" * 100_000 + "]" * 100_000)


def test_json_schema_describes_the_format():
    schema = schemas.json_schema()
    assert set(schema["required"]) == {"camera", "image"}
    assert schema["additionalProperties"] is False
    json.dumps(schema)


def test_face_index_beyond_any_mesh_is_an_error_not_a_crash():
    data = minimal(
        materials={"m": {}},
        objects=[{"type": "mesh", "material": "m", "vertices": [[0, 0, 0]], "faces": [[0, 0, 2**63]]}],
    )
    assert any(p.startswith("objects[0].faces[0][2]: must be <") for p in problems(data))


def test_a_long_document_parses_the_same_with_and_without_sharing_the_interpreter():
    from schemas.errors import YIELDING_PARSE

    doc = {"vertices": [[k * 0.5, -k, 1e-3 * k] for k in range(YIELDING_PARSE // 16)], "n": 12345678901234567890}
    text = json.dumps(doc)
    assert len(text) > YIELDING_PARSE
    assert schemas.parse_json(text) == schemas.parse_json(text, shared=False) == doc
    for bad in (text[:-1] + ', "n": 1}', text.replace("0.5", "NaN", 1)):  # a duplicate key; a NaN token
        for shared in (True, False):
            with pytest.raises(schemas.SceneError):
                schemas.parse_json(bad, shared=shared)


# -- the JSON Schema states the format: every shipped scene is valid by a Draft 2020-12 validator --------------

from pathlib import Path  # noqa: E402

from jsonschema import Draft202012Validator  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SHIPPED = sorted(
    [
        *ROOT.glob("examples/*.json"),
        *ROOT.glob("examples/class/scenes/*.json"),
        *ROOT.glob("examples/class/student-scenes/*/*.json"),
        ROOT / "service/static/example.json",
    ]
)


def schema_validator() -> Draft202012Validator:
    schema = schemas.json_schema()
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    Draft202012Validator.check_schema(schema)
    return Draft202012Validator(schema)


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_shipped_scene_is_valid_by_the_json_schema(path):
    errors = [
        f"{'/'.join(map(str, e.absolute_path))}: {e.message}"
        for e in schema_validator().iter_errors(json.loads(path.read_text()))
    ]
    assert errors == []


def test_the_json_schema_allows_colour_shorthands_and_refuses_what_the_format_refuses():
    validator = schema_validator()
    grey = minimal(materials={"m": {"diffuse": 0.5, "specular": [1, 1, 1]}}, lights=[{"type": "ambient", "color": 1}])
    assert validator.is_valid(grey)
    schemas.validate_scene(grey)  # and so does the format
    for wrong in (
        minimal(materials={"m": {"diffuse": -0.5}}),
        minimal(materials={"m": {"diffuse": [1, 1]}}),
        minimal(camera={"position": [0, 0, 5], "look_at": [0, 0, 0], "look_At": [0, 0, 0]}),
        minimal(lights=[{"type": "torch", "color": 1}]),
        {"camera": minimal()["camera"]},
        minimal(image={"width": 0, "height": 3}),
    ):
        assert not validator.is_valid(wrong), wrong
        with pytest.raises(schemas.SceneError):
            schemas.validate_scene(wrong)


@pytest.mark.parametrize(
    "text, says",
    [
        (
            '{"camera": {},\n "image": {"width": 1,}}',
            "a comma after the last item, before '}' (JSON allows none there: delete it) at line 2 column 22",
        ),
        (
            "[1,\n 2,\n]",
            "a comma after the last item, before ']' (JSON allows none there: delete it) at line 2 column 3",
        ),
        ('{\n  // the camera\n  "camera": {}}', "a comment (JSON has no comments: delete it) at line 2 column 3"),
        ("/* a scene */ {}", "a comment (JSON has no comments: delete it) at line 1 column 1"),
        ("{'camera': {}}", 'a string in single quotes (JSON strings take double quotes: "name") at line 1 column 2'),
        ('{"camera": {} "image": {}}', "a comma is missing between two items at line 1 column 15"),
        ('{"camera": {}', "the document ends too early (a closing '}', ']' or '\"' is missing) at line 1 column 14"),
        ("", "the document is empty"),
        (" \n ", "the document is empty"),
    ],
)
def test_json_syntax_errors_are_told_in_plain_words_with_line_and_column(text, says):
    with pytest.raises(schemas.SceneError) as info:
        schemas.load_scene(text)
    assert str(info.value) == "invalid JSON: " + says
    assert "Expecting" not in str(info.value) and "delimiter" not in str(info.value)


def test_a_colour_that_is_a_word_is_told_the_two_forms_it_may_take():
    data = minimal(
        materials={"m": {"diffuse": "white"}}, lights=[{"type": "point", "position": [0, 1, 0], "color": "warm"}]
    )
    data["image"]["background"] = "black"
    colour = "must be an array of 3 numbers [r, g, b] or one number (a grey: 0.5 means [0.5, 0.5, 0.5])"
    assert sorted(problems(data)) == [
        f"image.background: {colour}",
        f"lights[0].color: {colour}",
        f"materials.m.diffuse: {colour}",
    ]
    camera = minimal(materials={"m": {}})
    camera["camera"]["position"] = "here"  # not a colour: an array, and only an array
    assert problems(camera) == ["camera.position: must be an array"]


@pytest.mark.parametrize("key", ["color", "colour"])
def test_a_materials_color_key_is_pointed_to_diffuse(key):
    assert problems(minimal(materials={"m": {key: [1, 0, 0]}})) == [
        f"materials.m.{key}: unknown key (did you mean 'diffuse'?)"
    ]


# -- names (phongray's extension): optional, bounded, unique within their list ------------------------------------


def _named(objects=(), lights=()):
    sphere = {"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 1}
    point = {"type": "point", "color": 1, "position": [0, 2, 3]}
    return minimal(
        materials={"m": {}},
        objects=[sphere | ({"name": n} if n is not None else {}) for n in objects],
        lights=[point | ({"name": n} if n is not None else {}) for n in lights],
    )


def test_objects_and_lights_may_carry_a_name():
    s = schemas.validate_scene(_named(objects=["ball", None], lights=["key", "ball"]))
    assert [o.name for o in s.objects] == ["ball", None] and [light.name for light in s.lights] == ["key", "ball"]
    assert schemas.validate_scene(minimal(lights=[{"type": "ambient", "color": 0.1, "name": "fill"}])).lights[0].name


def test_a_name_used_twice_in_a_list_is_an_error_at_the_second():
    assert problems(_named(objects=["ball", None, "ball"])) == [
        "objects[2].name: 'ball' is already the name of objects[0] (names must be unique)"
    ]
    assert problems(_named(lights=["key", "key"])) == [
        "lights[1].name: 'key' is already the name of lights[0] (names must be unique)"
    ]


@pytest.mark.parametrize(
    "name, said",
    [
        ("", "must not be empty"),
        ("x" * 65, "must be at most 64 characters long"),
        ("a\nb", "must not contain control characters"),
        (3, "must be a string"),
    ],
)
def test_a_bad_name_is_an_error_at_its_place(name, said):
    assert problems(_named(lights=[name])) == [
        f"lights[0].name: {said}" + (" (line breaks, tabs, ...)" if "control" in said else "")
    ]


def test_a_name_changes_no_image_and_unnamed_scenes_keep_their_key():
    from service.render.scenekey import scene_key
    from tracer import Renderer

    plain, named = (schemas.validate_scene(d) for d in (_named([None], [None]), _named(["ball"], ["key"])))
    assert (Renderer(plain).pixels() == Renderer(named).pixels()).all()
    assert scene_key(plain) != scene_key(named)  # (messages speak of the names: a cached diagnosis is per name)
    data = _named([None], [None])
    data["objects"][0]["name"] = data["lights"][0]["name"] = None  # a name of null is no name
    assert scene_key(schemas.validate_scene(data)) == scene_key(plain)


def test_a_scene_error_crosses_processes_as_itself():
    """A SceneError raised in a pool's process is pickled back to the grading process: the same problems."""
    error = schemas.SceneError([("objects[2].radius", "must be > 0"), ("", "no camera")])
    back = pickle.loads(pickle.dumps(error))
    assert isinstance(back, schemas.SceneError) and back.problems == error.problems and str(back) == str(error)
