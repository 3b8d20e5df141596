"""Words for a student (schemas/names.py): an object or a light by its name, else by its place and kind."""

import pytest

import schemas
from schemas.names import light_words, object_words, ordinal


@pytest.mark.parametrize(
    "n, word",
    [
        (1, "first"),
        (3, "third"),
        (10, "tenth"),
        (11, "11th"),
        (12, "12th"),
        (13, "13th"),
        (21, "21st"),
        (22, "22nd"),
        (23, "23rd"),
        (101, "101st"),
        (111, "111th"),
    ],
)
def test_ordinals(n, word):
    assert ordinal(n) == word


def test_there_is_no_zeroth():
    with pytest.raises(ValueError):
        ordinal(0)


SCENE = {
    "camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
    "image": {"width": 4, "height": 3},
    "materials": {"m": {}},
    "objects": [
        {"type": "plane", "material": "m", "point": [0, -1, 0], "normal": [0, 1, 0]},
        {"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 1},
        {"type": "sphere", "material": "m", "center": [2, 0, 0], "radius": 1, "name": "glass ball"},
        {"type": "sphere", "material": "m", "center": [4, 0, 0], "radius": 1},
    ],
    "lights": [
        {"type": "ambient", "color": 0.1},
        {"type": "point", "color": 1, "position": [0, 3, 3], "name": "key"},
        {"type": "area", "color": 1, "corner": [0, 3, 0], "edge_u": [1, 0, 0], "edge_v": [0, 0, 1]},
    ],
}


def test_an_object_is_its_name_or_its_place_among_its_type():
    scene = schemas.validate_scene(SCENE)
    assert [object_words(scene, k) for k in range(4)] == [
        "the first plane",
        "the first sphere",
        "sphere 'glass ball'",
        "the third sphere",
    ]


def test_a_light_is_its_name_or_its_place_and_type():
    scene = schemas.validate_scene(SCENE)
    assert [light_words(scene, k) for k in range(3)] == [
        "the first light (ambient)",
        "light 'key'",
        "the third light (area)",
    ]
