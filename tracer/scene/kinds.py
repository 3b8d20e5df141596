"""The kinds of surface, in one list: what a hit is (``Hits.kind``) and what a ray leaves (``Rays.from_kind``).

MISS is none.  Each kind has an exact test in :mod:`tracer.scene.shapes`, arrays in :mod:`tracer.scene.world` and a
place in :mod:`tracer.exact.intersect`.  A module of its own, with no imports, so that the ray batches
(:mod:`tracer.scene.rays`) and the proofs name the kinds without standing on the exact tests.
"""

MISS, SPHERE, PLANE, TRIANGLE = 0, 1, 2, 3
KINDS = {SPHERE: "sphere", PLANE: "plane", TRIANGLE: "triangle"}
#: the kinds that lie in a plane (a triangle only without vertex normals, which the shading normal decides)
FLAT = (PLANE, TRIANGLE)
