"""The Embree BVH (tracer/exact/embree.py): its frame, and that the fast copy of a mesh gives Embree the same mesh."""

from unittest import mock

import numpy as np

from tracer.exact import embree
from tracer.exact.embree import Bvh, frame


def random_mesh(n_vertices=3000, n_faces=6000, seed=2):
    rng = np.random.default_rng(seed)
    vertices = rng.uniform(-5, 5, (n_vertices, 3)) + [1e3, -2e3, 7.0]
    return vertices, rng.integers(0, n_vertices, (n_faces, 3))


def rays(n=4000, seed=4):
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    return rng.uniform(-8, 8, (n, 3)) + [1e3, -2e3, 7.0], d / np.linalg.norm(d, axis=1, keepdims=True)


def test_the_frame_is_centred_and_a_power_of_two():
    centre, half = frame(np.array([1.0, 2, 3]), np.array([4.0, 10, 5]))
    assert np.array_equal(centre, [2.5, 6, 4]) and half == 4.0
    assert frame(np.ones(3), np.ones(3))[1] == 1.0  # a box of one point still gets a size


def test_the_object_copy_gives_embree_the_same_mesh():
    vertices, faces = random_mesh()
    centre, half = frame(vertices.min(axis=0), vertices.max(axis=0))
    fast = Bvh(vertices, faces, centre, half)
    with mock.patch.object(embree, "_as_objects", side_effect=TypeError):  # the typed arrays, as embreex takes
        typed = Bvh(vertices, faces, centre, half)
    o, d = rays()
    far = np.full(len(o), np.inf)
    face_a, t_a = fast.nearest(o, d, far)
    face_b, t_b = typed.nearest(o, d, far)
    assert np.sum(face_a >= 0) > 1000  # most rays hit something
    assert np.array_equal(face_a, face_b) and np.array_equal(t_a, t_b)
    short = np.full(len(o), 0.5)
    blocked = fast.any_hit(o, d, short)
    assert 0 < np.sum(blocked) < len(o) and np.array_equal(blocked, typed.any_hit(o, d, short))


def test_objects_hold_the_float32_values_exactly():
    corners = np.array([[0.1, 1e-30, 3e38], [-2.5, 7.0, 1 / 3]], dtype=np.float32)
    objects, faces = embree._as_objects(corners, np.array([[0, 1, 1]], dtype=np.int32))
    assert objects.dtype == object and faces.dtype == object and faces[0] == (0, 1, 1)
    assert np.array_equal(np.array(objects.tolist(), dtype=np.float32), corners)
