"""The course's own bookkeeping next to nbgrader's gradebook, in ``<course>/.cvkit/``.

- ``journal.json``: ``"student/assignment"`` → the hash of the submission's files when it was
  last graded, with the time the instructor's ``submission_times.csv`` lists for it
  (:mod:`.received`), so that an interrupted run resumes after it and a changed submission or
  listed time is regraded; with the due date, the late policy and the fingerprint of the
  checks it was graded under (:mod:`.stamps`: a later change offers a regrade);
- ``not_graded.json``: ``"student/assignment"`` → why it could not be graded (never a zero);
- flags for the instructor, added to the autograded notebooks' metadata (``metadata.cvkit.flags``).
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any, Callable, Mapping

from ..sandbox.isolation import collect_files
from .files import write_whole
from .received import listed_stamp

#: what a journal entry records besides the files' hash (see :mod:`.stamps`)
STAMPS = ("due", "late", "checks")


def _raw(text: str) -> bytes:
    """``text`` as UTF-8 bytes to hash, lone surrogates included (``surrogatepass``: any ``str``
    can be hashed)."""
    return text.encode("utf-8", "surrogatepass")


class Journal:
    """The bookkeeping files of the course folder ``root`` (see the module docstring).

    Parameters
    ----------
    root : Path
        The course folder.
    """

    def __init__(self, root: Path,
                 read: Callable[[str, str], tuple[dict[str, bytes], list[str]]] | None = None) -> None:
        self.root = root
        # a submission's files and refused notes (the course state's one read per run, or the folder now)
        self.read = read or (lambda student, assignment: collect_files(root / "submitted" / student / assignment))

    @property
    def path(self) -> Path:
        """``journal.json``: the hash of every graded submission."""
        return self.root / ".cvkit" / "journal.json"

    @property
    def not_graded_path(self) -> Path:
        """``not_graded.json``: the submissions that could not be graded, with their reasons."""
        return self.root / ".cvkit" / "not_graded.json"

    # ------------------------------------------------------------------ graded submissions
    def entries(self) -> dict[str, dict[str, Any]]:
        """``"student/assignment"`` → ``{"files": hash, "due": ..., "checks": ...}`` of every graded
        submission (an entry written before due dates and checks were recorded has ``files`` only)."""
        try:
            data = json.loads(self.path.read_text()) if self.path.exists() else {}
        except ValueError:
            return {}
        if not isinstance(data, dict):
            return {}
        return {str(key): value if isinstance(value, dict) else {"files": value} for key, value in data.items()}

    def graded(self) -> dict[str, str]:
        """``"student/assignment"`` → hash of the files it was graded from."""
        return {key: str(entry.get("files")) for key, entry in self.entries().items()}

    def submission_hash(self, student: str, assignment: str) -> str:
        """Hash of a submission's regular files (and of the notes on the files refused). The
        names are printable (:func:`~cvkit.sandbox.isolation.collect_files` refuses the others);
        a lone surrogate (a byte that was not UTF-8) would still be hashed, never stop the run."""
        digest = hashlib.sha256()
        files, refused = self.read(student, assignment)
        for name, data in sorted(files.items()):
            digest.update(_raw(name))
            digest.update(data)
        for note in refused:
            digest.update(_raw(note))
        listed = listed_stamp(self.root, student, assignment)  # the instructor's time: a correction regrades
        if listed:
            digest.update(f"\0received {listed}".encode())
        return digest.hexdigest()

    def is_current(self, student: str, assignment: str) -> bool:
        """Graded before from the very files submitted now."""
        return self.graded().get(f"{student}/{assignment}") == self.submission_hash(student, assignment)

    def mark_graded(self, pairs: list[tuple[str, str]],
                    stamps: Mapping[str, Mapping[str, Any]] | None = None) -> None:
        """Remember that these (student, assignment) submissions are graded, as they are now.

        Parameters
        ----------
        pairs : list of (student, assignment)
            The submissions just graded.
        stamps : mapping, optional
            assignment → ``{"due": ..., "late": ..., "checks": ...}``: what they were graded under.
        """
        journal = self.entries()
        for student, assignment in pairs:
            entry: dict[str, Any] = {"files": self.submission_hash(student, assignment)}
            entry.update({k: v for k, v in (stamps or {}).get(assignment, {}).items() if k in STAMPS})
            journal[f"{student}/{assignment}"] = entry
        write_whole(self.path, json.dumps(journal, indent=1))

    def changed(self, pairs: list[tuple[str, str]],
                stamps: Mapping[str, Mapping[str, Any]]) -> dict[tuple[str, str], list[str]]:
        """The graded submissions among ``pairs`` whose due date or checks have changed since.

        Parameters
        ----------
        pairs : list of (student, assignment)
            Submissions to look at (those never graded are skipped).
        stamps : mapping
            assignment → ``{"due": ..., "late": ..., "checks": ...}`` now.

        Returns
        -------
        dict
            (student, assignment) → what changed (``"due date"``, ``"late policy"``,
            ``"checks"``). What an entry does not record (written by an older cvkit) is not
            reported as changed.
        """
        entries = self.entries()
        changed: dict[tuple[str, str], list[str]] = {}
        for student, assignment in pairs:
            entry = entries.get(f"{student}/{assignment}")
            now = stamps.get(assignment, {})
            if entry is None:
                continue
            what = [label for key, label in (("due", "due date"), ("late", "late policy"), ("checks", "checks"))
                    if key in entry and key in now and entry[key] != now[key]]
            if what:
                changed[(student, assignment)] = what
        return changed

    # ------------------------------------------------------------------ not graded
    def not_graded(self) -> dict[str, str]:
        """``"student/assignment"`` → why it could not be graded (never a zero)."""
        try:
            data = json.loads(self.not_graded_path.read_text())
            return {str(k): str(v) for k, v in data.items()} if isinstance(data, dict) else {}
        except (OSError, ValueError):
            return {}

    def set_not_graded(self, student: str, assignment: str, reason: str | None) -> None:
        """List a submission as not graded with ``reason``, or (``None``) take it off the list."""
        data = self.not_graded()
        key = f"{student}/{assignment}"
        if reason is None and key not in data:
            return
        if reason is None:
            data.pop(key, None)
        else:
            data[key] = reason
        write_whole(self.not_graded_path, json.dumps(data, indent=1))

    # ------------------------------------------------------------------ flags
    def add_flag(self, student: str, assignment: str, flag: str) -> None:
        """Append a flag to the metadata of a student's autograded notebooks."""
        for path in (self.root / "autograded" / student / assignment).glob("*.ipynb"):
            nb = json.loads(path.read_text())
            meta = nb.setdefault("metadata", {}).setdefault("cvkit", {})
            meta.setdefault("flags", []).append(flag)
            write_whole(path, json.dumps(nb, indent=1))
