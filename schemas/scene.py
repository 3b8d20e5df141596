"""Pydantic models of the scene format, version 1 (docs/scene-format.md).

Structure, types, ranges and defaults live here.  Rules that relate one part of
a scene to another (material names, face indices, collinear vertices, ...) are
checked afterwards by :mod:`schemas.checks`, which can name the exact place.
"""

from __future__ import annotations

from itertools import chain
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, StrictFloat, StrictInt

Number = StrictFloat
NonNegative = Annotated[StrictFloat, Field(ge=0)]
Vec3 = tuple[Number, Number, Number]


def _expand_grey(value: Any) -> Any:
    """A single number ``k`` where a colour is expected means ``[k, k, k]``."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return [value, value, value]
    return value


#: a colour: an RGB triple, or one number k for [k, k, k] (both in the JSON Schema too)
Colour = Annotated[
    tuple[NonNegative, NonNegative, NonNegative],
    BeforeValidator(_expand_grey, json_schema_input_type=NonNegative | tuple[NonNegative, NonNegative, NonNegative]),
]
Attenuation = tuple[NonNegative, NonNegative, NonNegative]
#: the most characters of an object's or a light's ``name`` (a name is for messages: a word or a few)
NAME_MAX = 64
#: an object's or a light's name (phongray's extension of the format): 1 to NAME_MAX characters, none of them a
#: control character (a name is printed in messages to students)
Name = Annotated[str, Field(min_length=1, max_length=NAME_MAX, pattern=r"^[^\x00-\x1f\x7f-\x9f]+$", strict=True)]


class Strict(BaseModel):
    """Base of every model: unknown keys are errors, numbers are finite."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)


class Camera(Strict):
    type: Literal["perspective", "orthographic"] = "perspective"
    position: Vec3
    look_at: Vec3
    up: Vec3 = (0.0, 1.0, 0.0)
    fov: Annotated[StrictFloat, Field(gt=0, lt=180)] = 60.0
    height: Annotated[StrictFloat, Field(gt=0)] = 2.0


class Image(Strict):
    width: Annotated[StrictInt, Field(ge=1)]
    height: Annotated[StrictInt, Field(ge=1)]
    samples: Annotated[StrictInt, Field(ge=1)] = 1
    max_depth: Annotated[StrictInt, Field(ge=0)] = 4
    background: Colour = (0.0, 0.0, 0.0)


class Checker(Strict):
    size: Annotated[StrictFloat, Field(gt=0)]
    material: str


class Material(Strict):
    ambient: Colour = (0.3, 0.3, 0.3)
    diffuse: Colour = (0.5, 0.5, 0.5)
    specular: Colour = (0.8, 0.8, 0.8)
    shininess: NonNegative = 100.0
    reflectance: Annotated[StrictFloat, Field(ge=0, le=1)] = 0.0
    transmittance: Annotated[StrictFloat, Field(ge=0, le=1)] = 0.0
    ior: Annotated[StrictFloat, Field(gt=0)] = 1.5
    checker: Checker | None = None


class Sphere(Strict):
    type: Literal["sphere"]
    material: str
    name: Name | None = None
    center: Vec3
    radius: Annotated[StrictFloat, Field(gt=0)]


class Plane(Strict):
    type: Literal["plane"]
    material: str
    name: Name | None = None
    point: Vec3
    normal: Vec3


class Triangle(Strict):
    type: Literal["triangle"]
    material: str
    name: Name | None = None
    vertices: tuple[Vec3, Vec3, Vec3]


#: a vertex index; beyond 2³¹ it could not be in range of any mesh that fits in memory
FaceIndex = Annotated[StrictInt, Field(ge=0, lt=2**31)]


class Mesh(Strict):
    type: Literal["mesh"]
    material: str
    name: Name | None = None
    vertices: list[Vec3]
    faces: list[tuple[FaceIndex, FaceIndex, FaceIndex]]
    normals: list[Vec3] | None = None

    def rows(self, name: str) -> np.ndarray:
        """``vertices``, ``faces`` or ``normals`` (not None) as an ``(N, 3)`` array, float64 or int64 for faces:
        read once, then shared (read-only) by the checks and the tracer."""
        rows = getattr(self, name)
        read = self.__dict__.get("_read")
        if read is None:  # kept beside the fields (a frozen model's fields cannot change)
            read = _Read()
            object.__setattr__(self, "_read", read)
        kept = read.arrays.get(name)
        if kept is None or kept[0] is not rows:  # (a copy with other lists reads its own)
            out = np.fromiter(
                chain.from_iterable(rows), dtype=np.int64 if name == "faces" else np.float64, count=3 * len(rows)
            ).reshape(-1, 3)
            out.flags.writeable = False
            kept = read.arrays[name] = (rows, out)
        return kept[1]


class _Read:
    """The arrays :meth:`Mesh.rows` has read, each with the list it came from.  Not part of the mesh's value:
    any two compare equal, so two meshes are equal when their fields are, read or not."""

    __slots__ = ("arrays",)
    __hash__ = None  # type: ignore[assignment]

    def __init__(self) -> None:
        self.arrays: dict[str, tuple[list, np.ndarray]] = {}

    def __eq__(self, other: object) -> bool:
        return isinstance(other, _Read)


Object = Annotated[Sphere | Plane | Triangle | Mesh, Field(discriminator="type")]


class AmbientLight(Strict):
    type: Literal["ambient"]
    color: Colour
    name: Name | None = None


class DirectionalLight(Strict):
    type: Literal["directional"]
    color: Colour
    name: Name | None = None
    direction: Vec3


class PointLight(Strict):
    type: Literal["point"]
    color: Colour
    name: Name | None = None
    position: Vec3
    attenuation: Attenuation = (1.0, 0.0, 0.0)


class SpotLight(Strict):
    type: Literal["spot"]
    color: Colour
    name: Name | None = None
    position: Vec3
    direction: Vec3
    attenuation: Attenuation = (1.0, 0.0, 0.0)
    cutoff: Annotated[StrictFloat, Field(gt=0, le=90)] = 45.0
    inner_cutoff: Annotated[StrictFloat, Field(gt=0, le=90)] | None = None
    exponent: NonNegative = 1.0

    @property
    def inner(self) -> float:
        """The inner cone angle; it defaults to ``cutoff``."""
        return self.cutoff if self.inner_cutoff is None else self.inner_cutoff


class AreaLight(Strict):
    type: Literal["area"]
    color: Colour
    name: Name | None = None
    corner: Vec3
    edge_u: Vec3
    edge_v: Vec3
    samples: tuple[Annotated[StrictInt, Field(ge=1)], Annotated[StrictInt, Field(ge=1)]] = (4, 4)
    attenuation: Attenuation = (1.0, 0.0, 0.0)


Light = Annotated[
    AmbientLight | DirectionalLight | PointLight | SpotLight | AreaLight,
    Field(discriminator="type"),
]


class Scene(Strict):
    version: Literal[1] = 1
    camera: Camera
    image: Image
    materials: dict[str, Material] = Field(default_factory=dict)
    objects: list[Object] = Field(default_factory=list)
    lights: list[Light] = Field(default_factory=list)
