"""A combination of mistakes made together: its record (:class:`Combination`, each mistake a :class:`Member`
with its evidence), the options of mistakes made together (:func:`merged`) and of a mistake made by a student who
renders their own way (:func:`on_base`), and which come first of two a diagnosis cannot tell apart
(:func:`classic_first`)."""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

from tracer.scene.variants import MORE_VARIANTS, REFERENCE, VARIANTS, Options

#: every mistake that may be named: name → (options, what the student did)
ALL: dict[str, tuple[Options, str]] = {**VARIANTS, **MORE_VARIANTS}


@dataclass(frozen=True)
class Member:
    """One mistake of a combination, with its evidence: how much of the difference it accounts for."""

    variant: str
    mistake: str
    share: float  # of the submission's mean difference from the reference, what adding it takes away
    evidence: str  # in words: why it was tried


@dataclass(frozen=True)
class Combination:
    """Mistakes made together, and the submission graded against the reference rendered with all of them."""

    members: tuple[Member, ...]
    fraction_off_nearby: float
    passes: bool
    #: the other readings of the same image: as many mistakes, some made in place of others a diagnosis's rows
    #: cannot tell them from (:func:`.compose.readings`), whose render the submission passes against too
    readings: tuple[Combination, ...] = ()

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(m.variant for m in self.members)


def merged(names: tuple[str, ...] | list[str]) -> Options:
    """The options of mistakes made together: the changed fields of each mistake's options, on the reference's.
    ValueError for two that change one field differently (one bounce too many and too few)."""
    update: dict[str, object] = {}
    for name in names:
        options = ALL[name][0]
        for f in fields(options):
            value = getattr(options, f.name)
            if value != getattr(REFERENCE, f.name):
                if update.get(f.name, value) != value:
                    raise ValueError(f"{name} and another mistake both change {f.name}")
                update[f.name] = value
    return replace(REFERENCE, **update)  # type: ignore[arg-type]


def compatible(names: tuple[str, ...]) -> bool:
    """Whether the mistakes can be made together (no field changed two ways)."""
    try:
        merged(names)
    except ValueError:
        return False
    return True


def classic_first(names: tuple[str, ...]) -> tuple[int, tuple[str, ...]]:
    """A sort key: fewer new mistakes (:data:`MORE_VARIANTS`) first, then by name."""
    return sum(n not in VARIANTS for n in names), names


#: the fields of an offset, taken from a base together or not at all
OFFSET_FIELDS = ("offset", "offset_along")


def on_base(options: Options, base: Options) -> Options:
    """``options`` made by a student who renders as ``base`` says: its rays leave surfaces by its offset, unless
    ``options`` sets an offset of its own (an offset too large); every other field ``base`` changes (a camera
    mistake's, :mod:`.behind`) is changed so, unless ``options`` changes that field itself."""
    update: dict[str, object] = {}
    for f in fields(base):
        value = getattr(base, f.name)
        if value == getattr(REFERENCE, f.name):
            continue
        mine = (
            options.offset != 0 if f.name in OFFSET_FIELDS else getattr(options, f.name) != getattr(REFERENCE, f.name)
        )
        if not mine:
            update[f.name] = value
    return replace(options, **update) if update else options  # type: ignore[arg-type]
