"""What one render may be: how many pixels, primary rays and light samples phongray renders at most."""

from __future__ import annotations

import math

from schemas import Scene

from .scene.lights import emitter_count

#: the largest image the renderer will make (16384 × 16384): its pixels alone take 768 MiB
MAX_PIXELS = 1 << 28
#: the most primary rays (pixels × sub-samples) one render will cast
MAX_PRIMARY_RAYS = 1 << 32
#: the most point lights (lights plus area-light samples) one render will shade with
MAX_LIGHT_SAMPLES = 1 << 20


class ImageTooLarge(ValueError):
    """The render asked for is beyond what phongray does: too many pixels, rays or light samples."""


def shown(n: int) -> str:
    """An integer for a message: in full up to 15 digits, else its order of magnitude (Python refuses
    to format integers of more than 4300 digits, and nobody wants to read them)."""
    if abs(n) < 10**15:
        return str(n)
    return f"about 10^{int(abs(n).bit_length() * math.log10(2))}"


def check_size(scene: Scene) -> None:
    """Raises :class:`ImageTooLarge` for a render beyond what phongray does."""
    img = scene.image
    if img.width * img.height > MAX_PIXELS:
        raise ImageTooLarge(
            f"image: {shown(img.width)}×{shown(img.height)} pixels is more than phongray renders ({MAX_PIXELS} "
            "pixels, 16384×16384)"
        )
    if img.width * img.height * img.samples**2 > MAX_PRIMARY_RAYS:
        raise ImageTooLarge(
            f"image: {shown(img.width)}×{shown(img.height)} pixels × {shown(img.samples)}² sub-samples is more "
            f"primary rays than phongray renders ({MAX_PRIMARY_RAYS})"
        )
    lights = emitter_count(scene.lights)
    if lights > MAX_LIGHT_SAMPLES:
        raise ImageTooLarge(
            f"lights: {shown(lights)} light samples are more than phongray renders ({MAX_LIGHT_SAMPLES})"
        )
