"""The layout keeps its promises: the import rules of docs/architecture.md hold for every import statement
of the package (module level and inside functions), and no modules import each other in a ring.

The rules are parsed from the table of docs/architecture.md (one source of truth: edit a rule there and
this test checks the new one). The scan is static (ast), so an import that only runs in a rare branch is
checked as well as one at the top of a file.
"""

from __future__ import annotations

import ast
import fnmatch
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "pyfmu_wrapper"
DOC = ROOT / "docs" / "architecture.md"
PACKAGE = "pyfmu_wrapper"

# Import cycles that exist on main today and are being removed by helpers working in parallel. Each entry
# is the set of modules of one cycle (a strongly connected component of the import graph). THE LEAD
# EMPTIES THIS LIST as the branches merge: an entry whose cycle is gone fails the test as stale, so the
# list cannot outlive the cycles it excuses. A new cycle is never excused here: break it.
KNOWN_CYCLES: list[frozenset[str]] = []

# Imports that break a rule of docs/architecture.md today and are being removed in parallel, as
# (importing module, imported module). Emptied by the lead like KNOWN_CYCLES; a stale entry fails.
KNOWN_VIOLATIONS: list[tuple[str, str]] = []


# --- the import graph ----------------------------------------------------------------------------------


def _modules() -> dict[str, Path]:
    """Dotted module name relative to the package ('' is the package itself) -> file."""
    out = {}
    for p in sorted(PKG.rglob("*.py")):
        if "__pycache__" in p.parts:
            continue
        parts = list(p.relative_to(PKG).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = p
    return out


def _resolve(name: str, mods: dict) -> str | None:
    """The module a dotted name (relative to the package) refers to: itself, or its longest prefix that
    is a module (``physics.kernels.rhs`` -> ``physics.kernels``)."""
    while name not in mods:
        if "." not in name:
            return "" if name == "" else None
        name = name.rsplit(".", 1)[0]
    return name


def _type_checking_nodes(tree: ast.AST) -> set[int]:
    """ids of the nodes inside ``if TYPE_CHECKING:`` blocks (imports for annotations only)."""
    inside: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and (
            (isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING")
            or (isinstance(node.test, ast.Attribute) and node.test.attr == "TYPE_CHECKING")
        ):
            for stmt in node.body:
                inside.update(id(n) for n in ast.walk(stmt))
    return inside


#: a module of the package named by a string (``"pyfmu_wrapper.models.frame_model.cosim"``, or
#: ``"module:attribute"``): resolved at run time with import_module, it is an import all the same
_DOTTED = re.compile(r"^pyfmu_wrapper((?:\.[A-Za-z_]\w*)+)(?::[A-Za-z_][\w.]*)?$")


def _docstring_nodes(tree: ast.AST) -> set[int]:
    """ids of the docstrings' string constants (they name modules in prose, not to import them)."""
    out: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                out.add(id(first.value))
    return out


def _dotted_names(node: ast.AST, docstrings: set[int]) -> list[str]:
    """The package modules a string constant names (relative names), outside docstrings."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
        m = _DOTTED.match(node.value.strip())
        if m:
            return [m.group(1)[1:]]
    return []


def import_graph(runtime_only: bool = False) -> dict[str, set[str]]:
    """module -> the package modules it imports anywhere in its file (relative names), by an import
    statement or by a string that names one (a dotted name resolved at run time: :data:`_DOTTED`).

    runtime_only: leave out the imports under ``if TYPE_CHECKING:`` (never executed: they can form no
    import cycle, but the architecture's layer rules apply to them too)."""
    mods = _modules()
    graph: dict[str, set[str]] = {}
    for mod, path in mods.items():
        is_pkg = path.name == "__init__.py"
        found: set[str] = set()
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        skip = _type_checking_nodes(tree) if runtime_only else set()
        docstrings = _docstring_nodes(tree)
        for node in ast.walk(tree):
            if id(node) in skip:
                continue
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names if a.name == PACKAGE or a.name.startswith(PACKAGE + ".")]
                targets = [t[len(PACKAGE) + 1 :] for t in targets]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = mod.split(".") if mod else []
                    if not is_pkg:
                        base = base[:-1]
                    base = base[: len(base) - (node.level - 1)] if node.level > 1 else base
                    stem = ".".join(base + ([node.module] if node.module else []))
                elif node.module and (node.module == PACKAGE or node.module.startswith(PACKAGE + ".")):
                    stem = node.module[len(PACKAGE) + 1 :]
                else:
                    continue
                for alias in node.names:  # "from . import plots" names a module
                    sub = f"{stem}.{alias.name}" if stem else alias.name
                    targets.append(sub if sub in mods else stem)
            targets += _dotted_names(node, docstrings)
            for t in targets:
                r = _resolve(t, mods)
                assert r is not None, f"{path}: import of {t!r} resolves to no module of the package"
                if r != mod:
                    found.add(r)
        graph[mod] = found
    return graph


def cycles(graph: dict[str, set[str]]) -> list[frozenset[str]]:
    """The strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out = []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph.get(w, ())))))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = set()
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        comp.add(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        out.append(frozenset(comp))
    return out


# --- the rules of docs/architecture.md ----------------------------------------------------------------

_NAME = re.compile(r"`([^`]+)`")


def doc_rules() -> tuple[dict[str, set[str]], set[str]]:
    """(part -> parts it may import, shared parts every part may import), from the doc's table.

    A part is a folder (``physics/``) or a module file (``solvers/rodas.py``, ``_jit.py``, ``__init__.py``)."""
    text = DOC.read_text(encoding="utf-8")
    m = re.search(r"<!-- BEGIN import rules.*?-->\n(.*?)<!-- END import rules -->", text, re.S)
    assert m, "docs/architecture.md: the import rules table (between its BEGIN/END markers) is missing"
    rules: dict[str, set[str]] = {}
    shared: set[str] = set()
    for line in m.group(1).splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 3 or not cells[0].startswith("`"):
            continue
        part = _NAME.fullmatch(cells[0])
        assert part, f"docs/architecture.md: first cell {cells[0]!r} must be one backticked name"
        allowed = set(_NAME.findall(cells[2]))
        assert allowed or cells[2] == "nothing", (
            f"docs/architecture.md: row {part.group(1)}: 'may import' is {cells[2]!r}"
        )
        assert part.group(1) not in rules, f"docs/architecture.md: two rows for {part.group(1)}"
        rules[part.group(1)] = allowed
        if "every part may import it" in cells[1]:
            shared.add(part.group(1))
    return rules, shared


def _file_part(mod: str) -> str:
    """The module's own file as a part name: ``solvers.rodas`` -> ``solvers/rodas.py``."""
    path = _modules()[mod].relative_to(PKG).as_posix()
    return path


def _folder_part(mod: str) -> str:
    """The part a module belongs to: its top folder (``physics/``) or, at the top, its file."""
    top = mod.split(".")[0] if mod else ""
    return f"{top}/" if (PKG / top).is_dir() and top else _file_part(mod)


def _pattern_part(mod: str, rules: dict) -> str | None:
    """The pattern row (a name with ``*``: ``physics/*fmus/``, a folder at any depth whose name ends in
    ``fmus``) whose folder holds the module, if any: a layer inside a folder, governed by its own row."""
    f = _file_part(mod)
    for part in rules:
        if "*" in part and (fnmatch.fnmatch(f, part + "*") if part.endswith("/") else fnmatch.fnmatch(f, part)):
            return part
    return None


def _part_of(mod: str, rules: dict) -> str:
    """The most specific row that governs a module: its file's row if there is one, else the pattern row
    that holds it, else its folder's."""
    f = _file_part(mod)
    return f if f in rules else (_pattern_part(mod, rules) or _folder_part(mod))


def _may_import(src: str, dst: str, rules: dict, shared: set) -> bool:
    row = _part_of(src, rules)
    if _file_part(dst) in shared:
        return True
    pattern = _pattern_part(dst, rules)
    if pattern is not None:  # a layer inside a folder: only its own modules and the rows naming it reach it
        return row == pattern or bool({pattern, _file_part(dst)} & rules[row])
    targets = {_folder_part(dst), _file_part(dst)}
    if row == _folder_part(src) and _folder_part(dst) == row:
        return True  # within one folder (a module row, when there is one, is stricter)
    return bool(targets & rules[row])


# --- tests --------------------------------------------------------------------------------------------


def test_the_scan_sees_function_local_and_relative_imports():
    """The scanner itself, against imports known to exist in the package: a relative import, a relative
    module import (``from . import x``) and one inside a function."""
    g = import_graph()
    assert "physics.params" in g["physics.kernels"]  # from .params import ...
    assert "scenario.plots" in g["scenario.output"]  # from . import plots
    assert "scenario.engines" in g["paper.claims.sect5"]  # inside a claim function
    assert "solvers.frequency_response" in g["solvers.start"]  # inside initial_guess
    # a module named by a string (resolved at run time) is an import too, a docstring naming one is not
    tree = ast.parse('"""See pyfmu_wrapper.cosim.steady."""\nX = "pyfmu_wrapper.cosim.steady:sweep"\n')
    docs = _docstring_nodes(tree)
    assert [n for node in ast.walk(tree) for n in _dotted_names(node, docs)] == ["cosim.steady"]
    # the imports under `if TYPE_CHECKING:` can be told apart (runtime_only)
    tree = ast.parse("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .a import B\nfrom .c import D\n")
    skipped = _type_checking_nodes(tree)
    kept = [n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and id(n) not in skipped]
    assert kept == ["typing", "c"]
    # and Tarjan finds a planted ring, not a chain
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [frozenset("abc")]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycle():
    """No circle, counting the imports under ``if TYPE_CHECKING:`` too: a split-off helper that imports
    its facade's type for annotations still depends on it (take a Protocol instead: master/state.py)."""
    found = set(cycles(import_graph(runtime_only=False)))
    known = set(KNOWN_CYCLES)
    new = sorted(sorted(c) for c in found - known)
    assert not new, f"import cycles (modules that import each other, directly or in a ring): {new}"
    stale = sorted(sorted(c) for c in known - found)
    assert not stale, f"KNOWN_CYCLES lists cycles that no longer exist: remove {stale}"


def test_every_part_has_a_row_in_the_architecture_map():
    rules, _ = doc_rules()
    parts = {_folder_part(m) for m in _modules()}
    missing = sorted(parts - set(rules))
    assert not missing, f"docs/architecture.md has no row for {missing}: add one (what it holds, what it may import)"
    # every row names something that exists, and every part it allows exists
    for part, allowed in rules.items():
        for name in {part} | allowed:
            if "*" in name:  # a pattern row: some module lies below it
                pattern = name + "*" if name.endswith("/") else name
                exists = any(fnmatch.fnmatch(_file_part(m), pattern) for m in _modules())
            else:
                exists = (PKG / name.rstrip("/")).exists()
            assert exists, f"docs/architecture.md names {name}, which does not exist"


def test_imports_follow_the_rules_of_the_architecture_map():
    rules, shared = doc_rules()
    graph = import_graph()
    bad = []
    for src in sorted(graph):
        for dst in sorted(graph[src]):
            if not _may_import(src, dst, rules, shared) and (src, dst) not in KNOWN_VIOLATIONS:
                bad.append(
                    f"{src} imports {dst} ({_part_of(src, rules)} may import: "
                    f"{', '.join(sorted(rules[_part_of(src, rules)])) or 'nothing'})"
                )
    assert not bad, "imports against docs/architecture.md:\n  " + "\n  ".join(bad)
    stale = [v for v in KNOWN_VIOLATIONS if v[1] not in graph.get(v[0], set())]
    assert not stale, f"KNOWN_VIOLATIONS lists imports that no longer exist: remove {stale}"


@pytest.mark.parametrize(
    "src, dst, ok",
    [
        ("physics.kernels", "_jit", True),
        ("physics.kernels", "solvers.rodas", False),  # physics imports nothing of the project
        ("solvers.rodas", "physics.kernels", False),  # the integrator knows no model
        ("solvers.monolithic", "physics.models", True),
        ("master.master", "cosim.system", False),  # the master imports nothing of the application
        ("scenario.loader", "errors", True),  # the bottom of the bad-input policy
        ("scenario.loader", "cli.errors", False),  # nothing imports up into cli/
        ("cosim.steady", "scenario.engines", False),  # no arrow runs back up
        # a model's folder sits above the engines it plugs into ...
        ("models.frame_model.fmus.slave", "fmi.slave", True),
        ("models.frame_model.fmus.step", "models.frame_model.equations", True),
        ("models.frame_model.cosim", "cosim.periods", True),
        ("models.frame_model", "solvers.monolithic", True),
        ("models.base_tmd", "physics.tmd", True),
        # ... and nothing below reaches it: the engines take a unit as an argument
        ("solvers.monolithic", "models", False),
        ("fmi.varspec", "models.base_tmd.fmus.variables", False),
        ("fmubuild.native_build", "models.frame_model.fmus.native", False),
        ("fmubuild.build", "models.catalog", False),  # the builders take the FMUs they build
        ("cli.build_fmus", "models.catalog", True),
        ("models.catalog", "fmi.trivial", True),
        ("cosim.steady", "models.frame_model.cosim", False),
        ("physics.unit", "models", False),
        ("scenario.engines", "models", True),
    ],
)
def test_the_rules_bite(src, dst, ok):
    """The rule check on planted edges: what the map forbids is refused, what it allows passes."""
    rules, shared = doc_rules()
    assert _may_import(src, dst, rules, shared) is ok


def test_layer_rules_stated_in_words():
    """The map states the key rules in words as well as in the table."""
    text = DOC.read_text(encoding="utf-8")
    for phrase in (
        "physics imports nothing of the project",
        "the integrator\nknows no model",
        "the master imports nothing of the application",
    ):
        assert phrase.replace("\n", " ") in text.replace("\n", " "), phrase


# --- private names stay in their module -----------------------------------------------------------------

#: imports of a private name across modules that exist on main today and are being removed as the
#: branches merge (module, imported module, name); emptied by the lead like KNOWN_CYCLES (a stale entry fails)
KNOWN_PRIVATE_IMPORTS: set[tuple[str, str, str]] = set()


def private_imports() -> set[tuple[str, str, str]]:
    """(module, imported module, name) of every import of a name with one leading underscore from
    another module of the package."""
    out = set()
    mods = _modules()
    for m, path in mods.items():
        pkg = m if path.name == "__init__.py" else m.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.ImportFrom):
                continue
            if node.level:
                base = pkg.split(".") if pkg else []
                base = base[: len(base) - (node.level - 1)] if node.level > 1 else base
                target = ".".join([*base, *((node.module or "").split(".") if node.module else [])])
            elif (node.module or "").startswith(PACKAGE + "."):
                target = node.module[len(PACKAGE) + 1 :]
            else:
                continue
            for a in node.names:
                if a.name.startswith("_") and not a.name.startswith("__"):
                    out.add((m, target, a.name))
    return out


def test_no_private_name_imported_across_modules():
    found = private_imports()
    new = sorted(found - KNOWN_PRIVATE_IMPORTS)
    assert not new, f"private names imported from another module (make them public, or move the code): {new}"
    stale = sorted(KNOWN_PRIVATE_IMPORTS - found)
    assert not stale, f"KNOWN_PRIVATE_IMPORTS lists imports that no longer exist: remove {stale}"


# --- one job per module --------------------------------------------------------------------------------


def test_every_module_says_its_job():
    """No line cap (a cap chops modules instead of splitting them by job): every module opens with a
    docstring whose first sentence says the one job it does, which is what a review holds it to."""
    silent = {}
    for m, p in _modules().items():
        doc = ast.get_docstring(ast.parse(p.read_text(encoding="utf-8")))
        first = (doc or "").strip().split("\n\n")[0]
        if len(first) < 20:
            silent[m or PACKAGE] = first
    assert not silent, f"modules without a docstring that says their job: {silent}"
