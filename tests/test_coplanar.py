"""Overlapping surfaces in one plane: the same choice across the whole overlap, at every scale, by the stated order
(tracer.exact.ties, tracer.scene.coplanar), and the pixels the format leaves open (tracer.render.Picture)."""

import copy
import itertools

import numpy as np
import pytest

import schemas
from tracer import Renderer
from tracer.exact.best import Best
from tracer.exact.intersect import TRIANGLE, Intersector
from tracer.scene.coplanar import coplanar_groups
from tracer.scene.world import build_world

from helpers import scaled, translated

#: a glass box 2 × 1.5 × 2 whose bottom lies in the floor's plane y = 0, its faces' normals outward
CORNERS = [[x, y, z] for y in (0.0, 1.5) for z in (-1.0, 1.0) for x in (-1.0, 1.0)]
BOTTOM = [[0, 1, 3], [0, 3, 2]]
SIDES = [
    [4, 7, 5],
    [4, 6, 7],
    [0, 5, 1],
    [0, 4, 5],
    [1, 7, 3],
    [1, 5, 7],
    [3, 6, 2],
    [3, 7, 6],
    [2, 4, 0],
    [2, 6, 4],
]
MATERIALS = {
    "floor": {"diffuse": [0.8, 0.3, 0.2], "checker": {"size": 0.5, "material": "dark"}},
    "dark": {"diffuse": [0.1, 0.3, 0.8]},
    "glass": {"diffuse": 0.02, "ambient": 0, "specular": 0.5, "transmittance": 0.9, "reflectance": 0.05},
    "tile": {"diffuse": [0.2, 0.8, 0.2]},
}


def glass_box(bottom=True):
    return {"type": "mesh", "material": "glass", "vertices": CORNERS, "faces": (BOTTOM if bottom else []) + SIDES}


def floor(kind):
    if kind == "plane":
        return {"type": "plane", "material": "floor", "point": [0, 0, 0], "normal": [0, 1, 0]}
    verts = [[-6.0, 0.0, -6.0], [6.0, 0.0, -6.0], [-6.0, 0.0, 6.0], [6.0, 0.0, 6.0]]
    return {"type": "mesh", "material": "floor", "vertices": verts, "faces": [[0, 2, 3], [0, 3, 1]]}


def box_scene(kind="plane", floor_first=True, bottom=True, size=(64, 48)):
    objects = [floor(kind), glass_box(bottom)]
    return {
        "camera": {"position": [1.5, 3.2, 4.5], "look_at": [0, 0.3, 0], "fov": 45},
        "image": {"width": size[0], "height": size[1], "background": [0.5, 0.7, 1.0]},
        "materials": copy.deepcopy(MATERIALS),
        "objects": objects if floor_first else objects[::-1],
        "lights": [{"type": "ambient", "color": 0.2}, {"type": "point", "position": [3, 6, 4], "color": 1}],
    }


def picture(data):
    return Renderer(schemas.validate_scene(data)).picture(threads=1)


@pytest.mark.parametrize("kind", ["plane", "mesh"])
def test_a_glass_box_resting_on_a_floor_shows_the_floor_through_its_bottom(kind):
    # the bottom face lies in the floor's plane: a ray inside the glass meets the floor there (opaque first), so
    # the image is the one without the bottom face, whichever object comes first, with no sky speckled through
    without = picture(box_scene(kind, bottom=False)).pixels
    for floor_first in (True, False):
        got = picture(box_scene(kind, floor_first)).pixels
        assert np.array_equal(got, without), np.count_nonzero(np.any(got != without, axis=2))


@pytest.mark.parametrize("kind", ["plane", "mesh"])
def test_the_choice_in_a_coplanar_overlap_is_the_same_at_every_scale_and_place(kind):
    data = box_scene(kind, floor_first=False)
    base = picture(data)
    assert base.open.any()
    # a move by multiples of twice the checker's cell (the format's condition), and uniform scales
    for other in (scaled(data, 1e15), scaled(data, 1e-15), scaled(data, 1e30), translated(data, (3e5, -2e5, 1e5))):
        got = picture(other)
        assert np.array_equal(got.pixels, base.pixels), np.count_nonzero(np.any(got.pixels != base.pixels, axis=2))
        assert np.array_equal(got.open, base.open)


def test_the_open_pixels_are_those_whose_rays_meet_the_overlap():
    with_bottom, without = picture(box_scene()), picture(box_scene(bottom=False))
    assert not without.open.any()  # no surfaces in one plane: nothing is open
    # seen through the glass, the floor under the box; the open floor and sky around it are not open
    assert 0.05 < with_bottom.open.mean() < 0.4
    assert not with_bottom.open[:, :4].any() and not with_bottom.open[-4:].any()
    # a mesh floor, of faces that are neither open among themselves nor with anything but the box's bottom
    assert np.array_equal(picture(box_scene("mesh")).open, with_bottom.open)


def test_a_tile_on_a_floor_shows_by_the_order_of_ties():
    # an opaque tile (a triangle) in a plane floor's plane: planes come before triangles, so the floor shows; a
    # floor that lets light through comes after any opaque surface, so then the tile shows
    tile = {"type": "triangle", "material": "tile", "vertices": [[-1, 0, 1], [1, 0, 1], [0, 0, -1]]}
    data = {
        "camera": {"position": [0, 4, 0.01], "look_at": [0, 0, 0], "fov": 40},
        "image": {"width": 24, "height": 24},
        "materials": {"tile": {"diffuse": [0.2, 0.8, 0.2]}, "floor": {"diffuse": [0.8, 0.2, 0.2]}},
        "objects": [tile, {"type": "plane", "material": "floor", "point": [0, 0, 0], "normal": [0, 1, 0]}],
        "lights": [{"type": "directional", "direction": [0, -1, 0], "color": 1}],
    }
    centre = picture(data).pixels[12, 12]
    assert centre[0] > centre[1]  # the floor's red
    data["materials"]["floor"]["transmittance"] = 0.5
    centre = picture(data).pixels[12, 12]
    assert centre[1] > centre[0]  # the tile's green


def test_coplanar_groups_join_surfaces_of_different_objects_in_one_plane_only():
    world = build_world(schemas.validate_scene(box_scene("mesh")))
    groups = world.coplanar
    assert groups is not None
    # the floor's two faces and the box's bottom two, one group; the box's other faces none
    tris = world.triangles
    in_floor = np.flatnonzero(tris.object == 0)
    bottom = np.flatnonzero((tris.object == 1) & (tris.face < 2))
    assert len(set(groups.triangle[np.r_[in_floor, bottom]].tolist())) == 1
    assert np.all(groups.triangle[(tris.object == 1) & (tris.face >= 2)] == -1)
    # a box alone (its faces in pairs in one plane, but of one object) makes no group
    alone = build_world(schemas.validate_scene({**box_scene("mesh"), "objects": [glass_box()]}))
    assert alone.coplanar is None


@pytest.mark.parametrize("gap, one", [(0.0, True), (2e-15, True), (1e-12, False)])
def test_a_tilted_contact_is_one_plane_within_rounding_and_two_beyond(gap, one):
    # the floor and a tile on it, turned and moved far from the origin: their corners round, their plane does not
    rng = np.random.default_rng(4)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    q = np.linalg.qr(np.column_stack([axis, rng.normal(size=(3, 2))]))[0]
    shift = np.array([1e5, -3e4, 2e5])

    def place(p):
        return [float(v) for v in q @ np.asarray(p, float) + shift]

    lift = gap * 2e5  # (of the magnitudes)
    tile = {
        "type": "triangle",
        "material": "tile",
        "vertices": [place([x, lift, z]) for x, z in ((0, 0), (1, 0), (0, 1))],
    }
    plane = {"type": "plane", "material": "floor", "point": place([0.3, 0, 0.2]), "normal": [float(v) for v in q[:, 1]]}
    data = {**box_scene(), "objects": [plane, tile]}
    data["camera"] = {"position": place([0.3, 2, 0.3]), "look_at": place([0.3, 0, 0.3])}
    world = build_world(schemas.validate_scene(data))
    grouped = world.coplanar is not None and world.coplanar.triangle[0] >= 0
    assert grouped == one


def test_the_best_hit_and_its_openness_do_not_depend_on_the_order_of_candidates():
    world = build_world(schemas.validate_scene(box_scene("mesh")))
    ties = Intersector(world).ties
    # one ray, four candidates: two at the nearest t (a floor's face, the box's bottom face), two behind
    cands = [(TRIANGLE, 2, 2.0), (TRIANGLE, 0, 2.0), (TRIANGLE, 3, 2.5), (TRIANGLE, 5, 2.0 + 2**-51)]
    seen = set()
    for order in itertools.permutations(cands):
        for split in range(len(order) + 1):  # offered in one call or in two
            best = Best(np.full(1, np.inf), ties)
            for part in (order[:split], order[split:]):
                if part:
                    kind = np.array([c[0] for c in part])
                    best.offer(
                        np.zeros(len(part), dtype=np.int64),
                        np.array([c[2] for c in part]),
                        kind,
                        np.array([c[1] for c in part]),
                    )
            assert best.open is not None
            seen.add((int(best.key[0]), float(best.t[0]), bool(best.open[0])))
    assert len(seen) == 1
    ((key, t, opened),) = seen
    assert t == 2.0 and opened and key == int(ties.key(TRIANGLE, np.array([0]))[0])  # the floor's, opaque first


def test_without_coplanar_surfaces_there_are_no_groups():
    world = build_world(schemas.validate_scene(box_scene(bottom=False)))
    assert world.coplanar is None and coplanar_groups(world.planes, world.triangles) is None


@pytest.mark.parametrize("lift", [2.0**-52, 2.0**-50, 2.0**-49, 0.9 * 2.0**-48])
def test_a_tile_within_rounding_of_a_floor_is_in_it(lift):
    # a tile lifted off a floor by less than the groups' tolerance (of the magnitudes, about 1 here) lies in the
    # floor's plane: the image of a tile lying on it, the floor lit under it too (a shadow ray leaving the floor
    # leaves the tile's group: it starts in their plane), not shadowed by the tile a rounding above it
    def data(y):
        tile = {"type": "triangle", "material": "tile", "vertices": [[-1, y, 1], [1, y, 1], [0, y, -1]]}
        return {
            "camera": {"position": [0.3, 3, 2], "look_at": [0, 0, 0], "fov": 50},
            "image": {"width": 40, "height": 30},
            "materials": {"tile": {"diffuse": [0.2, 0.8, 0.2]}, "floor": {"diffuse": [0.8, 0.2, 0.2]}},
            "objects": [{"type": "plane", "material": "floor", "point": [0, 0, 0], "normal": [0, 1, 0]}, tile],
            "lights": [{"type": "point", "position": [1, 4, 1], "color": 1}],
        }

    assert np.array_equal(picture(data(lift)).pixels, picture(data(0.0)).pixels)


def test_a_grade_does_not_count_the_open_pixels_against_a_submission():
    # a student whose tracer breaks the tie the other way shows the background through the glass box's bottom:
    # every open pixel differs, and nothing else does
    from service.images import grading
    from service.work import pipeline
    from tracer import encode_png

    data = box_scene(size=(80, 60))
    scene = schemas.validate_scene(data)
    ref = picture(data)
    student = ref.pixels.copy()
    student[ref.open] = [128, 179, 255]
    assert not grading.grade(ref.pixels, student, "", 2.0, 0.001).passed
    assert grading.grade(ref.pixels, student, "", 2.0, 0.001, ref.open).passed
    png = encode_png(ref.pixels)
    explaining = pipeline.Explaining(lambda: scene, pipeline.Checks({}, diagnose=False), pipeline.Checking(threads=1))
    assert pipeline.grade_png(png, encode_png(student), 2.0, 0.001, explaining=explaining).grade.passed
    # a mistake outside them still fails: the box's shadow on the floor around it lit
    shadow = np.all(ref.pixels < 60, axis=2) & ~ref.open
    assert shadow.mean() > 0.005
    wrong = student.copy()
    wrong[shadow] += 100
    assert not pipeline.grade_png(png, encode_png(wrong), 2.0, 0.001, explaining=explaining).grade.passed


def test_a_variant_world_of_the_opaque_surfaces_alone_keeps_its_own_groups():
    # the variant whose glass casts no shadow traces shadow rays in a world of the opaque surfaces alone: its
    # coplanar groups are those of the surfaces it keeps, numbered as it numbers them (the glass box's bottom
    # gone, an opaque box resting on the floor is grouped with it), and the glass box on the floor renders as the
    # box without its bottom renders
    from tracer.scene.variants import VARIANTS
    from tracer.shade.seethrough import Opaque

    data = box_scene("mesh", floor_first=False)
    cube = copy.deepcopy(glass_box())
    cube["material"] = "tile"
    cube["vertices"] = [[x + 3.0, y, z] for x, y, z in cube["vertices"]]
    data["objects"].insert(1, cube)
    opaque = Opaque(build_world(schemas.validate_scene(data))).world
    assert opaque.coplanar is not None and len(opaque.coplanar.triangle) == len(opaque.triangles.v0) == 14
    grouped = (opaque.triangles.object == 2) | ((opaque.triangles.object == 1) & (opaque.triangles.face < 2))
    assert np.all(opaque.coplanar.triangle[grouped] == 0) and np.all(opaque.coplanar.triangle[~grouped] == -1)
    options = VARIANTS["transparent-no-shadows"][0]
    for kind in ("plane", "mesh"):
        with_bottom = Renderer(schemas.validate_scene(box_scene(kind, floor_first=False)), options).pixels()
        without = Renderer(schemas.validate_scene(box_scene(kind, floor_first=False, bottom=False)), options).pixels()
        assert np.array_equal(with_bottom, without)
