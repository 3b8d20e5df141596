"""Validating a parsed document in bounded pieces.

A document under the body limit can still hold a million wrong values, and
pydantic reports every one of them in a single call.  So a scene is validated
in parts: its head (camera, image, ...) alone, then materials, objects and
lights a few hundred at a time, and the long arrays of meshes a slice at a
time by type checks of their own.  No single call works on more than a
bounded piece, the interpreter can switch threads between pieces, and the
problems are listed up to :data:`MAX_LISTED` and counted up to
:data:`MAX_COUNTED` (then validation stops).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from itertools import chain, islice
from typing import Any

import numpy as np
from pydantic import TypeAdapter, ValidationError

from .checks import check_scene, out_of_range, unknown_material
from .errors import SceneError, problems_from_validation
from .scene import Light, Material, Mesh, Object, Scene

#: problems listed in full; the rest are counted
MAX_LISTED = 50
#: validation stops after this many problems
MAX_COUNTED = 10_000
#: list items (or dict entries) validated by one pydantic call
PIECE = 256
#: rows of a mesh array checked by one pass
ROWS = 16_384
#: keys kept of a dict other than ``materials``: no part of a scene has this many fields
MAX_KEYS = 24
#: mesh arrays longer than this bypass pydantic (checked here, a slice at a time)
LONG = 64
#: a face index must be below this (schemas.scene.FaceIndex)
INDEX_END = 2**31

_SECTIONS: dict[str, tuple[type, TypeAdapter]] = {
    "materials": (dict, TypeAdapter(dict[str, Material])),
    "objects": (list, TypeAdapter(list[Object])),
    "lights": (list, TypeAdapter(list[Light])),
}
_MESH_ARRAYS = ("vertices", "normals", "faces")


class _Problems:
    """The first :data:`MAX_LISTED` problems, and how many more."""

    def __init__(self) -> None:
        self.listed: list[tuple[str, str]] = []
        self.seen: set[tuple[str, str]] = set()
        self.more = 0

    def add(self, problem: tuple[str, str]) -> None:
        if problem in self.seen:
            return
        if len(self.listed) < MAX_LISTED:
            self.seen.add(problem)
            self.listed.append(problem)
        else:
            self.more += 1

    def extend(self, problems: list[tuple[str, str]]) -> None:
        for problem in problems:
            self.add(problem)

    @property
    def full(self) -> bool:
        return len(self.listed) + self.more >= MAX_COUNTED

    def __bool__(self) -> bool:
        return bool(self.listed)

    def error(self) -> SceneError:
        more = []
        if self.more:
            more = [("", f"and {'at least ' if self.full else ''}{self.more} more problems")]
        return SceneError(self.listed + more)


def validate_scene(data: Any) -> Scene:
    """Validate a parsed JSON document; raise :class:`SceneError` with its problems."""
    if not isinstance(data, dict):
        raise SceneError([("", "a scene must be a JSON object")])
    problems = _Problems()
    arrays: dict[tuple[int, str], list | None] = {}  # long mesh arrays, checked apart (None: wrong)
    original = data
    try:
        data = _bounded(data, "", problems, arrays)
        parts = {
            name: _in_pieces(data[name], name, adapter, problems)
            for name, (kind, adapter) in _SECTIONS.items()
            if isinstance(data.get(name), kind)
        }
        try:
            head = Scene.model_validate({**data, **{name: type(part)() for name, part in parts.items()}})
        except ValidationError as exc:
            problems.extend(problems_from_validation(exc))
            problems.extend(list(references(original)))
            raise problems.error() from None
    except RecursionError:
        raise SceneError([("", "the document is nested too deeply")]) from None
    if problems:
        problems.extend(list(references(original)))
        raise problems.error()
    objects = parts.get("objects", [])
    wrong = {f"objects[{i}].{key}" for (i, key), rows in arrays.items() if rows is None}
    for (i, key), rows in arrays.items():
        if rows is not None and isinstance(objects[i], Mesh):
            objects[i] = objects[i].model_copy(update={key: rows})
    scene = head.model_copy(update=parts)
    for path, message in check_scene(scene):
        if not any(path == w or path.startswith(w + "[") for w in wrong):
            problems.add((path, message))
    if problems:
        raise problems.error()
    return scene


def references(data: dict) -> Iterator[tuple[str, str]]:
    """The checks between parts (material names, face indices) on the raw document, wherever the fields
    themselves parsed, so that a scene with other errors gets them in the same answer."""
    materials = data.get("materials")
    names = materials if isinstance(materials, dict) else {}
    for name, mat in names.items():
        checker = mat.get("checker") if isinstance(mat, dict) else None
        ref = checker.get("material") if isinstance(checker, dict) else None
        if isinstance(ref, str) and ref not in names:
            yield f"materials.{name}.checker.material", unknown_material(ref, names)
    objects = data.get("objects")
    for i, obj in enumerate(objects if isinstance(objects, list) else []):
        if not isinstance(obj, dict):
            continue
        if isinstance(obj.get("material"), str) and obj["material"] not in names:
            yield f"objects[{i}].material", unknown_material(obj["material"], names)
        vertices, faces = obj.get("vertices"), obj.get("faces")
        if obj.get("type") == "mesh" and isinstance(vertices, list) and isinstance(faces, list):
            bad = [
                (f, k, x)
                for f, face in enumerate(faces)
                if isinstance(face, list)
                for k, x in enumerate(face[:3])
                if isinstance(x, int) and not isinstance(x, bool) and x >= len(vertices)
            ]
            yield from out_of_range(f"objects[{i}]", bad, len(vertices))


def _in_pieces(section: Any, name: str, adapter: TypeAdapter, problems: _Problems) -> Any:
    """Validate a list or dict :data:`PIECE` entries at a time, with error paths made absolute."""
    is_dict = isinstance(section, dict)
    out: Any = {} if is_dict else []
    items = iter(section.items() if is_dict else section)
    start = 0
    while not problems.full:
        chunk = list(islice(items, PIECE))
        if not chunk:
            break
        try:
            valid = adapter.validate_python(dict(chunk) if is_dict else chunk)
        except ValidationError as exc:
            errors = exc.errors(include_url=False)
            for err in errors:
                loc = err["loc"]
                if not is_dict and loc and isinstance(loc[0], int):
                    loc = (loc[0] + start, *loc[1:])
                err["loc"] = (name, *loc)
            problems.extend(problems_from_validation(errors))
        else:
            out.update(valid) if is_dict else out.extend(valid)
        start += len(chunk)
    return out


def _bounded(data: dict, path: str, problems: _Problems, arrays: dict[tuple[int, str], list | None]) -> dict:
    """``data`` with the parts pydantic would report in unbounded numbers made small: every dict but
    ``materials`` cut to :data:`MAX_KEYS` keys, and the long arrays of mesh objects taken out into
    ``arrays`` (checked here)."""
    items = list(data.items())
    if path != "materials" and len(items) > MAX_KEYS:
        problems.add(
            (
                path,
                f"has {len(items)} keys; no part of a scene has more than {MAX_KEYS} "
                f"(the first {MAX_KEYS} are checked)",
            )
        )
        items = items[:MAX_KEYS]
    out = {}
    for key, value in items:
        where = f"{path}.{key}" if path else str(key)
        if isinstance(value, dict):
            value = _bounded(value, where, problems, arrays)
        elif isinstance(value, list) and where in ("objects", "lights"):
            value = [
                _bounded(v, f"{where}[{i}]", problems, arrays) if isinstance(v, dict) else v
                for i, v in enumerate(value)
            ]
        elif (
            isinstance(value, list)
            and key in _MESH_ARRAYS
            and len(value) > LONG
            and path.startswith("objects[")
            and data.get("type") == "mesh"
        ):
            index = int(path[len("objects[") : -1])
            arrays[(index, key)] = _rows(value, where, key == "faces", problems)
            value = []
        out[key] = value
    return out


def _rows(rows: list, where: str, integer: bool, problems: _Problems) -> list | None:
    """A long mesh array as a list of 3-tuples, or None after reporting what is wrong with it."""
    out: list = []
    for start in range(0, len(rows), ROWS):
        piece = rows[start : start + ROWS]
        try:
            lengths = set(map(len, piece))
            flat = list(chain.from_iterable(piece))
        except TypeError:  # a row that is not an array
            break
        kinds = set(map(type, flat))
        if lengths != {3} or not kinds <= ({int} if integer else {int, float}):
            break
        low, high = min(flat), max(flat)
        if integer and not (0 <= low and high < INDEX_END):
            break
        if not integer:
            try:
                if not (math.isfinite(low) and math.isfinite(high)):
                    break
                if int in kinds:  # as pydantic would give them: floats
                    piece = np.array(piece, dtype=np.float64).tolist()
            except OverflowError:  # an integer beyond float64
                break
        out.extend(map(tuple, piece))
    else:
        return out
    _report_rows(rows, where, integer, problems)
    return None


def _report_rows(rows: list, where: str, integer: bool, problems: _Problems) -> None:
    """Every wrong entry of a mesh array (up to the counting limit), in the words pydantic would use."""
    for i, row in enumerate(rows):
        if problems.full:
            return
        at = f"{where}[{i}]"
        if not isinstance(row, list):
            problems.add((at, "must be an array"))
            continue
        if len(row) != 3:
            problems.add((at, f"has {len(row)} element{'' if len(row) == 1 else 's'}, expected 3"))
        for k, x in enumerate(row[:3]):
            message = _entry_problem(x, integer)
            if message:
                problems.add((f"{at}[{k}]", message))


def _entry_problem(x: Any, integer: bool) -> str | None:
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        return "must be an integer" if integer else "must be a number"
    if integer:
        if not isinstance(x, int):
            return "must be an integer"
        if x < 0:
            return "must be ≥ 0"
        return f"must be < {INDEX_END}" if x >= INDEX_END else None
    try:
        return None if math.isfinite(float(x)) else "must be a finite number"
    except OverflowError:
        return "must be a number"
