"""What a result measures, derived from the command that wrote it.

A result file records the ``command`` it was made with. The files that command runs are its
scripts (``python X.py``, ``python -m module``, ``python -m pytest tests/…``, ``rattlefit …``,
``jupyter execute X.ipynb``, ``.ci/run``), every repository module those scripts import,
directly or through others (found by reading their ``import`` statements, those inside
functions included, ``importlib.import_module("…")`` with a literal name, and, of a
package's table of names it imports on first use, ``_LAZY = {"name": ".module", …}``, the
modules of the names the importer uses: ``from pkg import name`` or ``pkg.name``; all of
them where it uses the package otherwise, e.g. ``getattr(pkg, …)``; and the command line's
modules where a file starts ``rattlefit`` in a process of its own), the
repository's files named on the command line (a bundled recording, a notebook), and
``constraints.txt`` (the versions of what they import from outside). Nothing is declared by
hand, so nothing can be forgotten.

    measured_paths(command) -> MeasuredPaths(paths, scripts, missing)

Standard library only.
"""

from __future__ import annotations

import ast
import functools
import json
import re
import shlex
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: Where a top-level name that is not beside its importer is looked for (a script's folder is
#: put on ``sys.path`` by Python, and tests and studies add these folders themselves).
SEARCH_DIRS = ("src", "benchmarks", "studies", "tests", ".")
#: What every result's environment pins: the versions of what it imports from outside.
ENVIRONMENT = ("constraints.txt",)
#: What ``.ci/run`` runs: the install, the lint and the whole test suite.
CI_PATHS = (".ci", "src", "tests", "notebooks", "data", "pyproject.toml", "constraints.txt")
#: Folders whose files are outputs, never what a result measures.
OUTPUT_DIRS = ("benchmarks/results", "studies/results", "studies/cache", "benchmarks/cache")
PYTHONS = re.compile(r"^(.*/)?python(3(\.\d+)?)?$")
SEPARATORS = re.compile(r"\s*(?:;|&&|\|\||\|)\s*")


@dataclass(frozen=True)
class MeasuredPaths:
    """``paths``: every repository path (relative, POSIX) the command's result depends on,
    sorted; ``scripts``: the scripts it runs; ``missing``: scripts it names that this tree does
    not have (a result whose script is gone cannot be re-measured as it was)."""

    paths: tuple[str, ...]
    scripts: tuple[str, ...]
    missing: tuple[str, ...]


@functools.cache
def measured_paths(command: str, root: Path = ROOT) -> MeasuredPaths:
    """The paths ``command`` (a shell line as a result file records it) depends on in the tree
    at ``root``: its scripts, their imports' closure, the repository files among its arguments
    and :data:`ENVIRONMENT`. Read once per process and command (cached)."""
    scripts, named, missing, whole = [], [], [], []
    for part in SEPARATORS.split(command.split(" #")[0].strip()):
        words = _words(part)
        found, args, gone, dirs = _scripts_of(words, root)
        scripts += found
        missing += gone
        whole += dirs
        named += [a for a in args if _repo_file(a, root)]
    paths = set(closure([root / s for s in scripts], root)) | set(whole) | set(ENVIRONMENT)
    paths |= {_repo_file(a, root) for a in named}
    return MeasuredPaths(tuple(sorted(paths)), tuple(sorted(set(scripts))), tuple(missing))


def _words(part: str) -> list[str]:
    """A shell command's words without leading ``NAME=value`` assignments."""
    try:
        words = shlex.split(part)
    except ValueError:
        words = part.split()
    while words and re.match(r"^[A-Za-z_][A-Za-z0-9_]*=", words[0]):
        words = words[1:]
    return words


def _scripts_of(words: list[str], root: Path):
    """(scripts in the tree, the other arguments, scripts named but absent, whole folders) of
    one simple command."""
    if not words:
        return [], [], [], []
    program, args = words[0], words[1:]
    if words[:1] == [".ci/run"] or words[:2] == ["bash", ".ci/run"]:
        return [], [], [], list(CI_PATHS)
    if program == "rattlefit":
        return [_module_file("rattlefit.cli", [root / "src"], root)], args, [], []
    if program == "jupyter":
        notebooks = [a for a in args if a.endswith(".ipynb")]
        return _present(notebooks, root), args, _absent(notebooks, root), []
    if not PYTHONS.match(program):
        return [], args, [], []
    if args[:2] == ["-m", "pytest"]:
        tests = [a.split("::")[0] for a in args[2:] if a.split("::")[0].startswith("tests")]
        tests = tests or ["tests"]
        files = [t for t in tests if (root / t).is_file()]
        files += [p.relative_to(root).as_posix() for t in tests if (root / t).is_dir()
                  for p in sorted((root / t).glob("*.py"))]  # fmt: skip
        return [*files, "tests/conftest.py"], args, _absent(tests, root), []
    if args[:1] == ["-m"] and len(args) > 1:
        module = _module_file(args[1], [root / d for d in SEARCH_DIRS], root)
        return ([module] if module else []), args[2:], ([] if module else [args[1]]), []
    script = next((a for a in args if a.endswith(".py")), None)
    if script is None:
        return [], args, [], []
    rest = [a for a in args if a != script]
    return _present([script], root), rest, _absent([script], root), []


def _present(paths, root: Path) -> list[str]:
    return [_repo_file(p, root) for p in paths if _repo_file(p, root)]


def _absent(paths, root: Path) -> list[str]:
    return [p for p in paths if not (Path(p) if Path(p).is_absolute() else root / p).exists()]


def _repo_file(arg: str, root: Path) -> str:
    """``arg`` as a path relative to ``root`` when it names a file of the tree outside the
    output folders, else ""."""
    path = Path(arg)
    path = path if path.is_absolute() else root / path
    try:
        rel = path.resolve().relative_to(root.resolve()).as_posix()
    except (ValueError, OSError):
        return ""
    if not path.is_file() or any(rel.startswith(d + "/") for d in OUTPUT_DIRS):
        return ""
    return rel


def closure(files, root: Path = ROOT) -> list[str]:
    """Every repository ``.py`` file (relative to ``root``) that ``files`` import, directly or
    through others, ``files`` included; a notebook's code cells are read as one module."""
    seen: set[str] = set()
    todo = [Path(f) for f in files]
    while todo:
        path = todo.pop()
        rel = path.resolve().relative_to(root.resolve()).as_posix()
        if rel in seen or not path.is_file():
            continue
        seen.add(rel)
        dirs = [path.parent] + [root / d for d in SEARCH_DIRS]
        for name in imported_names(path.resolve(), root):
            found = _module_file(name, dirs, root)
            if found:
                todo.append(root / found)
                table = lazy_table(root / found, root) if found.endswith("__init__.py") else {}
                for module in lazy_modules(path.resolve(), name, table):
                    todo += [root / f for f in [_module_file(module, dirs, root)] if f]
        if runs_the_command_line(path.resolve()):
            todo += [root / f for f in [_module_file("rattlefit.cli", [root / "src"], root)] if f]
    return sorted(seen)


@functools.cache
def runs_the_command_line(path: Path) -> bool:
    """Whether the file ``path`` starts the ``rattlefit`` command: it looks the program up
    (``….with_name("rattlefit")``, ``shutil.which("rattlefit")``) or lists
    ``"-m", "rattlefit"``."""
    try:
        tree = ast.parse(_source(path))
    except SyntaxError:
        return False
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and node.args:
            looks_up = getattr(node.func, "attr", getattr(node.func, "id", ""))
            if looks_up in ("with_name", "which") and _is_program(node.args[0]):
                return True
        if isinstance(node, ast.List | ast.Tuple):
            pairs = zip(node.elts, node.elts[1:], strict=False)
            if any(getattr(a, "value", None) == "-m" and _is_program(b) for a, b in pairs):
                return True
    return False


def _is_program(node) -> bool:
    return isinstance(node, ast.Constant) and node.value == "rattlefit"


@functools.cache
def lazy_table(init: Path, root: Path = ROOT) -> dict[str, str]:
    """A package's ``_LAZY`` table in its ``__init__.py`` ``init``: public name → the absolute
    dotted module that defines it ({} without one)."""
    for node in ast.walk(ast.parse(_source(init))):
        if isinstance(node, ast.Assign) and any(
            getattr(t, "id", "") == "_LAZY" for t in node.targets
        ):
            keys, values = getattr(node.value, "keys", []), getattr(node.value, "values", [])
            return {
                k.value: _relative(v.value, init, root)
                for k, v in zip(keys, values, strict=True)
                if isinstance(k, ast.Constant) and isinstance(v, ast.Constant)
            }
    return {}


def lazy_modules(path: Path, package: str, table: dict[str, str]) -> set[str]:
    """The modules of ``table`` (a package's ``_LAZY``) that the file ``path`` reaches through
    ``package``: those of the names it imports from it or reads as its attributes, and every
    one where it uses the package's name otherwise (``getattr(pkg, …)``, ``import *``)."""
    if not table:
        return set()
    tree = ast.parse(_source(path))
    used, aliases = set(), set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module == package and not node.level:
            used |= {a.name for a in node.names}
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name == package or a.name.startswith(package + "."):
                    aliases.add(a.asname or a.name.split(".")[0])
    bases = {id(n.value) for n in ast.walk(tree) if isinstance(n, ast.Attribute)}
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and getattr(node.value, "id", None) in aliases:
            used.add(node.attr)
        elif isinstance(node, ast.Name) and node.id in aliases and id(node) not in bases:
            if not isinstance(node.ctx, ast.Store):
                used |= set(table)  # the package passed on or read dynamically
    if "*" in used:
        used |= set(table)
    return {table[n] for n in used if n in table}


@functools.cache
def imported_names(path: Path, root: Path = ROOT) -> frozenset[str]:
    """The dotted names a file imports (every prefix of each, since importing ``a.b`` runs
    ``a``; ``from a import b`` also gives ``a.b``, which may be a module)."""
    source = _source(path)
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return frozenset()
    package = _package(path, root)
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = _absolute(node, package)
            names |= {base} | {f"{base}.{a.name}" for a in node.names if a.name != "*"}
        elif (
            isinstance(node, ast.Call)
            and getattr(node.func, "attr", getattr(node.func, "id", "")) == "import_module"
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and isinstance(node.args[0].value, str)
        ):
            names.add(node.args[0].value)
    return frozenset(
        ".".join(n.split(".")[: k + 1]) for n in names if n for k in range(n.count(".") + 1)
    )


def _relative(module: str, path: Path, root: Path) -> str:
    """The absolute dotted name of ``module`` (".x" relative to the package of ``path``, an
    ``__init__.py``)."""
    if not module.startswith("."):
        return module
    package = [*_package(path, root)]
    return ".".join([*package, module.lstrip(".")])


def _source(path: Path) -> str:
    text = path.read_text(encoding="utf-8", errors="replace")
    if path.suffix != ".ipynb":
        return text
    cells = json.loads(text).get("cells", [])
    code = ["".join(c.get("source", "")) for c in cells if c.get("cell_type") == "code"]
    lines = "\n".join(code).splitlines()
    return "\n".join(line for line in lines if not line.lstrip().startswith(("%", "!")))


def _package(path: Path, root: Path) -> list[str]:
    """The dotted package ``path`` lies in (for relative imports): its folders below ``src``."""
    try:
        parts = path.resolve().relative_to((root / "src").resolve()).parts
    except ValueError:
        return []
    return list(parts[:-1])


def _absolute(node: ast.ImportFrom, package: list[str]) -> str:
    if not node.level:
        return node.module or ""
    base = package[: len(package) - (node.level - 1)] if node.level > 1 else package
    return ".".join([*base, *([node.module] if node.module else [])])


def _module_file(name: str, dirs, root: Path) -> str:
    """The repository file of dotted module ``name`` (``a/b.py`` or ``a/b/__init__.py``) in the
    first of ``dirs`` that has it, relative to ``root``; "" for a module from outside."""
    parts = name.split(".")
    for d in dirs:
        for candidate in (Path(d, *parts).with_suffix(".py"), Path(d, *parts, "__init__.py")):
            if candidate.is_file():
                try:
                    return candidate.resolve().relative_to(root.resolve()).as_posix()
                except ValueError:
                    continue
    return ""
