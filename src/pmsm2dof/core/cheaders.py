"""The comments beside the fields of C structs, read from the C text: meaning, [unit], range.

One parser for every reader: ``ffibuild.py`` compiles the comments of the library's configuration
structs into the extension with it (:func:`pmsm2dof.core.bindings.field_comment` reads them back),
and the A2L file of a firmware build (:mod:`pmsm2dof.drive.a2l`) takes the comments of the
firmware's variables from its headers with it. Pure Python, importing nothing of the package, so
that the build script can load this file before the extension exists.
"""

import re
from collections.abc import Iterable

#: ``typedef struct { fields } name;`` (no nested braces): its body and its name.
STRUCT = re.compile(r"typedef struct\s*\{([^{}]*?)\}\s*(\w+)\s*;", re.S)
#: A field declaration followed by the start of its comment.
FIELD = re.compile(r"^\s*[\w ]*?\s\**(\w+)(?:\[[^\]]*\])?\s*;\s*/\*(.*)$")
#: The unit in a comment: the text of its first square brackets, ``[unit]``.
UNIT = re.compile(r"\[([^\]]*)\]")


def field_comments(texts: Iterable[str], struct_names: str = r"\w+") -> dict[str, str]:
    """The comments of the fields of the typedef'd structs in the C texts, by ``"<struct>.<field>"``.

    Parameters
    ----------
    texts : iterable of str
        C source or header texts.
    struct_names : str
        A regular expression the struct's name must match whole (e.g. ``r"\\w+_(?:config|params)_t"``).
    """
    wanted = re.compile(struct_names)
    comments: dict[str, str] = {}
    for text in texts:
        for body, struct in STRUCT.findall(text):
            if wanted.fullmatch(struct) is None:
                continue
            lines = body.splitlines()
            for i, line in enumerate(lines):
                m = FIELD.match(line)
                if m is None:
                    continue
                parts = [m.group(2)]
                while "*/" not in parts[-1] and i + 1 < len(lines):
                    i += 1
                    parts.append(lines[i])
                joined = " ".join(p.strip() for p in parts)
                comments[f"{struct}.{m.group(1)}"] = " ".join(joined[: joined.index("*/")].split())
    return comments


def comment_unit(comment: str) -> str:
    """The unit of a field comment, the text of its first square brackets ("" when none, "-" for dimensionless)."""
    m = UNIT.search(comment)
    return m.group(1).strip() if m else ""
