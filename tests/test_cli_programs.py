"""The command line's options for students' programs (service.cli.programs): sizes, limits, mistakes."""

import argparse

import pytest

from service.cli.programs import add_arguments, program, size
from service.programs.limits import GIB, MB


@pytest.mark.parametrize(
    ("text", "expected"),
    [("2G", 2 * GIB), ("512MiB", 512 << 20), ("100MB", 100 * MB), ("4096", 4096), ("1.5k", 1536), (" 8 M ", 8 << 20)],
)
def test_a_size_reads_its_unit(text, expected):
    assert size(text) == expected


@pytest.mark.parametrize("text", ["", "G", "2T", "-1M", "0", "two"])
def test_a_size_that_is_not_one_is_refused_in_words(text):
    with pytest.raises(argparse.ArgumentTypeError, match="not a size"):
        size(text)


def parse(*args: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    return parser.parse_args(list(args))


def test_the_defaults_are_a_courses_and_the_options_set_the_limits():
    assert program(parse()) is None
    default = program(parse("--run", "python3 r.py {scene} {output}"))
    assert default is not None and default.sandbox and default.build is None
    assert (
        default.limits.memory_bytes,
        default.limits.processes,
        default.limits.wall_seconds,
        default.limits.cpu_seconds,
        default.limits.output_bytes,
    ) == (2 * GIB, 64, 60.0, 60, 100 * MB)
    given = program(
        parse(
            "--run",
            "./rt {scene} {output}",
            "--build",
            "make",
            "--run-timeout",
            "5",
            "--memory",
            "1G",
            "--processes",
            "8",
            "--output-size",
            "10MB",
            "--no-sandbox",
        )
    )
    assert given is not None and given.build == "make" and not given.sandbox
    assert (
        given.limits.memory_bytes,
        given.limits.processes,
        given.limits.wall_seconds,
        given.limits.cpu_seconds,
        given.limits.output_bytes,
    ) == (GIB, 8, 5.0, 5, 10 * MB)


def test_a_program_option_without_run_is_the_tas_mistake():
    with pytest.raises(ValueError, match="--build, --no-sandbox, --memory: only with --run"):
        program(parse("--build", "make", "--no-sandbox", "--memory", "1G"))
