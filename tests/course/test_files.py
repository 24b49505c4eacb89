"""The course's files are written whole or not at all (cvkit.course.files)."""
from __future__ import annotations

import json
import os
import stat
import threading

import pytest

from cvkit.course import files
from cvkit.course.files import whole_file, write_whole
from cvkit.course.journal import Journal


def _leftovers(folder):
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".part"))


def test_text_and_bytes_are_written_exactly_and_the_folder_is_made(tmp_path):
    target = tmp_path / "new" / "deep" / "a.csv"
    write_whole(target, "a,b\r\nü,€\n")
    assert target.read_bytes() == "a,b\r\nü,€\n".encode()  # line ends as given, UTF-8
    write_whole(target, b"\x00\xff")
    assert target.read_bytes() == b"\x00\xff"
    assert _leftovers(target.parent) == []


def test_the_target_is_the_old_file_until_the_block_ends(tmp_path):
    target = tmp_path / "journal.json"
    target.write_text("old")
    with whole_file(target) as handle:
        handle.write("new")
        handle.flush()
        assert target.read_text() == "old"  # a reader meanwhile sees the old file, whole
    assert target.read_text() == "new"


def test_an_error_in_the_block_leaves_the_target_as_it_was_and_no_temporary_file(tmp_path):
    target = tmp_path / "marks.json"
    target.write_text("kept")
    with pytest.raises(RuntimeError, match="interrupted"):
        with whole_file(target) as handle:
            handle.write("half of the new ")
            raise RuntimeError("interrupted")
    assert target.read_text() == "kept"
    assert _leftovers(tmp_path) == []


def test_an_encoding_error_leaves_the_target_as_it_was(tmp_path):
    target = tmp_path / "records.json"
    target.write_text("kept")
    with pytest.raises(UnicodeEncodeError):
        write_whole(target, "a lone surrogate \udc80")
    assert target.read_text() == "kept"
    assert _leftovers(tmp_path) == []
    write_whole(target, "a lone surrogate \udc80", errors="surrogateescape")
    assert target.read_bytes() == b"a lone surrogate \x80"


def test_a_failed_flush_to_disk_keeps_the_old_file(tmp_path, monkeypatch):
    target = tmp_path / "x.txt"
    target.write_text("kept")

    def no_disk(descriptor):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(files.os, "fsync", no_disk)
    with pytest.raises(OSError, match="No space"):
        write_whole(target, "new")
    assert target.read_text() == "kept"
    assert _leftovers(tmp_path) == []


def test_permissions_are_those_of_a_plain_new_file_unless_given(tmp_path):
    plain = tmp_path / "plain"
    plain.write_text("x")
    whole = tmp_path / "whole"
    write_whole(whole, "x")
    assert stat.S_IMODE(whole.stat().st_mode) == stat.S_IMODE(plain.stat().st_mode)
    old = os.umask(0o077)
    try:
        write_whole(whole, "x")
        assert stat.S_IMODE(whole.stat().st_mode) == 0o600  # the umask of the moment
    finally:
        os.umask(old)
    for mode in (0o640, 0o644, 0o600):
        write_whole(whole, "y", mode=mode)
        assert stat.S_IMODE(whole.stat().st_mode) == mode


def test_a_link_at_the_target_is_replaced_not_followed(tmp_path):
    elsewhere = tmp_path / "elsewhere.txt"
    elsewhere.write_text("not to be touched")
    link = tmp_path / "stamp"
    link.symlink_to(elsewhere)
    write_whole(link, "ours")
    assert not link.is_symlink() and link.read_text() == "ours"
    assert elsewhere.read_text() == "not to be touched"


def test_concurrent_writers_leave_one_whole_version(tmp_path):
    target = tmp_path / "shared.json"
    versions = [json.dumps({"writer": i, "pad": "x" * 20000}) for i in range(8)]
    threads = [threading.Thread(target=write_whole, args=(target, text)) for text in versions]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert target.read_text() in versions
    assert _leftovers(tmp_path) == []


def test_a_name_as_long_as_the_system_allows(tmp_path):
    target = tmp_path / ("n" * 250)
    write_whole(target, "x")
    assert target.read_text() == "x" and _leftovers(tmp_path) == []


def test_data_must_be_text_or_bytes(tmp_path):
    with pytest.raises(TypeError, match="data must be str or bytes, got dict"):
        write_whole(tmp_path / "x", {"a": 1})
    assert list(tmp_path.iterdir()) == []


def test_an_interrupted_journal_write_keeps_the_journal_readable(tmp_path, monkeypatch):
    journal = Journal(tmp_path, read=lambda student, assignment: ({"a.ipynb": b"{}"}, []))
    journal.mark_graded([("alice", "ch01")])
    before = journal.graded()
    assert set(before) == {"alice/ch01"}

    def lost_machine(descriptor):
        raise OSError(5, "Input/output error")

    monkeypatch.setattr(files.os, "fsync", lost_machine)
    with pytest.raises(OSError):
        journal.mark_graded([("bob", "ch01")])
    assert journal.graded() == before  # not "nothing graded yet"
    with pytest.raises(OSError):
        journal.set_not_graded("carol", "ch01", "no notebook")
    assert journal.not_graded() == {}
