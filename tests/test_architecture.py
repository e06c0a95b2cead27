"""The package's structure: no import cycle between its modules."""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"


def module_names() -> dict[str, Path]:
    out = {}
    for path in (SRC / "rattlefit").rglob("*.py"):
        parts = path.relative_to(SRC).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


def type_checking_nodes(tree: ast.AST) -> set[int]:
    """The ids of nodes inside ``if TYPE_CHECKING:`` blocks (imports for annotations only)."""
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skip |= {id(n) for stmt in node.body for n in ast.walk(stmt)}
    return skip


def imports_of(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The package's modules that ``name`` imports at run time (anywhere in the file)."""
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    skip = type_checking_nodes(tree)
    found = set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name in modules}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(parts + ([node.module] if node.module else []))
            subs = {f"{base}.{a.name}" for a in node.names} & modules.keys()
            # "from pkg import submodule" imports the submodule, and the package only for
            # the names that are not submodules
            if subs:
                found |= subs
            if len(subs) < len(node.names) and base in modules:
                found.add(base)
    return found - {name}


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state, stack = {}, []

    def visit(u):
        state[u] = 1
        stack.append(u)
        for v in sorted(graph[u]):
            if state.get(v) == 1:
                return [*stack[stack.index(v) :], v]
            if v not in state and (cycle := visit(v)):
                return cycle
        stack.pop()
        state[u] = 2
        return None

    for u in sorted(graph):
        if u not in state and (cycle := visit(u)):
            return cycle
    return None


def test_no_module_imports_itself_through_others():
    modules = module_names()
    graph = {m: imports_of(m, p, modules) for m, p in modules.items()}
    # the detector sees a cycle made on purpose
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    cycle = find_cycle(graph)
    assert cycle is None, " → ".join(cycle)


def package_of(module: str) -> str:
    """``rattlefit.inference.profile.stage`` → ``rattlefit.inference``."""
    return ".".join(module.split(".")[:2])


def test_no_package_imports_itself_through_others():
    """The packages form layers: no package reaches back into one that imports it (the
    likelihoods and the inference meet at :mod:`rattlefit.problem`, below both)."""
    modules = module_names()
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        if name.count(".") == 0:
            continue
        deps = {package_of(m) for m in imports_of(name, path, modules) if m.count(".")}
        graph.setdefault(package_of(name), set()).update(deps - {package_of(name)})
    cycle = find_cycle(graph)
    assert cycle is None, " → ".join(cycle)


#: Which layers a package may not import: recordings are read without any analysis, the
#: report only draws (what it shows is computed by the layers below it), and a diagnosis
#: decides without wording (its words are the report's).
FORBIDDEN = {
    "rattlefit.io": ("rattlefit.features", "rattlefit.simulation", "rattlefit.inference",
                     "rattlefit.diagnosis", "rattlefit.report", "rattlefit.likelihood"),
    "rattlefit.report": ("rattlefit.simulation",),
    "rattlefit.diagnosis": ("rattlefit.report",),
    "rattlefit.likelihood": ("rattlefit.inference", "rattlefit.diagnosis", "rattlefit.report",
                             "rattlefit.campaign", "rattlefit.cli"),
    "rattlefit.problem": ("rattlefit.likelihood", "rattlefit.inference", "rattlefit.diagnosis",
                          "rattlefit.report", "rattlefit.campaign", "rattlefit.cli"),
    "rattlefit.rig": ("rattlefit.simulation", "rattlefit.inference", "rattlefit.diagnosis",
                      "rattlefit.report", "rattlefit.likelihood", "rattlefit.campaign"),
}  # fmt: skip


def test_layers_import_only_downwards():
    modules = module_names()
    wrong = []
    for name, path in modules.items():
        for layer, banned in FORBIDDEN.items():
            if name == layer or name.startswith(layer + "."):
                hits = [m for m in imports_of(name, path, modules) if m.startswith(banned)]
                wrong += [f"{name} imports {m}" for m in hits]
    assert not wrong, "\n".join(wrong)


#: Calls that simulate: the report is handed what they give, never calls them.
SIMULATING = {"simulate", "simulate_batch", "synthesize", "predictive_features",
              "fitted_realisations", "evaluate"}  # fmt: skip


def test_the_report_simulates_nothing():
    wrong = []
    for path in sorted((SRC / "rattlefit" / "report").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call):
                f = node.func
                name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")
                if name in SIMULATING:
                    wrong.append(f"{path.name}:{node.lineno} calls {name}")
    assert not wrong, "\n".join(wrong)
