"""The one place that knows the order of the stages: a chunk of pixels, its ray tree traced depth by depth.

For each chunk of pixels, per depth: intersect → misses take the background →
direct light (ambient, then one shadow batch per light or area-light sample)
→ spawn mirror and refracted rays.  The ray tree is traced depth-first in
bounded slices, and every contribution is a fixed-point integer on the chunk's
film (:mod:`tracer.film`), so neither the slices, the chunks nor the threads
that run them (:mod:`tracer.render`) change a byte.
"""

from __future__ import annotations

import threading

import numpy as np

from schemas import Scene

from .budget import Calls, Growth
from .chunks import CHUNK_RAYS, Pixels, pixel_numbers
from .exact.best import NO_HIT
from .exact.intersect import PLANE, SPHERE, TRIANGLE, Intersector
from .exact.visible import visible_size
from .film import Film
from .proofs.planner import plan_proofs, scene_sightlines
from .scene.camera import CameraRays, up_perpendicular
from .scene.lights import LIGHT_TYPES, light_groups
from .scene.rays import Among, Rays, Work
from .scene.surfaces import unit
from .scene.variants import Options, scene_size
from .scene.vec import scaled
from .scene.world import World, build_world
from .shade.direct import DirectLight
from .shade.passes import UNOBSERVED, PassObserver, Tally
from .shade.shading import resolve_material, shading_normal
from .shade.shadows import Meter, ShadowRays
from .shade.spawn import Spawner


class Stages:
    """A scene's stages, built in order (world, camera, intersector, spawner, proofs, shadow rays, direct light),
    and :meth:`film`, a chunk traced through them.  Every stage polls and counts into ``calls``: the budget of
    the render call its thread works for (:class:`tracer.budget.Calls`)."""

    def __init__(self, scene: Scene, options: Options, calls: Calls):
        self.scene, self.options, self._calls = scene, options, calls
        self.max_depth = max(0, scene.image.max_depth + options.depth_offset)
        #: the index in ``scene.lights`` of each emitter
        self.emitter_light = np.repeat(
            np.arange(len(scene.lights)), [LIGHT_TYPES[type(light)].count(light) for light in scene.lights]
        )
        with np.errstate(all="ignore"):  # hostile magnitudes (1e300) overflow to inf here; the tracer copes
            self.world: World = build_world(scene, options)
            self.camera = CameraRays(
                scene.camera, scene.image, self.world.origin, options.half_pixel, options.vertical_fov
            )
            if options.aspect_inverted:  # a variant's window h·H/W across (the format's h·W/H upside down)
                self.camera.scale_x = scene.image.height / scene.image.width
            if options.left_handed:  # a variant's r = up × f (u kept): the image mirrored left to right
                self.camera.right = -self.camera.right
            if not options.up_made and not up_perpendicular(scene.camera):  # a variant's u = unit(up), as given
                self.camera.up = unit(np.asarray(scene.camera.up, dtype=np.float64))
            self.intersector = Intersector(self.world, scene_sightlines(scene, self.world.origin, self.camera, options))
            #: where shadow and secondary rays are born: off the surface in a variant of a student's offset
            self.spawner = Spawner(self.world, options, options.spawn(self.visible_size))
            #: which proofs spare which rays (:mod:`tracer.proofs.planner`)
            self.plan = plan_proofs(self.world, options, self.spawner.offset)
            #: the shadow rays every light's terms ask, and the direct-light stage
            self.shadows = ShadowRays(
                self.world, options, self.intersector, self.plan, self.spawner, Meter(calls.stop, calls.count)
            )
            self.shading = DirectLight(light_groups(scene, self.world.origin), self.shadows)
        #: the index in ``scene.objects`` of each surface, by kind (the passes' ``object``)
        self._owners = {
            SPHERE: self.world.spheres.object,
            PLANE: self.world.planes.object,
            TRIANGLE: self.world.triangles.object,
        }
        self.intersector.check = calls.stop
        self.intersector.tested = calls.tested

    def visible_size(self) -> float:
        """The size of what the camera sees (:func:`tracer.exact.visible.visible_size`): what an offset is measured
        against."""
        return visible_size(self.scene, self.world, self.intersector, scene_size(self.scene))

    def film(
        self,
        start: int,
        stop: int,
        tally: Tally | None = None,
        pixels: Pixels | None = None,
        depth: int | None = None,
        slice_rays: int = CHUNK_RAYS,
    ) -> Film:
        """The film of pixels ``start..stop``, or of the pixels ``pixels`` (then ``stop − start`` of them): their
        sub-samples' sums and which are open.

        The ray tree is traced depth-first in slices of at most ``slice_rays``
        rays, so memory depends on the slice size and the depth, never on
        2^depth.  Every contribution goes to the chunk's :class:`tracer.film.Film`
        as a fixed-point integer, so the sums, and the bytes of the image, do not
        depend on the order in which slices, chunks or threads deliver them.  With
        a ``tally``, the passes it asks for are added up too (each ray then carries
        the branch of the ray tree it belongs to).  With ``depth``, the tree stops
        there (0: the camera rays' hits alone), if not before.  The slice size is
        the call's own: one renderer may trace chunks of several renders at once.
        """
        s = self.scene.image.samples**2
        deepest = self.max_depth if depth is None else min(depth, self.max_depth)
        with np.errstate(all="ignore"):
            origins, dirs = (
                self.camera.rays(start, stop) if pixels is None else self.camera.rays_of(pixel_numbers(pixels))
            )
            n = len(origins)
            self._calls.count("primary", n)
            film = Film(stop - start, s, slice_rays, not self.options.clamp_colour)
            camera = Work(
                self.intersector.rays(origins, dirs),
                np.arange(n),
                np.ones(n),
                0,
                None if tally is None else np.zeros(n, dtype=np.int8),
            )
            stack: list[Work] = [camera]
            holder = threading.get_ident()  # (one chunk at a time per thread)
            growth = Growth(n, deepest)
            while stack:
                work = stack.pop()
                if len(work) > slice_rays:  # split; the first slice goes on top, so it is traced first
                    stack += reversed(work.slices(slice_rays))
                    continue
                self._calls.hold(holder, len(work) + sum(len(w) for w in stack))
                self._calls.stop()
                growth.add(work.depth, len(work), 0)
                children = self._trace(work, film, tally, deepest)
                if children is None:
                    continue
                self._calls.count("secondary", len(children))
                growth.add(work.depth, 0, len(children))
                self._calls.foresee(holder, growth.ahead())
                if len(children):
                    stack.append(children)
            self._calls.hold(holder, 0)
            self._calls.foresee(holder, 0.0)
            return film

    def _trace(self, work: Work, film: Film, tally: Tally | None, deepest: int) -> Work | None:
        """One slice of one depth, stage by stage: intersect → misses take the background → direct light → the
        next depth's mirror and refracted rays, returned (None: no hit, or the deepest depth)."""
        background = self.options.background(np.asarray(self.scene.image.background, dtype=np.float64), work.depth)
        best = self.intersector.nearest(
            work.rays, self._camera_among(work.rays) if work.depth == 0 else self._mirror_among(work.rays)
        )
        missed = best.key == NO_HIT
        if best.open is not None:  # a tie the format leaves open (tracer.exact.ties): its sample's pixel is open
            film.opened(work.sample[best.open])
        once = work.depth == 0  # a primary ray is its sample's only ray of its depth; later, two may share
        film.add(work.sample[missed], scaled(background, work.weight[missed]), once)
        (UNOBSERVED if tally is None else PassObserver(tally, work)).missed(missed, background)
        rows = np.flatnonzero(~missed)
        if len(rows) == 0:
            return None
        hit, done = self.intersector.describe(work.rays, best, rows), work.take(rows)  # (the hits alone)
        dd = done.rays.dirs
        mat = resolve_material(self.world, hit, self.options.checker_floor)
        normal = shading_normal(self.world, hit, dd, self.options.flip_normals, self.options.normals_unit)
        observer = UNOBSERVED if tally is None else PassObserver(tally, done)
        if work.depth == 0:
            observer.first_hits(hit, self._owners, normal)
        colour = self.shading.shade(hit, mat, normal, dd, observer)
        colour = self.options.blended(colour, self.world.materials.reflectance[mat])  # (a variant's)
        self._calls.lit(len(rows) * len(self.emitter_light))
        film.add(done.sample, scaled(colour, done.weight), once)
        if work.depth >= deepest:
            return None
        return self.spawner.bounce(hit, mat, normal, done)

    def _mirror_among(self, rays: Rays) -> Among | None:
        """The surfaces each mirror or refracted ray may meet (:func:`tracer.proofs.cones.on_lines`), when the scene has
        few enough and walks them (with no walk, every surface is tested against every ray already)."""
        return self.plan.mirror_pairs(rays, self.intersector.walker is not None)

    def _camera_among(self, rays: Rays) -> Among | None:
        """The surfaces each camera ray may meet (:mod:`tracer.proofs.cones`), when the scene has few enough: from the
        eye (every perspective ray starts there, exactly), or along the view (orthographic)."""
        return self.plan.camera_pairs(self.camera, rays)
