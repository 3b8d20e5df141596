"""The lighting kernel: one emitter's Phong terms at hit points, the same code for every type of light.

A point light, a spot and a directional light are one emitter each, an area
light a grid of them (:mod:`tracer.scene.lights`); :mod:`tracer.shade.direct` runs the
kernel once per emitter of the first three, :mod:`tracer.shade.area` once per sample
of the last.  Per emitter, in buffers of the kernel's own (every array computed
a column at a time):

* :meth:`Kernel.reach`: L, d and the intensity factor (:func:`tracer.scene.lights.illuminate_into`),
  N·L, and the weight ``w``: the factor where the emitter lights the point
  (N·L > 0, or everywhere for the variant that lights a point from behind), 0
  elsewhere;
* the caller's shadow rays set ``w`` to 0 where the light is blocked (:meth:`Reach.shadowed`);
* :meth:`Kernel.terms`: ``wd = w·(N·L)`` and ``ws = w·max(0, R·V)^n``, with
  ``R·V = 2(N·L)(N·V) + L·D`` (V = −D), or N·H for Blinn–Phong (a variant), or
  −R·V for a reflected vector of the wrong sign (another); for the variant whose
  shadow test skips the specular term, ``ws`` takes ``w`` as it was before the
  shadow rays.

``max(0, R·V)^n`` is 0 where R·V ≤ 0, also for n = 0: the power is taken of 1
there and multiplied by 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene.lights import Emitter, illuminate_into
from ..scene.rays import Hits
from ..scene.surfaces import unit
from ..scene.variants import Options
from ..scene.vec import columns, dot, dot_into, rows_of
from ..scene.world import World
from .shading import light_in_plane


@dataclass
class Points:
    """The hit points being shaded, with what every light's terms read: the facing shading ``normal``, the
    rays' ``dirs``, N·V and the points' world magnitudes (where their shadow rays start), each per point."""

    hit: Hits
    normal: np.ndarray  # (N, 3), columns contiguous
    dirs: np.ndarray  # (N, 3)
    nv: np.ndarray  # (N,) N·V with V = −D
    mag: np.ndarray  # (N,)
    shininess: np.ndarray  # (N,)

    def take(self, rows: np.ndarray) -> Points:
        return Points(
            self.hit.take(rows),
            rows_of(self.normal, rows),
            rows_of(self.dirs, rows),
            self.nv[rows],
            self.mag[rows],
            self.shininess[rows],
        )


@dataclass
class Reach:
    """Where one emitter reaches the kernel's points, before shadows: views of the kernel's buffers, valid until
    its next :meth:`Kernel.reach`."""

    to_light: np.ndarray  # (N, 3) L, unit
    dist: np.ndarray  # (N,) d, ∞ for a directional light
    nl: np.ndarray  # (N,) N·L (0 where a flat surface's plane holds the light)
    facing: np.ndarray  # (N,) bool: N·L > 0
    lit: np.ndarray  # (N,) bool: where a shadow ray decides whether the emitter lights the point
    weight: np.ndarray  # (N,) the factor where lit, 0 elsewhere: :meth:`shadowed` zeroes it where a ray is blocked
    #: the weight before shadows, kept for the specular term of a variant whose shadows take only the diffuse
    unshadowed: np.ndarray | None = None

    def kept(self) -> Reach:
        """A copy of what :meth:`Kernel.terms` and the observer read (L, N·L, the facing, the weight and the weight
        before shadows), for an emitter decided after the kernel has gone on to others; ``dist`` and ``lit``, read
        only before, stay views."""
        to_light, nl, facing, weight = (a.copy(order="K") for a in (self.to_light, self.nl, self.facing, self.weight))
        before = None if self.unshadowed is None else self.unshadowed.copy()
        return Reach(to_light, self.dist, nl, facing, self.lit, weight, before)

    def shadowed(self, rows: np.ndarray, specular: bool = True) -> None:
        """Zero the weight at ``rows`` (indices or a mask), where the emitter's shadow rays are blocked; without
        ``specular`` (a variant's student, whose shadow test skips the specular term), the weight before is kept
        for that term."""
        if not specular and self.unshadowed is None:
            self.unshadowed = self.weight.copy()
        self.weight[rows] = 0.0


class Kernel:
    """The Phong terms of one emitter after another at the points ``at``, computed into buffers of its own."""

    def __init__(self, world: World, options: Options, at: Points):
        m = len(at.nv)
        self.world, self.options, self.at = world, options, at
        self.to_light = columns(m)
        self.dist, self.tmp, self.nl, self.rv, self.spec, self.weight, self.wd, self.ws = (
            np.empty(m) for _ in range(8)
        )
        self.facing, self.pos = np.empty(m, dtype=bool), np.empty(m, dtype=bool)
        self.normal, self.dirs = np.asfortranarray(at.normal), np.asfortranarray(at.dirs)  # (a column at a time)
        self.nv2 = 2.0 * at.nv  # (2·(N·L)·(N·V) as (2·N·V)·(N·L): doubling is exact)

    def reach(self, em: Emitter, holds: bool) -> Reach:
        """Where ``em`` lights the points, before shadows; ``holds``: some flat surface's plane may hold it
        (:func:`tracer.shade.shading.light_in_plane`, which then sets N·L to 0 on that surface)."""
        factor = illuminate_into(em, self.at.hit.point, self.to_light, self.dist, self.tmp)
        nl = dot_into(self.nl, self.normal, self.to_light, self.tmp)
        if holds:
            nl = light_in_plane(self.world, self.at.hit, em, nl, self.dist)
        np.greater(nl, 0.0, out=self.facing)
        scalar = isinstance(factor, float)
        if self.options.specular_behind:
            lit = np.asarray(factor > 0) & np.ones(len(nl), dtype=bool)
        else:
            lit = self.facing if scalar and factor > 0 else self.facing & (factor > 0)
        if scalar and np.isfinite(factor):
            np.multiply(lit, factor, out=self.weight)  # (factor or 0: np.where(lit, factor, 0.0))
        else:
            np.copyto(self.weight, np.where(lit, factor, 0.0))
        return Reach(self.to_light, self.dist, nl, self.facing, lit, self.weight)

    def terms(self, reach: Reach) -> tuple[np.ndarray, np.ndarray]:
        """``wd = w·(N·L)`` and ``ws = w·max(0, R·V)^n`` per point (N·L at least 0 for the variant that lights
        a point from behind; ``w`` before shadows in ``ws`` for the variant whose shadows skip it), into the
        kernel's buffers: valid until its next call. Each (N,)."""
        nl, rv, tmp, pos, spec = reach.nl, self.rv, self.tmp, self.pos, self.spec
        if self.options.blinn:  # N·H with H = unit(L + V)
            np.copyto(rv, dot(self.normal, unit(reach.to_light - self.dirs)))
        else:  # R·V = 2·(N·L)·(N·V) + L·D
            dot_into(rv, reach.to_light, self.dirs, tmp)
            np.multiply(nl, self.nv2, out=tmp)
            rv += tmp
            if self.options.reflect_flipped:  # a variant's R = L − 2(N·L)N: −R·V
                np.negative(rv, out=rv)
        np.greater(rv, 0.0, out=pos)
        np.copyto(rv, 1.0, where=~pos)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            np.power(rv, self.at.shininess, out=spec)
        spec *= pos  # (where R·V ≤ 0 the power of 1, times 0)
        np.multiply(reach.weight, np.maximum(nl, 0.0) if self.options.specular_behind else nl, out=self.wd)
        np.multiply(reach.weight if reach.unshadowed is None else reach.unshadowed, spec, out=self.ws)
        return self.wd, self.ws
