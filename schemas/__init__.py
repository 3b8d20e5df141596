"""The scene format: models, validation with located errors, JSON Schema."""

from __future__ import annotations

import os
from typing import Any

# phongray uses no pydantic plugins; not looking for any saves scanning every installed package at start-up
os.environ.setdefault("PYDANTIC_DISABLE_PLUGINS", "__all__")

from .checks import parallel  # noqa: E402
from .errors import SceneError, format_problem, parse_json  # noqa: E402
from .scene import (  # noqa: E402
    AmbientLight,
    AreaLight,
    Camera,
    DirectionalLight,
    Image,
    Material,
    Mesh,
    Plane,
    PointLight,
    Scene,
    Sphere,
    SpotLight,
    Triangle,
)
from .validation import validate_scene  # noqa: E402

__all__ = [
    "AmbientLight",
    "AreaLight",
    "Camera",
    "DirectionalLight",
    "Image",
    "Material",
    "Mesh",
    "Plane",
    "PointLight",
    "Scene",
    "SceneError",
    "Sphere",
    "SpotLight",
    "Triangle",
    "format_problem",
    "json_schema",
    "load_scene",
    "parallel",
    "validate_scene",
]


def load_scene(text: str | bytes) -> Scene:
    """Parse and validate the text of a scene file."""
    return validate_scene(parse_json(text))


#: the JSON Schema dialect of :func:`json_schema` (the one pydantic writes: tuples as prefixItems)
DIALECT = "https://json-schema.org/draft/2020-12/schema"


def json_schema() -> dict[str, Any]:
    """The JSON Schema (Draft 2020-12) of a scene: structure, types, ranges, shorthands; the rules between values
    (material names, face indices, ...) are beyond what a schema states."""
    schema = {"$schema": DIALECT, **Scene.model_json_schema()}
    schema["title"] = "phongray scene, version 1"
    return schema
