"""The margins the tracer's proofs rely on, each named once, with the error it covers and why it holds.

A proof spares rays their exact tests (:mod:`tracer.proofs.culling`, :mod:`tracer.proofs.tiles`,
:mod:`tracer.proofs.penumbra`,
:mod:`tracer.proofs.cones`) or lets Embree meet a triangle as it is (:mod:`tracer.proofs.sightlines`).  Each compares
computed numbers with a threshold grown by one of these margins, relative to the magnitudes involved (the
largest coordinates of the points, corners and bounds compared), never a distance picked by hand: so a margin
that covers an error at one scale covers it at every scale, the relative errors of float64 (2^-53) and float32
(2^-24) being the same at every magnitude.  The exact tests (:mod:`tracer.scene.shapes`) keep their own tolerances.
"""

from __future__ import annotations

#: a proof's margin, relative to the magnitudes involved (a distance) or absolute (a cosine of unit vectors).
#: **Covers** the float64 rounding of every number a proof computes: a rounded difference and a dot product of
#: three (a few 2^-53 of the magnitudes), a face normal's direction (:data:`NORMAL_ERROR`, a quarter of this),
#: a tile's centre (2^-53 of its coordinates).  **Holds at every scale** because each such error is a few units
#: in the last place of the same magnitudes the margin is taken of: 2^-30 leaves a factor of 2^20 and more
MARGIN = 2.0**-30
#: how far a face's computed unit normal (:func:`tracer.proofs.bounds.face_normal`) may turn from the true face's and
#: still serve a proof.  **Covers** the roundings of a cross product of a long vector with a short exact one
#: (at most 16·2^-53·|u||e|/|u × e|, kept below this or the face is declined).  The error it brings to a
#: separation, at most (NORMAL_ERROR + 2^-50)·√3 of the magnitudes, is under a quarter of :data:`MARGIN` at
#: every scale, since both are relative to the same magnitudes
NORMAL_ERROR = 2.0**-33
#: the slack over the float64 rounding of a handful of operations, relative to their result: a cosine of unit
#: vectors or a squared distance that :mod:`tracer.proofs.cones` compares, a tile's radius rounded up
#: (:func:`tracer.proofs.tiles.tiles_of`).  **Covers** a dot product or a sum of three squares and a root (three
#: products, two sums, a root: a few 2^-53 of the result, so at every scale)
SLACK = 2.0**-40
#: how far a float32 cosine of two unit vectors may lie from the float64 one: the casts of both vectors'
#: components, three products and two sums are eight roundings, each by at most 2^-24 times a sum of |products|
#: of at most 1 (Cauchy–Schwarz, for unit vectors): 2^-21 in all.  The cones' tests through a point, made in
#: float32, compare with eight times that much slack; unit vectors make it hold at every scale
SLACK32 = 2.0**-18
#: how far a shadow ray ``P + t·d`` may stray from its true segment, relative to the segment's length: ``d``
#: is a computed unit vector, a few 2^-53 off in direction, which moves the ray's end by as much of its length
STRAY = 2.0**-46
#: how far outside a triangle an exact test (:func:`tracer.scene.shapes.triangle_t`) may accept a hit, relative to
#: the triangle's size: its barycentric allowance (``UV_TOL``, 2^-40) and the rounding of the barycentrics,
#: both relative to the triangle's own edges, so at every scale.  A triangle's bound (:func:`tracer.proofs.bounds.
#: bounds_of`) and the cones' edge planes are grown by this much
GROWTH = 2.0**-20
#: how far float32 rounding may move a ray or a corner, in units of the BVH's half-size (:mod:`tracer.exact.embree`:
#: Embree meets triangles in float32, in the BVH's normalised units)
LINE_ERROR = 2.0**-19
#: the least sine of the angle at which a ray may meet a plain triangle (:mod:`tracer.proofs.sightlines`)
MIN_SINE = 2.0**-4
#: how far (relative to the BVH's half-size) a plain triangle's float32 crossing may lie from its float64 hit:
#: a displacement of :data:`LINE_ERROR` across the plane moves the crossing by that over the sine
CROSSING_SLACK = LINE_ERROR / MIN_SINE
#: a plain triangle keeps at least this far (relative to the BVH's half-size) from every known point
NEAR = 4.0 * CROSSING_SLACK
