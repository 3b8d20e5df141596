"""Which proof spares which rays: the one place that decides, from the scene, the light and the render's options.

Each proof is a function that states its guarantee in its docstring and holds under stated conditions; this
module checks those conditions once per render (:func:`plan_proofs`) and hands each stage the proofs that
apply to its rays (:class:`ProofPlan`):

* camera rays, and a point, spot or directional light's shadow rays, pass through one point or run along one
  direction: :func:`tracer.proofs.cones.through_point` and :func:`tracer.proofs.cones.along_direction` pair each with
  the surfaces it may meet.  They need few surfaces (at most :data:`CONE_MAX` spheres and triangles), and, for
  shadow rays, rays that start at the exact hit point and end at the light (no variant's acne or offset);
* a mirror's or a glass's rays, each of its own direction: :func:`tracer.proofs.cones.on_lines`, in the same scenes,
  when the rays are walked (with no walk every surface is tested against every ray already);
* tiles of points a point, spot or directional light reaches whole (:func:`tracer.proofs.tiles.lit_tiles`): the
  format's shadow rays (cast at all, from the exact point, no offset), where at least :data:`PROVEN_LIT` points
  are lit, and only points that face the light (not the variant that lights points from behind), since a
  point's own surface is exempt from blocking only the rays of points facing the light;
* an area light's points seen, hidden or mixed (:func:`tracer.proofs.culling.classify`), its penumbra
  (:class:`tracer.proofs.penumbra.Penumbra`) and the points facing away from it
  (:func:`tracer.proofs.culling.faces_away`):
  the format's shadow rays; the points facing away, and the penumbra's own-surface rule, only where just the
  points facing a sample are lit;
* mesh faces Embree may meet as they are (:func:`tracer.proofs.sightlines.plain_triangles`): from the lines every
  ray of the scene runs on (:func:`scene_sightlines`), none with a mirror or glass, nor for a variant's shadow rays
  that run on past their light.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from schemas import Scene

from ..scene.camera import CameraRays
from ..scene.lights import LIGHT_TYPES, Emitter
from ..scene.rays import Among, Rays
from ..scene.surfaces import Triangles
from ..scene.variants import REFERENCE, Options, Spawn
from ..scene.world import World
from .bounds import Bounds, bounds_of
from .cones import along_direction, on_lines, through_point
from .sightlines import Sightlines

#: a scene with at most this many spheres and triangles tests its camera rays and its point and directional
#: lights' shadow rays against the surfaces their bounds allow (:mod:`tracer.proofs.cones`), with no walk
CONE_MAX = 32
#: the fewest lit points of a point or directional light for which tiles of them are proven lit whole
#: (:func:`tracer.proofs.tiles.lit_tiles`): the proof's 60-odd NumPy calls cost what the shadow rays of a few thousand
#: points do (measured: three spots lighting 4k points each lost 1 ms a light; 32k points gain several)
PROVEN_LIT = 1 << 13


@dataclass(frozen=True)
class ProofPlan:
    """The proofs that apply to a render's rays, decided once (:func:`plan_proofs`)."""

    triangles: Triangles
    #: the surfaces as bounds for rays through one point, along one direction or of their own
    #: (:mod:`tracer.proofs.cones`); None where the scene has too many surfaces
    cone_bounds: Bounds | None
    #: the surfaces as bounds for which points a light reaches (:mod:`tracer.proofs.tiles`,
    #: :mod:`tracer.proofs.culling`,
    #: :mod:`tracer.proofs.penumbra`); None where shadow rays are not the format's, where points not facing a light
    #: may be lit (their own surface may block them), where a blocked ray leaves the specular term (a variant's:
    #: a point proven hidden is shaded still), or the scene has too many surfaces
    light_bounds: Bounds | None
    #: shadow rays start at the exact hit point, leaving its surface by identity, and end at the light
    exact_shadows: bool
    #: only points that face a light (or a sample) are lit by it: not the variant lighting points from behind
    facing: bool

    def camera_pairs(self, camera: CameraRays, rays: Rays) -> Among | None:
        """The surfaces each camera ray may meet: from the eye (every perspective ray starts there, exactly), or
        along the view (orthographic); None where no proof applies."""
        if self.cone_bounds is None:
            return None
        if camera.orthographic:
            return along_direction(self.cone_bounds, self.triangles, rays.origins, camera.forward)
        return through_point(self.cone_bounds, self.triangles, camera.eye, rays.dirs, True)

    def mirror_pairs(self, rays: Rays, walked: bool) -> Among | None:
        """The surfaces each mirror or refracted ray may meet, when they are ``walked``; None otherwise."""
        if self.cone_bounds is None or not walked:
            return None
        return on_lines(self.cone_bounds, rays.origins, rays.dirs)

    def shadow_pairs(self, em: Emitter, rays: Rays, reach: np.ndarray) -> Among | None:
        """The surfaces each shadow ray of ``rays`` (from hit points, lengths ``reach``) to a point, spot or
        directional light ``em`` may meet; None where no proof applies (too many surfaces, a variant's rays that
        do not run from the exact point to the light)."""
        if self.cone_bounds is None or not self.exact_shadows:
            return None
        if em.kind == "directional":
            return along_direction(self.cone_bounds, self.triangles, rays.origins, -em.direction)
        longest = float(np.max(reach, initial=0.0))
        return through_point(self.cone_bounds, self.triangles, em.position, rays.dirs, False, longest)

    def lit_tile_bounds(self, lit: int) -> Bounds | None:
        """The bounds to prove tiles of ``lit`` lit points reached whole by a point or directional light
        (:func:`tracer.proofs.tiles.lit_tiles`), or None where the proof does not apply or is not worth its cost."""
        if self.light_bounds is None or not self.facing or lit < PROVEN_LIT:
            return None
        return self.light_bounds


def plan_proofs(world: World, options: Options, spawn: Spawn | None) -> ProofPlan:
    """Which proofs apply to the rays of a render of ``world`` with ``options`` (and a student's ray offset
    ``spawn``, if any)."""
    spheres_and_triangles = len(world.spheres.radius) + len(world.triangles.v0)
    cone_bounds = bounds_of(world) if spheres_and_triangles <= CONE_MAX else None
    exact = not options.acne and spawn is None and options.transparent_shadows and options.shadow_to_light
    # (else: a variant's rays)
    facing = not options.specular_behind
    # the proofs of which points a light reaches (tiles, classify, penumbra) exempt a point's own surface, which
    # holds only for rays of points facing the light: with the variant lighting points from behind, its sphere
    # may block them
    # (and, for the variant whose shadows take only the diffuse term, a point proven hidden still has its specular)
    light_bounds = bounds_of(world) if options.shadows and exact and facing and options.specular_shadowed else None
    return ProofPlan(world.triangles, cone_bounds, light_bounds, exact, facing)


def scene_sightlines(
    scene: Scene, origin: np.ndarray, camera: CameraRays, options: Options = REFERENCE
) -> Sightlines | None:
    """The lines of a validated scene's rays (local coordinates about ``origin``), or None when a mirror or
    glass may send rays anywhere, or a variant's shadow rays run on past their light (the faces the walk
    spares a shadow ray are those it does not meet on its way to the light:
    :func:`tracer.proofs.sightlines.plain_triangles`), or a variant's orthographic camera uses ``up`` as given
    (its rays then start off the plane through the eye across the view, which the starts below assume)."""
    if not options.shadow_to_light or (camera.orthographic and not options.up_made):
        return None
    used = {obj.material for obj in scene.objects}
    used |= {checker.material for name in used if (checker := scene.materials[name].checker) is not None}
    if scene.image.max_depth > 0 and any(
        scene.materials[name].reflectance > 0 or scene.materials[name].transmittance > 0 for name in used
    ):
        return None
    lines = Sightlines()
    if camera.orthographic:
        lines.directions.append(camera.forward)
        lines.starts.append((camera.eye, camera.forward))
    else:
        lines.hulls.append(camera.eye[None])
    for light in scene.lights:
        kind = LIGHT_TYPES[type(light)]
        if kind.hull is not None:
            lines.hulls.append(kind.hull(light, origin))
        if kind.direction is not None:
            lines.directions.append(kind.direction(light))
    if not all(np.all(np.isfinite(h)) for h in lines.hulls) or not all(
        np.all(np.isfinite(d)) for d in lines.directions
    ):
        return None
    return lines
