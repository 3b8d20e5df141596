"""The shapes of the service's answers, for its OpenAPI document (and so for Swagger UI, ReDoc and clients)."""

from __future__ import annotations

import dataclasses
from typing import Any, Literal, get_args, get_origin, get_type_hints

from pydantic import BaseModel, Field, create_model

from service.diagnosis import records
from service.diagnosis.records import ANSWERED


class Problem(BaseModel):
    path: str = Field(description="where in the scene, as users write it: objects[2].radius ('' for the whole)")
    message: str = Field(examples=["must be > 0"])
    line: int | None = Field(description="the line of the JSON text the problem concerns, where known")


class ErrorAnswer(BaseModel):
    """Every 4xx and 5xx: what went wrong, and for a scene that breaks the format every problem in it."""

    detail: str = Field(examples=["invalid scene"])
    errors: list[Problem] | None = None
    part: Literal["scene", "image"] | None = Field(None, description="the form part of /grade the error concerns")


class ValidAnswer(BaseModel):
    valid: Literal[True]


class GradeAnswer(BaseModel):
    """A submission's grade; fractions are of the image's pixels, errors in 8-bit levels."""

    passed: bool
    tolerance: float = Field(description="levels a channel may differ by")
    max_fraction: float = Field(description="the fraction of pixels that may be off even nearby")
    mean_abs_error: float
    rmse: float
    psnr: float | None = Field(description="dB; null for identical images")
    max_error: int
    fraction_off: float = Field(description="pixels off by more than the tolerance")
    fraction_off_nearby: float = Field(
        description="pixels off against every reference pixel of their 3×3 neighbourhood: the ones the verdict counts"
    )
    width: int
    height: int
    reference_sha256: str
    grossly_off: int = Field(
        0,
        description="pixels off even nearby by more than 128 levels (a dot or speckle of the wrong colour): "
        "none may be, whatever the fraction",
    )
    open_pixels: int = Field(0, description="pixels the scene format leaves open, not counted")
    reason: str = Field(description="why it failed, in words; empty when it passed")
    #: (Diagnosis: a model made by answer_model, below)
    diagnosis: Diagnosis | None = Field(  # type: ignore[valid-type]
        description="what the student most likely got wrong; null when it passed or diagnose=false"
    )
    accepted: str | None = Field(
        None,
        examples=["a ray offset of 0.003 along the normal"],
        description="the accepted variant of the reference it passed against (an "
        "honest tracer's ray offset); null when it passed against the "
        "reference itself, or failed",
    )


def answer_model(
    record: type, first: dict[str, tuple[object, Any]] | None = None, nested: dict[type, type] | None = None
) -> Any:
    """The pydantic model of a record of :mod:`service.diagnosis.records` as the service answers it: the record's
    fields in its order, each typed and documented as its metadata says (:func:`~service.diagnosis.records.answered`;
    a field without that metadata is not in the answer), after the answer's ``first`` fields; records nested in
    it are their ``nested`` models."""
    hints = get_type_hints(record)
    fields: dict[str, Any] = dict(first or {})  # (name → (type, its Field), as create_model takes them)
    for f in dataclasses.fields(record):
        if ANSWERED not in f.metadata:
            continue
        as_type, doc = f.metadata[ANSWERED]
        kind = hints[f.name] if as_type is None else as_type
        if get_origin(kind) is list and get_args(kind)[0] in (nested or {}):
            kind = list[(nested or {})[get_args(kind)[0]]]  # type: ignore[misc]
        fields[f.name] = (kind, doc)
    return create_model(record.__name__, **fields)


Cause = answer_model(records.Cause)
Term = answer_model(records.Term)
Share = answer_model(records.Share)
Diagnosis = answer_model(
    records.Diagnosis,
    first={
        "sentence": (
            str,
            Field(
                examples=[
                    "Likely: no shadow rays — the submission matches the reference rendered "
                    "with that mistake (0.02 % of pixels off)"
                ]
            ),
        )
    },
    nested={records.Cause: Cause, records.Term: Term, records.Share: Share},
)
GradeAnswer.model_rebuild()
