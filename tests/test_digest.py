"""What a kept grade of a student's program stands for (service.programs.digest): every file's name, bytes and
executable bit, and how the program is built, run, limited and given its runtime; two different folders never
make one digest."""

import os

from service.programs.digest import digest
from service.programs.folder import MAX_PATH
from service.programs.limits import Limits
from service.programs.program import Program

RUN = "./raytracer {scene} {output}"
PROGRAM = Program(RUN, limits=Limits(folder_bytes=4 << 20))


def test_a_files_executable_bit_is_part_of_the_program(tmp_path):
    """A program handed in without its executable bit crashes (exit 126); given it, it is another program."""
    (tmp_path / "raytracer").write_text("#!/usr/bin/python3\nprint('hello')\n")
    (tmp_path / "raytracer").chmod(0o644)
    before = digest(tmp_path, PROGRAM)
    (tmp_path / "raytracer").chmod(0o755)
    assert digest(tmp_path, PROGRAM) != before


def test_the_runtime_and_its_packages_are_part_of_how_it_runs(tmp_path):
    (tmp_path / "render.py").write_text("print('hello')\n")
    plain = digest(tmp_path, Program("python3 render.py {scene} {output}"))
    given = digest(tmp_path, Program("python3 render.py {scene} {output}", runtime="/opt/course-env"))
    packages = digest(tmp_path, Program("python3 render.py {scene} {output}", packages=("python3-numpy",)))
    assert len({plain, given, packages}) == 3


def test_names_and_contents_cannot_run_into_each_other(tmp_path):
    """{a: "xb\\0y"} and {a: "x", b: "y"} are two folders (each name and each content has its length)."""
    one, two = tmp_path / "one", tmp_path / "two"
    one.mkdir()
    two.mkdir()
    (one / "a").write_bytes(b"xb\0y")
    (two / "a").write_bytes(b"x")
    (two / "b").write_bytes(b"y")
    assert digest(one, PROGRAM) != digest(two, PROGRAM)


def test_an_empty_folder_and_an_empty_file_differ(tmp_path):
    one, two = tmp_path / "one", tmp_path / "two"
    (one / "data").mkdir(parents=True)
    two.mkdir()
    (two / "data").write_bytes(b"")
    assert digest(one, PROGRAM) != digest(two, PROGRAM)


def _chain(folder, depth: int) -> None:
    """``depth`` folders of 250-byte names, one in the other (made through descriptors: the path grows past the
    machine's PATH_MAX)."""
    fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    for _ in range(depth):
        os.mkdir("d" * 250, dir_fd=fd)
        deeper = os.open("d" * 250, os.O_RDONLY | os.O_DIRECTORY, dir_fd=fd)
        os.close(fd)
        fd = deeper
    os.close(fd)


def test_what_the_copy_leaves_out_is_not_part_of_it(tmp_path):
    """A link is not followed; a path longer than MAX_PATH is left out of the copy, and of the digest (however
    deep: no path of the machine's, absolute or not, is asked for)."""
    deep, cut = tmp_path / "deep", tmp_path / "cut"
    for folder, depth in ((deep, 20), (cut, MAX_PATH // 251)):
        folder.mkdir()
        (folder / "render.py").write_text("print('hello')\n")
        _chain(folder, depth)
    os.symlink("/etc/passwd", deep / "passwd")
    assert digest(deep, PROGRAM) == digest(cut, PROGRAM)
    (cut / "render.py").write_text("print('changed')\n")
    assert digest(deep, PROGRAM) != digest(cut, PROGRAM)
