"""The cost model prices the real work: the worst-case ray tree, the lights and what each ray is tested against."""

import pytest
from test_render import nested_glass_and_mirror

import schemas
from service.limits import LimitError, check_scene, estimated_cost, ray_tree_nodes
from service.settings import Settings


def test_ray_tree_doubles_only_where_a_material_both_reflects_and_transmits():
    both = schemas.validate_scene(nested_glass_and_mirror(16, 8))
    assert ray_tree_nodes(both) == 2**17 - 1
    mirror_only = nested_glass_and_mirror(16, 8)
    mirror_only["materials"] = {"glass": {"reflectance": 0.5}, "mirror": {"reflectance": 0.5}}
    assert ray_tree_nodes(schemas.validate_scene(mirror_only)) == 17


def test_nested_glass_and_mirror_at_depth_16_is_refused_up_front():
    scene = schemas.validate_scene(nested_glass_and_mirror(16, 128))
    with pytest.raises(LimitError, match="max_cost"):
        check_scene(scene, Settings())


def test_thousands_of_spheres_around_the_eye_are_priced_as_such():
    objs = [{"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 1.0 + k} for k in range(10_000)]
    data = {"camera": {"position": [0, 0, 0.5], "look_at": [0, 0, 0]}, "image": {"width": 128, "height": 128},
            "materials": {"m": {}}, "objects": objs, "lights": [{"type": "point", "color": 1, "position": [0, 0, 0]}]}
    inside = schemas.validate_scene(data)
    with pytest.raises(LimitError, match="max_cost"):
        check_scene(inside, Settings())
    data["camera"]["position"] = [0, 0, 2e4]
    assert estimated_cost(schemas.validate_scene(data)) < estimated_cost(inside) / 100
