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
    fraction_off_nearby: float = Field(description="pixels off against every reference pixel of their 3×3 "
                                                   "neighbourhood: the ones the verdict counts")
    width: int
    height: int
    reference_sha256: str
    reason: str = Field(description="why it failed, in words; empty when it passed")
