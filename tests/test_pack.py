"""A student's folder as bytes (service.programs.pack): the same folder makes the same bytes, holds what a run's
copy holds (no link, executable bits kept), is refused over the limit, and is not unpacked when damaged."""

import os
from dataclasses import replace

import pytest

from service.programs.pack import DamagedPack, pack_folder, unpacked


def student(root):
    folder = root / "ann"
    (folder / "src").mkdir(parents=True)
    (folder / "src" / "main.c").write_text("int main() { return 0; }\n")
    (folder / "run.sh").write_text("#!/bin/sh\n")
    (folder / "run.sh").chmod(0o755)
    (root / "secret.txt").write_text("the TA's")
    (folder / "peek").symlink_to(root / "secret.txt")
    return folder


def test_a_pack_holds_the_copy_and_the_same_folder_makes_the_same_bytes(tmp_path):
    folder = student(tmp_path)
    pack = pack_folder(folder, 1 << 20)
    os.utime(folder / "run.sh", (0, 12345))  # (a time is not part of the program)
    assert pack_folder(folder, 1 << 20) == pack and pack.too_large is None
    with unpacked(pack, 1 << 20) as there:
        assert sorted(p.relative_to(there).as_posix() for p in there.rglob("*")) == ["run.sh", "src", "src/main.c"]
        assert os.access(there / "run.sh", os.X_OK) and not os.access(there / "src" / "main.c", os.X_OK)
        assert (there / "src" / "main.c").read_text() == "int main() { return 0; }\n"
    assert not there.exists()
    (folder / "src" / "main.c").write_text("int main() { return 1; }\n")
    assert pack_folder(folder, 1 << 20).sha256 != pack.sha256


def test_a_folder_over_the_limit_makes_a_pack_that_says_so(tmp_path):
    folder = student(tmp_path)
    (folder / "data.bin").write_bytes(b"\0" * 4096)
    pack = pack_folder(folder, 1024)
    assert pack.data == b"" and pack.too_large == "the student's folder is larger than the limit"


def test_a_damaged_pack_is_not_unpacked(tmp_path):
    pack = pack_folder(student(tmp_path), 1 << 20)
    damaged = replace(pack, data=pack.data[:-1] + b"x")
    with pytest.raises(DamagedPack, match="arrived damaged"), unpacked(damaged, 1 << 20):
        pass
