"""Sphinx extension: the C API page, made from the public headers' own comments.

The directive ``.. c-headers::`` documents every header of ``csrc/include/pmsm2dof`` (a new header
appears by itself) with Sphinx's C domain: the header's opening comment, then each enum, struct, callback type and
function in the order of the header, each with the comment the header gives it. The declarations
are read by pycparser (the parser cffi uses for the same headers), the comments by their line: a
block comment on the lines just above a declaration documents it, a comment that starts on the line
of a struct field or enumerator documents that one.

The build warns (fails under ``-W``) when a public function or struct field has no comment,
when the comment of a ``float`` field gives no unit in brackets (``[Nm]``, ``[-]``), or when the
fields read here differ from those of the compiled extension ``pmsm2dof._core``.
"""

import re
import sys
import textwrap
from dataclasses import dataclass, field
from pathlib import Path

from docutils import nodes
from docutils.statemachine import StringList
from pycparser import c_ast, c_generator, c_parser
from sphinx.errors import ExtensionError
from sphinx.util import logging
from sphinx.util.docutils import SphinxDirective
from sphinx.util.nodes import nested_parse_with_titles

ROOT = Path(__file__).resolve().parents[2]
HEADERS = ROOT / "csrc" / "include" / "pmsm2dof"
# The types the headers take from <stdint.h> and <stdbool.h>, for pycparser (which reads no system header)
PRELUDE = (
    "typedef int bool; typedef unsigned int uint32_t; typedef int int32_t; typedef unsigned char uint8_t;\n"
    "typedef short int16_t; typedef unsigned short uint16_t; typedef long long int64_t;\n"
)
COMMENT = re.compile(r"/\*.*?\*/", re.S)
CPLUSPLUS = re.compile(r"#ifdef __cplusplus.*?#endif", re.S)
# a unit in brackets, "[Nm]", "[-]": not an index such as x[k-1], whose bracket follows a name
UNIT = re.compile(r"(?<![\w\]])\[[^\]]+\]")
logger = logging.getLogger(__name__)


@dataclass
class Comment:
    """A block comment: its first and last line (1-based), whether code precedes it, its text."""

    first: int
    last: int
    trailing: bool
    text: str


@dataclass
class Item:
    """An enum, struct or function of a header, with its members (enumerators or fields)."""

    kind: str  # "enum", "struct" or "function"
    name: str
    declaration: str
    comment: str
    members: list[tuple[str, str]] = field(default_factory=list)  # (declaration, comment)


def comments_of(text):
    """The block comments of ``text``, with the lines they span, their text without the stars."""
    found = []
    for match in COMMENT.finditer(text):
        first = text.count("\n", 0, match.start()) + 1
        line_start = text.rfind("\n", 0, match.start()) + 1
        trailing = text[line_start : match.start()].strip() != ""
        body = match.group(0)[2:-2]
        lines = [re.sub(r"^\s*\* ?", "", line).rstrip() for line in body.splitlines()]
        while lines and not lines[0].strip():
            lines.pop(0)
        while lines and not lines[-1].strip():
            lines.pop()
        found.append(Comment(first, first + match.group(0).count("\n"), trailing, textwrap.dedent("\n".join(lines))))
    return found


def blank(text):
    """``text`` with comments, C++ guards and preprocessor lines blanked out, the line numbers kept."""

    def spaces(match):
        return re.sub(r"[^\n]", " ", match.group(0))

    text = COMMENT.sub(spaces, text)
    text = CPLUSPLUS.sub(spaces, text)
    return "\n".join("" if line.lstrip().startswith("#") else line for line in text.splitlines())


def public_headers():
    """The public headers in the order ffibuild.py gives them to cffi (each after the types it uses)."""
    sys.path.insert(0, str(ROOT))
    import ffibuild

    return [path for path in ffibuild.HEADERS if path.parent == HEADERS]


def parse_headers(paths):
    """The declarations of the headers ``paths``, parsed together in the order given."""
    source = PRELUDE + "".join(f'# 1 "{path.name}"\n{blank(path.read_text())}\n' for path in paths)
    return c_parser.CParser().parse(source, filename="prelude")


class Header:
    """The opening comment and the documented items of one public header."""

    def __init__(self, path, ast):
        self.path = path
        self.name = path.name
        self.comments = comments_of(path.read_text())
        if not self.comments or self.comments[0].first != 1:
            raise ExtensionError(f"{self.name}: no opening comment that says what the header declares")
        self.intro = self.comments[0].text
        generate = c_generator.CGenerator()
        self.items = [self._item(node, generate) for node in ast.ext if Path(node.coord.file).name == self.name]

    def _above(self, line):
        """The text of the block comment that ends on the line above ``line`` ('' if none)."""
        for comment in self.comments:
            if comment.last == line - 1 and not comment.trailing:
                return comment.text
        return ""

    def _beside(self, line):
        """The text of the comment that starts after code on ``line`` ('' if none)."""
        for comment in self.comments:
            if comment.first == line and comment.trailing:
                return " ".join(comment.text.split())
        return ""

    def _at(self, node):
        """The header and line of ``node``, for a warning."""
        return f"{self.path}:{node.coord.line}"

    def _item(self, node, generate):
        where = f"{self.name}:{node.coord.line}"
        if isinstance(node, c_ast.Typedef) and isinstance(node.type.type, c_ast.Enum):
            members = []
            for value in node.type.type.values.enumerators:
                text = value.name + (f" = {generate.visit(value.value)}" if value.value is not None else "")
                members.append((text, self._beside(value.coord.line)))
            return Item("enum", node.name, node.name, self._above(node.coord.line), members)
        if isinstance(node, c_ast.Typedef) and isinstance(node.type.type, c_ast.Struct):
            members = []
            for decl in node.type.type.decls:
                text = generate.visit(decl)
                comment = self._beside(decl.coord.line)
                if not comment:
                    logger.warning(f"field {node.name}.{decl.name} has no comment", location=self._at(decl))
                elif text.startswith("float ") and not UNIT.search(comment):
                    logger.warning(f"field {node.name}.{decl.name}: no [unit] in its comment", location=self._at(decl))
                members.append((text, comment))
            return Item("struct", node.name, node.name, self._above(node.coord.line), members)
        if isinstance(node, c_ast.Typedef) and isinstance(getattr(node.type, "type", None), c_ast.FuncDecl):
            # a callback type: its name, then its comment and, as a formula line, its declaration
            comment = self._above(node.coord.line)
            if not comment:
                logger.warning(f"type {node.name} has no comment above it", location=self._at(node))
            return Item("type", node.name, node.name, f"{comment}\n  {generate.visit(node)}")
        if isinstance(node, c_ast.Decl) and isinstance(node.type, c_ast.FuncDecl):
            comment = self._above(node.coord.line)
            if not comment:
                logger.warning(f"function {node.name} has no comment above it", location=self._at(node))
            return Item("function", node.name, generate.visit(node), comment)
        raise ExtensionError(f"{where}: a declaration of a kind the C API page does not document")


def check_against_extension(headers):
    """Fail if the structs and functions read here are not those the compiled extension declares."""
    from pmsm2dof.core.bindings import ffi, lib

    for header in headers:
        for item in header.items:
            if item.kind == "struct":
                compiled = [name for name, _ in ffi.typeof(item.name).fields]
                read = [re.match(r".*?(\w+)(\[\d+\])?$", text).group(1) for text, _ in item.members]
                if compiled != read:
                    raise ExtensionError(f"{header.name}: {item.name} fields {read} != compiled {compiled}")
            if item.kind == "function" and not hasattr(lib, item.name):
                raise ExtensionError(f"{header.name}: {item.name} is not in pmsm2dof._core")


def escape(text):
    """``text`` as reStructuredText that shows every character as written (a C comment is no markup)."""
    return re.sub(r"([\\*`|_\[\]<>])", r"\\\1", text)


def rst_text(comment):
    """A comment as reStructuredText: its lines as paragraphs, its indented lines (formulas) as literal blocks."""
    lines = []
    in_formula = False
    for line in comment.splitlines():
        formula = line.startswith(" ")
        if formula and not in_formula:
            lines += ["", "::", ""]
        elif not formula and in_formula:
            lines += [""]
        lines.append("   " + line if formula else escape(line))
        in_formula = formula
    return "\n".join(lines)


def indent(text, spaces):
    return [" " * spaces + line if line.strip() else "" for line in text.splitlines()]


def rst_of(header):
    """The reStructuredText of one header's section."""
    lines = [f"``{header.name}``", "-" * (len(header.name) + 4), "", ".. code-block:: text", ""]
    lines += indent(header.intro, 3) + [""]
    directive = {"enum": "c:enum", "struct": "c:struct", "function": "c:function", "type": "c:type"}
    member = {"enum": "c:enumerator", "struct": "c:member"}
    for item in header.items:
        lines += [f".. {directive[item.kind]}:: {item.declaration}", ""]
        if item.comment:
            lines += indent(rst_text(item.comment), 3) + [""]
        for declaration, comment in item.members:
            lines += [f"   .. {member[item.kind]}:: {declaration}", ""]
            if comment:
                lines += indent(escape(comment), 6) + [""]
    return lines


class CHeaders(SphinxDirective):
    """``.. c-headers::``: a section per public header, every declaration with its comment."""

    has_content = False

    def run(self):
        paths = public_headers()
        for path in paths:
            self.env.note_dependency(str(path))
        ast = parse_headers(paths)
        headers = [Header(path, ast) for path in sorted(paths)]
        check_against_extension(headers)
        lines = []
        for header in headers:
            lines += rst_of(header) + [""]
        container = nodes.section()
        container.document = self.state.document
        nested_parse_with_titles(self.state, StringList(lines, source=str(HEADERS)), container)
        return container.children


def setup(app):
    app.add_directive("c-headers", CHeaders)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
