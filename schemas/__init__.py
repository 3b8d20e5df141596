"""The scene format: models, validation with located errors, JSON Schema."""

from __future__ import annotations

import os
from typing import Any

# phongray uses no pydantic plugins; not looking for any saves scanning every installed package at start-up
os.environ.setdefault("PYDANTIC_DISABLE_PLUGINS", "__all__")

from pydantic import ValidationError  # noqa: E402

from .checks import check_scene, parallel
from .errors import SceneError, format_problem, parse_json, problems_from_validation
from .scene import (AmbientLight, AreaLight, Camera, DirectionalLight, Image, Material, Mesh, Plane,
                    PointLight, Scene, Sphere, SpotLight, Triangle)

__all__ = [
    "AmbientLight", "AreaLight", "Camera", "DirectionalLight", "Image", "Material", "Mesh", "Plane",
    "PointLight", "Scene", "SceneError", "Sphere", "SpotLight", "Triangle", "format_problem",
    "json_schema", "load_scene", "parallel", "validate_scene",
]


def validate_scene(data: Any) -> Scene:
    """Validate a parsed JSON document; raise :class:`SceneError` listing every problem."""
    if not isinstance(data, dict):
        raise SceneError([("", "a scene must be a JSON object")])
    try:
        scene = Scene.model_validate(data)
    except ValidationError as exc:
        raise SceneError(problems_from_validation(exc)) from None
    except RecursionError:
        raise SceneError([("", "the document is nested too deeply")]) from None
    problems = check_scene(scene)
    if problems:
        raise SceneError(problems)
    return scene


def load_scene(text: str | bytes) -> Scene:
    """Parse and validate the text of a scene file."""
    return validate_scene(parse_json(text))


def json_schema() -> dict[str, Any]:
    schema = Scene.model_json_schema()
    schema["title"] = "phongray scene, version 1"
    return schema
