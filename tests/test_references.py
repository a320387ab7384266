"""Every reference in the docstrings and documents names something that exists.

What counts as a reference (the grammar; everything else is prose and is not read):

In the docstrings (module, class and function docstrings, read with :mod:`ast`) of every Python
file the repository tracks:

- a Sphinx role ``:R:`TARGET``` with R one of ``mod func class meth attr data exc obj const``,
  TARGET optionally written ``~TARGET`` or ``text <TARGET>`` and ending in ``()``;
- a double-backticked literal that is a *rooted* dotted name (below), such as
  ````harness.cosim.master.Loop````.

In the Markdown documents (README.md, docs/*.md and each folder's README.md), outside fenced
code blocks:

- a relative link or image ``[text](PATH)`` or ``[text](PATH#anchor)`` (no URL scheme): PATH
  exists relative to the document and, where PATH is a Markdown file, the anchor is one of its
  headings (GitHub's slugs); an anchor alone (``(#anchor)``) is a heading of the document itself;
- a code span ```` `NAME` ```` that is a rooted dotted name;
- a code span that is a repository path: a tracked top-level folder, ``/`` and more path
  (letters, digits, ``_ - . /``), such as ```` `models/linear.py` ````; it exists in the checkout.

A *rooted* dotted name starts with ``dronefly.`` or with one of the package's sub-packages
(``models.``, ``harness.``, ...: the top-level folders with an ``__init__.py``) and continues with
identifiers separated by dots. Three kinds are file names, placeholders or FMU variables, not
references: a name whose last part is a file suffix (``controller.ssv``, ``.png``); a name whose
last part is a metavariable of the CLI's help (``controller.NAME``); and, as the harness names
its controller FMU's instance ``controller``, a two-part ``controller.X`` where X is no module
of the package ``controller`` (``controller.saturated``, as ``plant.n``). A role's
target is not unwrapped: a target split across lines is broken for Sphinx too. A relative
name (``.timing``, ``..values.PAPER``) is read only inside a role, where Sphinx reads it the
same way.

How a name resolves:

- rooted or relative (relative to the docstring's module, as a relative import would be): the
  longest prefix that imports as a module, then each further part as an attribute; an attribute
  of a class is also found among its annotations (dataclass fields) and its ``self.NAME = ``
  assignments;
- any other name in a role, e.g. :func:`run_sweep`, :meth:`angles` or :mod:`numpy.linalg`: a name
  the module defines or imports, a member of one of its classes (first the enclosing class's),
  then, as Sphinx looks names up across a project, a name that any module of the package defines
  at top level or in a class, an importable module (``numpy.linalg``) or a builtin.

A reference that does not resolve fails the test with its file, line and text.
"""

from __future__ import annotations

import ast
import builtins
import importlib
import inspect
import re
import subprocess
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "dronefly"

#: the sub-packages a rooted name may start with (besides ``dronefly``)
SUBPACKAGES = tuple(sorted(p.parent.name for p in ROOT.glob("*/__init__.py")))
#: a name ending in one of these is a file name (``controller.ssv``, ``.png``), not a reference
FILE_SUFFIXES = frozenset(
    "png csv json fmu ssp ssv ssd ssm xml md py pyc so dll dylib exe txt zip c h toml cfg opt "
    "part ini log html svg pdf gz tar whl".split())
#: metavariables of the CLI's help: ``controller.NAME`` is a placeholder, not a reference
PLACEHOLDERS = frozenset({"NAME", "VALUE"})
_ROLES = "mod|func|class|meth|attr|data|exc|obj|const"
_ROLE = re.compile(r":(?:py:)?(?:" + _ROLES + r"):`(?P<body>[^`]+)`")
_DOTTED = r"[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*)*"
_ROOTED = re.compile(r"(?:dronefly|" + "|".join(SUBPACKAGES) + r")\." + _DOTTED)
_RELATIVE = re.compile(r"\.{1,3}" + _DOTTED)
_LITERAL = re.compile(r"``(?P<body>[^`]+)``")
_SPAN = re.compile(r"(?<!`)`(?P<body>[^`\n]+)`(?!`)")
_LINK = re.compile(r"!?\[[^\]\n]*\]\((?P<target>[^)\s]+)\)")
_FENCE = re.compile(r"^```.*?^```$", re.M | re.S)
_HEADING = re.compile(r"^#{1,6}\s+(?P<title>.+?)\s*#*$", re.M)


@dataclass(frozen=True)
class Ref:
    """One reference: where it stands and what it names."""

    file: str
    line: int
    text: str
    #: the docstring's module (``dronefly.harness.cosim.master``), or "" in a document
    module: str = ""
    #: the class whose docstring (or method's docstring) holds it, or ""
    cls: str = ""


def _tracked(pattern: str) -> list[Path]:
    out = subprocess.run(["git", "ls-files", pattern], cwd=ROOT, capture_output=True, text=True,
                         check=True).stdout.split()
    return [ROOT / p for p in out]


def _module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = [PACKAGE, *rel.parts]
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _is_placeholder_or_file(name: str) -> bool:
    parts = name.split(".")
    if parts[-1] in FILE_SUFFIXES or parts[-1] in PLACEHOLDERS:
        return True
    # ``controller.saturated``: a variable of the FMU instance ``controller``
    return len(parts) == 2 and parts[0] == "controller" \
        and not (ROOT / "controller" / f"{parts[1]}.py").is_file() \
        and not (ROOT / "controller" / parts[1] / "__init__.py").is_file()


def _docstrings(tree: ast.Module) -> list[tuple[ast.AST, str, str]]:
    """(node, enclosing class name, docstring) of the module and every class and function."""
    out: list[tuple[ast.AST, str, str]] = []

    def visit(node: ast.AST, cls: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                inner = child.name if isinstance(child, ast.ClassDef) else cls
                doc = ast.get_docstring(child, clean=False)
                if doc:
                    out.append((child, inner, doc))
                visit(child, inner)

    doc = ast.get_docstring(tree, clean=False)
    if doc:
        out.append((tree, "", doc))
    visit(tree, "")
    return out


def _doc_line(node: ast.AST, doc: str, offset: int) -> int:
    body = getattr(node, "body", [])
    first = body[0].lineno if body and isinstance(body[0], ast.Expr) else 1
    return first + doc.count("\n", 0, offset)


def docstring_references(path: Path) -> list[Ref]:
    """The references in ``path``'s docstrings (see the module text for the grammar)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    module, rel = _module_name(path), str(path.relative_to(ROOT))
    refs = []
    for node, cls, doc in _docstrings(tree):
        for m in _ROLE.finditer(doc):
            body = m.group("body").strip()
            if "<" in body and body.endswith(">"):
                body = body[body.rindex("<") + 1:-1]
            body = body.lstrip("~!").removesuffix("()")
            if _is_placeholder_or_file(body):
                continue
            refs.append(Ref(rel, _doc_line(node, doc, m.start()), body, module, cls))
        for m in _LITERAL.finditer(doc):
            body = m.group("body").removesuffix("()")
            if _ROOTED.fullmatch(body) and not _is_placeholder_or_file(body):
                refs.append(Ref(rel, _doc_line(node, doc, m.start()), body, module, cls))
    return refs


def document_references(path: Path) -> list[Ref]:
    """The links, rooted names and repository paths of a Markdown document (module text)."""
    text = _FENCE.sub(lambda m: "\n" * m.group(0).count("\n"), path.read_text(encoding="utf-8"))
    rel = str(path.relative_to(ROOT))
    refs = []
    for m in _LINK.finditer(text):
        target = m.group("target")
        if re.match(r"[a-z][a-z0-9+.-]*:", target):  # a URL (https:, mailto:)
            continue
        refs.append(Ref(rel, text.count("\n", 0, m.start()) + 1, "link:" + target))
    for m in _SPAN.finditer(text):
        body = m.group("body").removesuffix("()")
        line = text.count("\n", 0, m.start()) + 1
        if _ROOTED.fullmatch(body) and not _is_placeholder_or_file(body):
            refs.append(Ref(rel, line, body))
        elif re.fullmatch(r"(?:" + "|".join(_top_folders()) + r")/[A-Za-z0-9_./-]*", body):
            refs.append(Ref(rel, line, "path:" + body))
    return refs


@lru_cache(maxsize=None)
def _top_folders() -> tuple[str, ...]:
    """The tracked top-level folders (``models``, ``docs``, ``benchmarks``, ...)."""
    out = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True,
                         check=True).stdout.split()
    return tuple(sorted({p.split("/", 1)[0] for p in out if "/" in p and not p.startswith(".")}))


@lru_cache(maxsize=None)
def _class_members(cls: type) -> frozenset[str]:
    """Names a class's instances have that ``hasattr`` on the class cannot see: annotations
    (dataclass fields without a default) and ``self.NAME = `` assignments in its methods."""
    names: set[str] = set()
    for klass in cls.__mro__:
        names.update(getattr(klass, "__annotations__", {}))
        try:
            source = inspect.getsource(klass)
        except (OSError, TypeError):
            continue
        names.update(re.findall(r"self\.([A-Za-z_][A-Za-z0-9_]*)\s*(?::[^=\n]*)?=(?!=)", source))
    return frozenset(names)


def _has(obj: Any, name: str) -> tuple[bool, Any]:
    if hasattr(obj, name):
        return True, getattr(obj, name)
    if isinstance(obj, type) and name in _class_members(obj):
        return True, None
    return False, None


def resolve_dotted(name: str) -> bool:
    """Whether the absolute dotted ``name`` is a module or an attribute chain under one."""
    parts = name.split(".")
    for k in range(len(parts), 0, -1):
        try:
            obj: Any = importlib.import_module(".".join(parts[:k]))
        except ImportError:
            continue
        for attr in parts[k:]:
            if obj is None:  # an instance attribute: nothing further to look into
                return False
            ok, obj = _has(obj, attr)
            if not ok:
                return False
        return True
    return False


@lru_cache(maxsize=None)
def _module_names(module: str) -> tuple[frozenset[str], dict[str, frozenset[str]]]:
    """The names ``module`` defines or imports at top level, and each class's members."""
    path = ROOT.joinpath(*module.split(".")[1:])
    path = path / "__init__.py" if path.is_dir() else path.with_suffix(".py")
    tree = ast.parse(path.read_text(encoding="utf-8"))
    top: set[str] = set()
    classes: dict[str, frozenset[str]] = {}

    def targets(node: ast.AST) -> list[str]:
        if isinstance(node, ast.Name):
            return [node.id]
        if isinstance(node, (ast.Tuple, ast.List)):
            return [n for e in node.elts for n in targets(e)]
        return []

    def bound(stmt: ast.stmt) -> list[str]:
        if isinstance(stmt, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            return [stmt.name]
        if isinstance(stmt, ast.Assign):
            return [n for t in stmt.targets for n in targets(t)]
        if isinstance(stmt, (ast.AnnAssign, ast.AugAssign)):
            return targets(stmt.target)
        if isinstance(stmt, (ast.Import, ast.ImportFrom)):
            return [(a.asname or a.name).split(".")[0] for a in stmt.names]
        if isinstance(stmt, (ast.If, ast.Try)):
            inner = [*stmt.body, *stmt.orelse, *getattr(stmt, "finalbody", [])]
            inner += [s for h in getattr(stmt, "handlers", []) for s in h.body]
            return [n for s in inner for n in bound(s)]
        return []

    for stmt in tree.body:
        top.update(bound(stmt))
    for node in ast.walk(tree):
        if isinstance(node, ast.ClassDef):
            members = {n for s in node.body for n in bound(s)}
            members.update(a.target.id for a in ast.walk(node) if isinstance(a, ast.AnnAssign)
                           and isinstance(a.target, ast.Name))
            members.update(t.attr for a in ast.walk(node) if isinstance(a, ast.Assign)
                           for t in a.targets if isinstance(t, ast.Attribute)
                           and isinstance(t.value, ast.Name) and t.value.id == "self")
            classes[node.name] = frozenset(members)
    return frozenset(top), classes


@lru_cache(maxsize=None)
def _package_names() -> frozenset[str]:
    """Every name a module of the package defines at top level or in a class."""
    names: set[str] = set()
    for path in _tracked("*.py"):
        module = _module_name(path)
        top, classes = _module_names(module)
        names.update(top)
        for members in classes.values():
            names.update(members)
    return frozenset(names)


def _absolute(ref: Ref) -> str | None:
    """The absolute dotted name of a rooted or relative reference, or None for a bare one."""
    text = ref.text
    if text.startswith(PACKAGE + "."):
        return text
    if _ROOTED.fullmatch(text):
        return f"{PACKAGE}.{text}"
    if text.startswith("."):
        level = len(text) - len(text.lstrip("."))
        is_package = ROOT.joinpath(*ref.module.split(".")[1:], "__init__.py").is_file() \
            or ref.module == PACKAGE
        base = ref.module.split(".")
        if not is_package:
            base = base[:-1]
        base = base[:len(base) - (level - 1)] if level > 1 else base
        return ".".join([*base, text.lstrip(".")])
    return None


def resolves(ref: Ref) -> bool:
    """Whether ``ref`` names something that exists (see the module text)."""
    if ref.text.startswith("link:"):
        return _link_resolves(ref)
    if ref.text.startswith("path:"):
        return (ROOT / ref.text[5:]).exists()
    absolute = _absolute(ref)
    if absolute is not None:
        return resolve_dotted(absolute)
    head, _, rest = ref.text.partition(".")
    top, classes = _module_names(ref.module)
    if not rest:
        if head in top or head in classes.get(ref.cls, ()):
            return True
        if any(head in members for members in classes.values()):
            return True
        if head in _package_names() or hasattr(builtins, head):
            return True
    elif head in classes and rest.count(".") == 0:
        return rest in classes[head] or resolve_dotted(f"{ref.module}.{ref.text}")
    elif head in top:
        return resolve_dotted(f"{ref.module}.{ref.text}") or resolve_dotted(ref.text)
    elif head in classes.get(ref.cls, ()):
        return resolve_dotted(f"{ref.module}.{ref.cls}.{ref.text}")
    return resolve_dotted(ref.text)


def _slug(title: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    title = re.sub(r"`|\*\*|\*", "", title.strip().lower())
    return re.sub(r"[^\w\- ]", "", title).replace(" ", "-")


def _link_resolves(ref: Ref) -> bool:
    target = ref.text[5:]
    where, _, anchor = target.partition("#")
    doc = ROOT / ref.file
    path = (doc.parent / where).resolve() if where else doc
    if not path.exists():
        return False
    if anchor and path.suffix == ".md":
        text = _FENCE.sub("", path.read_text(encoding="utf-8"))
        return anchor in {_slug(m.group("title")) for m in _HEADING.finditer(text)}
    return True


def all_references() -> list[Ref]:
    refs = [r for p in _tracked("*.py") for r in docstring_references(p)]
    docs = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")),
            *sorted(ROOT.glob("*/README.md")), *sorted(ROOT.glob("*/*/README.md"))]
    refs += [r for p in docs for r in document_references(p)]
    return refs


def test_every_reference_resolves() -> None:
    refs = all_references()
    # the grammar finds the references it was written for (a matcher that finds nothing passes
    # vacuously): roles, rooted literals, links and paths of the documents
    assert sum(r.text.startswith("link:") for r in refs) > 20
    assert sum(r.text.startswith("path:") for r in refs) > 20
    assert sum(r.module != "" for r in refs) > 200
    broken = [f"{r.file}:{r.line}: {r.text}" for r in refs if not resolves(r)]
    assert not broken, f"{len(broken)} references name nothing:\n" + "\n".join(broken)


@pytest.mark.parametrize("text, module, cls, ok", [
    # relative to the module, as a relative import: a sibling, a parent's module, a name in it
    (".master.Loop", "dronefly.harness.cosim.system", "", True),
    ("..cosim.master.Loop", "dronefly.harness.stability.run", "", True),
    (".master", "dronefly.harness.cosim", "", True),
    (".timing.grid_simulate", "dronefly.harness.cosim.system", "", False),
    (".master.NoSuchLoop", "dronefly.harness.cosim.system", "", False),
    # rooted, with and without the package's name; a dataclass field of a class
    ("dronefly.harness.cosim.master.Loop", "dronefly.harness.cosim.system", "", True),
    ("harness.cosim.master.Loop", "dronefly.harness.cosim.system", "", True),
    ("harness.cosim.master.run", "dronefly.harness.cosim.system", "", False),
    # bare: defined or imported by the module, a member of its class, a builtin, another library
    ("Loop", "dronefly.harness.cosim.master", "", True),
    ("NoSuchName", "dronefly.harness.cosim.master", "", False),
    ("ValueError", "dronefly.harness.cosim.master", "", True),
    ("numpy.linalg.eig", "dronefly.harness.cosim.master", "", True),
    ("numpy.linalg.no_such", "dronefly.harness.cosim.master", "", False),
])
def test_resolution(text: str, module: str, cls: str, ok: bool) -> None:
    """The resolver accepts what exists and refuses what does not, for each kind of name."""
    assert resolves(Ref("x.py", 1, text, module, cls)) is ok


def test_grammar_reads_references_not_prose(tmp_path: Path) -> None:
    """Roles and rooted literals are read; suffixes, placeholders and prose are not."""
    source = tmp_path / "m.py"
    source.write_text('"""See :func:`.timing.grid_simulate`, :class:`~.master.Loop`,\n'
                      ':meth:`text <Loop.run>`, ``harness.cosim.master.Loop`` and\n'
                      '``controller.NAME``, ``.png``, ``controller.ssv``,\n'
                      '``controller.saturated``, ``controller.timing``, e.g. the model.\n"""\n',
                      encoding="utf-8")
    found = [(r.text, r.line) for r in docstring_references(_AsIfIn(source))]
    assert found == [(".timing.grid_simulate", 1), (".master.Loop", 1), ("Loop.run", 2),
                     ("harness.cosim.master.Loop", 2), ("controller.timing", 4)]
    doc = tmp_path / "d.md"
    doc.write_text("A [link](d.md#title) and [bad](#nowhere), `models.linear`,\n"
                   "`models/linear.py`,\n"
                   "`controller.ssv`, `plant.NAME`, `e.g.` and\n```sh\n`harness.x`\n```\n# Title\n",
                   encoding="utf-8")
    found = [r.text for r in document_references(_AsIfIn(doc))]
    assert found == ["link:d.md#title", "link:#nowhere", "models.linear", "path:models/linear.py"]


class _AsIfIn(type(Path())):  # type: ignore[misc]
    """A scratch file read as if it stood at the checkout's root (for its relative name)."""

    def relative_to(self, *_: Any, **__: Any) -> Path:  # type: ignore[override]
        return Path(self.name)
