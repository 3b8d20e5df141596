"""The private copy of a student's folder (service.programs.folder): links, FIFOs and names leaving the folder
are left out, and a folder over its limit (in bytes, or in files) is refused."""

import io
import os
import shutil
import tarfile
import tempfile
from pathlib import Path

import pytest

from service.programs.folder import ENTRY_BYTES, MAX_ENTRIES, FolderTooLarge, copy_folder, unpack


def test_the_copy_holds_regular_files_and_folders_only(tmp_path):
    student, copy = tmp_path / "ann", tmp_path / "copy"
    (student / "src").mkdir(parents=True)
    copy.mkdir()
    (student / "src" / "main.c").write_text("int main() { return 0; }\n")
    (student / "raytracer").write_bytes(b"\x7fELF")
    (student / "raytracer").chmod(0o755)
    (tmp_path / "secret.txt").write_text("the TA's")
    (student / "link").symlink_to(tmp_path / "secret.txt")
    (student / "folder-link").symlink_to(tmp_path)
    os.mkfifo(student / "pipe")
    copy_folder(student, copy, 1 << 20)
    assert sorted(str(p.relative_to(copy)) for p in copy.rglob("*")) == ["raytracer", "src", "src/main.c"]
    assert os.access(copy / "raytracer", os.X_OK) and not os.access(copy / "src" / "main.c", os.X_OK)


def test_a_folder_over_the_limit_is_refused_in_bytes_or_in_files(tmp_path):
    student = tmp_path / "ann"
    for folder in (student, tmp_path / "copy", tmp_path / "copy2"):
        folder.mkdir()
    (student / "big").write_bytes(b"\0" * 2048)
    with pytest.raises(FolderTooLarge):
        copy_folder(student, tmp_path / "copy", 1024)
    (student / "big").unlink()
    for i in range(10):
        (student / f"empty{i}").touch()
    with pytest.raises(FolderTooLarge):
        copy_folder(student, tmp_path / "copy2", 5 * ENTRY_BYTES)


def test_a_folder_of_too_many_files_is_refused_before_anything_is_copied(tmp_path):
    """More than MAX_ENTRIES empty files, far under the limit in bytes: refused, and nothing was copied (a folder
    of 190,000 empty files cost each run 13 s of copying and removal, outside every limit)."""
    student, copy = tmp_path / "ann", tmp_path / "copy"
    (student / "a" / "b").mkdir(parents=True)
    copy.mkdir()
    (student / "tracer.py").write_text("print('hello')\n")
    for i in range(MAX_ENTRIES):
        (student / "a" / "b" / f"{i}").touch()
    assert (MAX_ENTRIES + 3) * ENTRY_BYTES < 100 * 1000 * 1000  # (in bytes, the default folder limit holds it)
    with pytest.raises(FolderTooLarge, match=f"more than {MAX_ENTRIES} files and folders"):
        copy_folder(student, copy, 100 * 1000 * 1000)
    assert list(copy.iterdir()) == []
    for i in range(3):  # (tracer.py, a and b count too)
        (student / "a" / "b" / f"{i}").unlink()
    copy_folder(student, copy, 100 * 1000 * 1000)  # at the cap: copied
    assert (copy / "tracer.py").read_text() == "print('hello')\n"


def _tar(members: list[tuple[tarfile.TarInfo, bytes]]) -> bytes:
    out = io.BytesIO()
    with tarfile.open(fileobj=out, mode="w") as tar:
        for info, data in members:
            info.size = len(data)
            tar.addfile(info, io.BytesIO(data) if info.isreg() else None)
    return out.getvalue()


def _member(name: str, kind: bytes = tarfile.REGTYPE, target: str = "") -> tarfile.TarInfo:
    info = tarfile.TarInfo(name)
    info.type, info.linkname, info.mode = kind, target, 0o755
    return info


def test_a_builds_result_is_unpacked_without_links_or_escapes(tmp_path):
    stream = _tar(
        [
            (_member("./bin/raytracer"), b"built"),
            (_member("../escaped"), b"x"),
            (_member("/etc/escaped"), b"x"),
            (_member("passwd", tarfile.SYMTYPE, "/etc/passwd"), b""),
            (_member("hard", tarfile.LNKTYPE, "bin/raytracer"), b""),
            (_member("bin/raytracer/x"), b"x"),
        ]
    )
    target = tmp_path / "built"
    target.mkdir()
    unpack(stream, target, 1 << 20)
    assert sorted(str(p.relative_to(target)) for p in target.rglob("*")) == ["bin", "bin/raytracer"]
    assert (target / "bin" / "raytracer").read_bytes() == b"built" and os.access(target / "bin/raytracer", os.X_OK)
    assert not (tmp_path / "escaped").exists()
    with pytest.raises(FolderTooLarge):
        unpack(_tar([(_member("big"), b"\0" * 4096)]), tmp_path / "small", 1024)


def test_a_folder_deeper_than_the_machines_longest_path_is_copied_to_its_limit(tmp_path):
    """Folders of 250-byte names, 20 deep: each name is legal, the whole path 5,000 bytes, longer than the
    machine's PATH_MAX. The copy (and the pack made of it) keeps what is within MAX_PATH, as it keeps what is
    within MAX_DEPTH, and leaves the rest out."""
    from service.programs.folder import MAX_PATH
    from service.programs.pack import pack_folder, unpacked

    student, copy = tmp_path / "ann", tmp_path / "copy"
    student.mkdir()
    copy.mkdir()
    (student / "render.py").write_text("print('hello')\n")
    fd = os.open(student, os.O_RDONLY | os.O_DIRECTORY)
    for _ in range(20):
        os.mkdir("d" * 250, dir_fd=fd)
        deeper = os.open("d" * 250, os.O_RDONLY | os.O_DIRECTORY, dir_fd=fd)
        os.close(fd)
        fd = deeper
    with open(os.open("deepest.txt", os.O_WRONLY | os.O_CREAT, 0o600, dir_fd=fd), "w") as f:
        f.write("beyond every limit")
    os.close(fd)
    copy_folder(student, copy, 1 << 20)
    kept = sorted(str(p.relative_to(copy)) for p in copy.rglob("*"))
    assert max(kept, key=len) == "/".join(["d" * 250] * (MAX_PATH // 251)) and "render.py" in kept
    pack = pack_folder(student, 1 << 20)
    assert pack.too_large is None
    with unpacked(pack, 1 << 20) as folder:
        assert sorted(str(p.relative_to(folder)) for p in folder.rglob("*")) == kept


def _as_nobody(work):  # noqa: ANN001, ANN202
    """``work()``'s answer, called as a user who is not root (here if this is not root, else in a child that
    becomes user 65534): root reads every file, whatever its mode."""

    def said() -> str:
        try:
            return str(work())
        except Exception as exc:  # noqa: BLE001
            return f"{type(exc).__name__}: {exc}"

    if os.geteuid() != 0:
        return said()
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # (the child: never back into pytest)
        os.close(read)
        try:
            os.setgid(65534)
            os.setuid(65534)
            os.write(write, said().encode())
        finally:
            os._exit(0)
    os.close(write)
    with os.fdopen(read, "rb") as f:
        answer = f.read().decode()
    os.waitpid(pid, 0)
    return answer


def test_a_students_file_the_grader_cannot_read_stops_the_class_naming_it():
    """A student's file this user cannot read (unpacked by another user) was left out of the program's copy
    without a word, and the student charged with the crash: now the run stops first, naming it."""
    from service.classgrade.programs import discover_programs

    place = Path(tempfile.mkdtemp(prefix="phongray-unreadable-"))
    try:
        os.chmod(place, 0o755)
        (place / "scenes").mkdir(mode=0o755)
        (place / "scenes" / "spheres.json").write_text("{}")
        for student in ("ada", "eve"):
            (place / "subs" / student / "src").mkdir(mode=0o755, parents=True)
            (place / "subs" / student / "src" / "tracer.js").write_text("1")
        os.chmod(place / "subs", 0o755)
        os.chmod(place / "subs" / "eve" / "src" / "tracer.js", 0o000)

        def found():  # noqa: ANN202
            return len(discover_programs(place / "scenes", place / "subs").students)

        said = _as_nobody(found)
        assert str(said).startswith(f"ClassError: {place}/subs/eve/src/tracer.js: this user cannot read it"), said
        os.chmod(place / "subs" / "eve" / "src" / "tracer.js", 0o644)
        assert str(_as_nobody(found)) == "2"
        os.chmod(place / "subs" / "eve", 0o444)  # (listed, but nothing in it can be opened)
        said = _as_nobody(found)
        assert str(said).startswith(f"ClassError: {place}/subs/eve: this user cannot read it"), said
        os.chmod(place / "subs" / "eve", 0o755)
    finally:
        shutil.rmtree(place)


def test_names_too_long_for_a_path_or_a_folder_gone_meanwhile_are_no_refusal(tmp_path):
    """Sixteen nested folders of 250-byte names make paths longer than the system takes: the copy leaves them
    out (MAX_PATH), and the check that every file may be read does not count them as refused."""
    from service.programs.folder import unreadable

    deep = tmp_path / "student"
    deep.mkdir()
    fd = os.open(deep, os.O_RDONLY)
    try:
        for _ in range(16):
            os.mkdir("d" * 250, dir_fd=fd)
            inner = os.open("d" * 250, os.O_RDONLY, dir_fd=fd)
            os.close(fd)
            fd = inner
        with open(os.open("f.txt", os.O_WRONLY | os.O_CREAT, 0o644, dir_fd=fd), "w") as f:
            f.write("x")
    finally:
        os.close(fd)
    (deep / "tracer.py").write_text("1")
    assert unreadable(deep) is None
