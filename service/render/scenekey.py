"""The canonical key of a scene: what the render cache and the diagnosis cache file a scene under.

Kept apart from :mod:`service.work.jobs` so that what needs only the key (a diagnosis in the command line, a class
worker) does not import the service's settings.
"""

from __future__ import annotations

import hashlib
import json
from typing import Any

import numpy as np

from schemas import Mesh, Scene

#: part of every key: a renderer whose images change gets a new one
RENDERER_VERSION = "phongray-1"

#: rows of a mesh array hashed at once (each hashing step is a short call)
KEY_ROWS = 65_536


def scene_key(scene: Scene) -> str:
    """sha256 of the canonical scene: its JSON (keys sorted) piece by piece, each mesh array as float64 or
    int64 bytes, so a large mesh is hashed in short steps."""
    digest = hashlib.sha256(RENDERER_VERSION.encode())

    def put(value: Any) -> None:
        text = json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=False)
        digest.update(b"%d:" % len(text) + text.encode("utf-8", "surrogatepass"))

    whole = scene.model_dump(mode="json", exclude={"objects"})
    whole["lights"] = [_unnamed(light) for light in whole["lights"]]
    put(whole)
    put(len(scene.objects))
    for obj in scene.objects:
        if not isinstance(obj, Mesh):
            put(_unnamed(obj.model_dump(mode="json")))
            continue
        put(_unnamed(obj.model_dump(mode="json", exclude={"vertices", "faces", "normals"})))
        for name, dtype in (("vertices", np.float64), ("faces", np.int64), ("normals", np.float64)):
            rows = getattr(obj, name)
            put([name, None if rows is None else len(rows)])
            for start in range(0, len(rows or ()), KEY_ROWS):
                digest.update(np.asarray(rows[start : start + KEY_ROWS], dtype=dtype).tobytes())
    return digest.hexdigest()


def _unnamed(fields: dict[str, Any]) -> dict[str, Any]:
    """An object's or a light's fields without a ``name`` that is not given: the key of a scene without names is
    the key it had before names were part of the format; a name given is part of the key (messages use it)."""
    return {k: v for k, v in fields.items() if not (k == "name" and v is None)}
