"""The course's own bookkeeping next to nbgrader's gradebook, in ``<course>/.cvkit/``.

- ``journal.json``: ``"student/assignment"`` → hash of the submission's files when it was last
  graded, so that an interrupted run resumes after it and a changed submission is regraded;
- ``not_graded.json``: ``"student/assignment"`` → why it could not be graded (never a zero);
- flags for the instructor, added to the autograded notebooks' metadata (``metadata.cvkit.flags``).
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

from ..grading.isolation import collect_files


class Journal:
    """The bookkeeping files of the course folder ``root`` (see the module docstring).

    Parameters
    ----------
    root : Path
        The course folder.
    """

    def __init__(self, root: Path) -> None:
        self.root = root

    @property
    def path(self) -> Path:
        """``journal.json``: the hash of every graded submission."""
        return self.root / ".cvkit" / "journal.json"

    @property
    def not_graded_path(self) -> Path:
        """``not_graded.json``: the submissions that could not be graded, with their reasons."""
        return self.root / ".cvkit" / "not_graded.json"

    # ------------------------------------------------------------------ graded submissions
    def graded(self) -> dict[str, str]:
        """``"student/assignment"`` → hash of the files it was graded from."""
        try:
            return json.loads(self.path.read_text()) if self.path.exists() else {}
        except ValueError:
            return {}

    def submission_hash(self, student: str, assignment: str) -> str:
        """Hash of a submission's regular files (and of the notes on the files refused)."""
        digest = hashlib.sha256()
        files, refused = collect_files(self.root / "submitted" / student / assignment)
        for name, data in sorted(files.items()):
            digest.update(name.encode())
            digest.update(data)
        for note in refused:
            digest.update(note.encode())
        return digest.hexdigest()

    def is_current(self, student: str, assignment: str) -> bool:
        """Graded before from the very files submitted now."""
        return self.graded().get(f"{student}/{assignment}") == self.submission_hash(student, assignment)

    def mark_graded(self, pairs: list[tuple[str, str]]) -> None:
        """Remember that these (student, assignment) submissions are graded, as they are now."""
        journal = self.graded()
        for student, assignment in pairs:
            journal[f"{student}/{assignment}"] = self.submission_hash(student, assignment)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.path.write_text(json.dumps(journal, indent=1))

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
        self.not_graded_path.parent.mkdir(parents=True, exist_ok=True)
        self.not_graded_path.write_text(json.dumps(data, indent=1))

    # ------------------------------------------------------------------ flags
    def add_flag(self, student: str, assignment: str, flag: str) -> None:
        """Append a flag to the metadata of a student's autograded notebooks."""
        for path in (self.root / "autograded" / student / assignment).glob("*.ipynb"):
            nb = json.loads(path.read_text())
            meta = nb.setdefault("metadata", {}).setdefault("cvkit", {})
            meta.setdefault("flags", []).append(flag)
            path.write_text(json.dumps(nb, indent=1))
