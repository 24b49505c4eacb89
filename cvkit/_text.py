"""Text a student names, made safe to show: :func:`printable` for what leaves cvkit (the
terminal table, the CSV exports), :func:`name_problem` and :func:`skeleton` for the names of
student folders and submitted files.

A student controls file and folder names (any bytes but ``/`` and NUL: Python gives the bytes
that are not UTF-8 as lone surrogates, ``b"\\xff"`` → ``"\\udcff"``, which crash ``encode``,
``print``, ``csv`` and ``json`` writers) and the text of exceptions, problems and flags. Shown
as they are, control characters drive the instructor's terminal (``ESC [2J`` clears it and its
scrollback), bidi overrides reorder what is read, and invisible characters make two different
ids look the same. Here they are shown as visible escapes, in Python's notation
(``\\x1b``, ``\\u202e``; an undecodable byte as ``\\xff``); the rendering is for reading, not
reversible (a backslash stays a backslash).
"""
from __future__ import annotations

import re
import unicodedata

#: Unicode categories never shown as they are: controls (C0, DEL, C1), format characters (bidi
#: overrides and marks, zero-width space and joiners, BOM, soft hyphen…), surrogates (bytes that
#: are not UTF-8), line and paragraph separators
HIDDEN_CATEGORIES = frozenset({"Cc", "Cf", "Cs", "Zl", "Zp"})

#: invisible characters of other categories (Unicode's default-ignorable code points that are
#: not format characters): combining grapheme joiner, Hangul fillers, Khmer inherent vowels,
#: Mongolian and other variation selectors
_INVISIBLE = re.compile("[\u034f\u115f\u1160\u17b4\u17b5\u180b-\u180d\u180f\u3164\ufe00-\ufe0f\uffa0"
                        "\U000e0100-\U000e01ef]")
_SHORT = {"\n": "\\n", "\r": "\\r", "\t": "\\t"}


def hidden(char: str) -> bool:
    """True for a character that would act on the terminal or not be seen: a control, format,
    surrogate or separator character, or another invisible one (see the module docstring)."""
    return unicodedata.category(char) in HIDDEN_CATEGORIES or bool(_INVISIBLE.match(char))


def escape(char: str) -> str:
    """One character in Python's escape notation; a byte that was not UTF-8 (a surrogate
    U+DC80…U+DCFF of ``surrogateescape``) as the byte itself, ``\\xff``."""
    code = ord(char)
    if char in _SHORT:
        return _SHORT[char]
    if 0xDC80 <= code <= 0xDCFF:
        return f"\\x{code - 0xDC00:02x}"
    if code < 0x100:
        return f"\\x{code:02x}"
    return f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}"


def printable(text: object, *, newlines: bool = False) -> str:
    """``text`` (any object, as ``str``) with every hidden character (:func:`hidden`) replaced by
    its visible escape (:func:`escape`): safe to print on a terminal and to write as UTF-8.

    Parameters
    ----------
    text : object
        What to show.
    newlines : bool, default False
        Keep ``\\n`` (a multi-line cell of a CSV file); otherwise it is shown as ``\\n`` too,
        so that a student's text never starts a line of its own on the terminal.

    >>> printable("\\x1b[2Jcleared"), printable("ada\\u200b"), printable("st\\udcffudent")
    ('\\\\x1b[2Jcleared', 'ada\\\\u200b', 'st\\\\xffudent')
    >>> printable("two\\nlines", newlines=True), printable("Zoë ✓ =A1")
    ('two\\nlines', 'Zoë ✓ =A1')
    """
    text = text if isinstance(text, str) else str(text)
    if text.isprintable() and not _INVISIBLE.search(text):  # the usual case: nothing to do
        return text
    return "".join(escape(c) if hidden(c) and not (newlines and c == "\n") else c for c in text)


def _described(chars: list[str]) -> str:
    """``U+200B ZERO WIDTH SPACE, U+001B`` for the distinct ``chars``, in order."""
    names = [f"U+{ord(c):04X}" + (f" {unicodedata.name(c)}" if unicodedata.name(c, "") else "")
             for c in dict.fromkeys(chars)]
    return ", ".join(names[:4]) + (f" and {len(names) - 4} more" if len(names) > 4 else "")


def name_problem(name: str) -> str | None:
    """Why ``name`` (of a file or folder a student made) cannot be used as it is, or None:
    it is not valid UTF-8, or it holds control characters, or invisible or format characters
    (:func:`hidden`). The answer is printable.

    >>> name_problem("ada"), name_problem("st\\udcffudent"), name_problem("ada\\u200b")
    (None, 'is not valid UTF-8', 'holds invisible or format characters (U+200B ZERO WIDTH SPACE)')
    """
    if any(0xD800 <= ord(c) <= 0xDFFF for c in name):
        return "is not valid UTF-8"
    controls = [c for c in name if unicodedata.category(c) == "Cc"]
    if controls:
        return f"holds control characters ({_described(controls)})"
    invisible = [c for c in name if hidden(c)]
    if invisible:
        return f"holds invisible or format characters ({_described(invisible)})"
    return None


def skeleton(name: str) -> str:
    """What ``name`` looks like: without its invisible characters (:func:`hidden`), in Unicode's
    compatibility normal form (NFKC: full-width ``ａ`` → ``a``, ligature ``ﬁ`` → ``fi``), without
    surrounding spaces. Two names with the same skeleton are look-alikes; a name that is its own
    skeleton is made of ordinary characters. Case is kept (``Ada`` and ``ada`` differ).

    >>> skeleton("ada\\u200b"), skeleton("ａｄａ"), skeleton("Ada")
    ('ada', 'ada', 'Ada')
    """
    visible = "".join(c for c in name if not hidden(c))
    normal = unicodedata.normalize("NFKC", visible)
    return "".join(c for c in normal if not hidden(c)).strip()


def differences(name: str) -> str:
    """In words, what makes ``name`` differ from its :func:`skeleton` (printable): the invisible
    characters it holds, compatibility forms, surrounding spaces."""
    parts = []
    controls = [c for c in name if unicodedata.category(c) == "Cc"]
    invisible = [c for c in name if hidden(c) and c not in controls]
    if controls:
        parts.append(f"control characters ({_described(controls)})")
    if invisible:
        parts.append(f"invisible characters ({_described(invisible)})")
    visible = "".join(c for c in name if not hidden(c))
    if unicodedata.normalize("NFKC", visible).strip() != visible.strip():
        odd = [c for c in visible if unicodedata.normalize("NFKC", c) != c]
        parts.append(f"compatibility forms of characters ({_described(odd)})" if odd
                     else "accented letters composed another way")
    if visible != visible.strip():
        parts.append("surrounding spaces")
    return " and ".join(parts) or "nothing visible"
