"""The shapes of the service's answers, for its OpenAPI document (and so for Swagger UI, ReDoc and clients)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field


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
    diagnosis: Diagnosis | None = Field(
        description="what the student most likely got wrong; null when it passed or diagnose=false"
    )
    accepted: str | None = Field(
        None,
        examples=["a ray offset of 0.003 along the normal"],
        description="the accepted variant of the reference it passed against (an "
        "honest tracer's ray offset); null when it passed against the "
        "reference itself, or failed",
    )


class Cause(BaseModel):
    variant: str = Field(
        examples=["no-shadows"],
        description="a mistake's id; for a nearest explanation that is a term, term:NAME or term:NAME:LIGHT",
    )
    mistake: str = Field(examples=["no shadow rays"])
    fraction_off_nearby: float = Field(
        description="the submission graded against the reference rendered with "
        "the mistake (with the others of a combination)"
    )
    passes: bool = Field(description="the submission passes against that render")
    together: list[str] | None = Field(
        None,
        description="the other mistakes it was rendered with (mistakes made together); absent for a single mistake",
    )
    share: float | None = Field(
        None,
        description="of the submission's difference from the reference, what this "
        "accounts for (a combination's or a nearest explanation's)",
    )
    evidence: str | None = Field(None, description="why it is named, in words")


class Term(BaseModel):
    name: Literal["background", "ambient", "diffuse", "specular", "reflection", "refraction"]
    light: int | None = Field(description="the index in lights of a light's own term")
    scale: float = Field(description="the fitted coefficient against the reference's term: 1 is right")
    share: float | None = Field(
        None, description="of the submission's difference from the reference, what this term accounts for"
    )
    words: str = Field("", examples=["the specular of light 'key' is missing"], description="for a student")


class Share(BaseModel):
    index: int = Field(description="the index in objects (or lights); -1 for the background")
    kind: str
    share: float = Field(description="of the failing pixels")
    words: str = Field(
        "",
        examples=["sphere 'ball'", "the third light (area)"],
        description="for a student: its name in quotes, else its place and kind",
    )


class Diagnosis(BaseModel):
    sentence: str = Field(
        examples=[
            "Likely: no shadow rays — the submission matches the reference rendered "
            "with that mistake (0.02 % of pixels off)"
        ]
    )
    closest: bool = Field(description="the first cause is only the closest, not passed against")
    causes: list[Cause] = Field(description="the mistakes whose render the submission matches, best first")
    terms: list[Term] = Field(description="the additive terms out of scale, most first")
    objects: list[Share] = Field(description="what the failing pixels show")
    lights: list[Share] = Field(description="the lights that fall on the failing pixels")
    offset: str | None = Field(
        None,
        examples=["a ray offset of 0.003 along the normal"],
        description="the honest ray offset the submission's mistakes were named at (its own offset, fitted); "
        "null when they were named against the reference itself",
    )
