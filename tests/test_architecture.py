"""The package's shape, checked: imports run one way, formats are asked, not named.

Reads the source with :mod:`ast`; nothing is imported or run.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

from splatconv.formats import REGISTRY

PACKAGE = Path(__file__).resolve().parent.parent / "splatconv"
#: Imports allowed inside functions: moderngl is loaded only when something is drawn.
LAZY_ALLOWED = {"moderngl"}


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict:
    return {_module_name(p): p for p in PACKAGE.rglob("*.py")}


def _resolve(module: str, path: Path, node: ast.ImportFrom) -> list:
    """Absolute names a ``from ... import ...`` statement may load."""
    if node.level:
        package = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
        base = ".".join(package[:len(package) - node.level + 1])
        target = f"{base}.{node.module}" if node.module else base
    else:
        target = node.module or ""
    return [target] + [f"{target}.{alias.name}" for alias in node.names]


def _imports(modules: dict) -> dict:
    """Module -> splatconv modules it imports (top level and inside functions)."""
    graph = {}
    for module, path in modules.items():
        found = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = []
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = _resolve(module, path, node)
            found.update(n for n in names if n in modules and n != module)
        graph[module] = found
    return graph


def _ancestors(module: str) -> set:
    parts = module.split(".")
    return {".".join(parts[:i]) for i in range(1, len(parts))}


def test_no_module_imports_one_that_imports_it_back():
    modules = _modules()
    graph = _imports(modules)
    # Importing a.b.c runs a and a.b first: a package's __init__ importing a module
    # below it is the package's own business, not a cycle through that module.
    cycles = []
    for start in graph:
        stack, seen = [(start, [start])], set()
        while stack:
            node, trail = stack.pop()
            for nxt in graph[node]:
                if nxt in _ancestors(start) or nxt in _ancestors(node):
                    continue
                if nxt == start:
                    cycles.append(" -> ".join(trail + [nxt]))
                elif nxt not in seen:
                    seen.add(nxt)
                    stack.append((nxt, trail + [nxt]))
    assert not cycles, cycles[:5]


def test_imports_are_at_the_top_of_each_file_except_moderngl():
    late = []
    for module, path in _modules().items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        top = set(id(n) for n in tree.body)
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)) and id(node) not in top:
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
                if not all(n.split(".")[0] in LAZY_ALLOWED for n in names):
                    late.append(f"{module}:{node.lineno}")
    assert not late, late


def test_nothing_outside_formats_names_a_format_to_decide_what_to_do():
    """No ``is splatv`` / ``NAME == "..."`` outside formats/: callers ask a module what it supports."""
    offenders = []
    for module, path in _modules().items():
        if module.startswith("splatconv.formats"):
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Compare):
                text = ast.unparse(node)
                if any(f"{word} " in text or f"'{word}'" in text or f'"{word}"' in text
                       for word in ("is splatv", "is ply", "NAME ==", "NAME !=")):
                    offenders.append(f"{module}:{node.lineno}: {text}")
                for side in [node.left, *node.comparators]:
                    if isinstance(side, ast.Constant) and side.value in ("splatv", "ply", "splat"):
                        offenders.append(f"{module}:{node.lineno}: {text}")
            # path.endswith(".html"): a format chosen by its suffix outside the registry. The player
            # (web/) plays .splatv files and writes .html pages: those two it may name.
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "endswith"
                    and not module.startswith("splatconv.web")):
                for arg in node.args:
                    if isinstance(arg, ast.Constant) and arg.value in REGISTRY:
                        offenders.append(f"{module}:{node.lineno}: {ast.unparse(node)}")
    assert not offenders, offenders


def test_the_library_never_imports_click_and_the_cli_holds_no_numpy():
    graph_sources = {m: p.read_text(encoding="utf-8") for m, p in _modules().items()}
    for module, text in graph_sources.items():
        tree = ast.parse(text)
        names = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names.update(a.name.split(".")[0] for a in node.names)
            elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
                names.add(node.module.split(".")[0])
        if module == "splatconv.cli" or module.startswith("splatconv.cli."):  # not splatconv.clips
            assert "numpy" not in names, module
        else:
            assert "click" not in names, module


def test_operations_do_no_io_and_draw_nothing():
    """ops/ works on the model: no files, no formats, no renderer, no reports."""
    graph = _imports(_modules())
    forbidden = ("splatconv.io", "splatconv.fsutil", "splatconv.transport", "splatconv.formats", "splatconv.render",
                 "splatconv.cli", "splatconv.report", "splatconv.stats")
    found = [(module, target) for module, targets in graph.items() if module.startswith("splatconv.ops")
             for target in targets if target.startswith(forbidden)]
    assert not found, found


#: The sigmoid and logit of the viewer's opacity, written out: ``1 + exp(-x)`` and ``log(p) - log1p(-p)``.
_SIGMOID_OR_LOGIT = re.compile(r"1(\.0)?\s*\+\s*np\.exp\(\s*-|np\.log\((?P<p>\w+)\)\s*-\s*np\.log1p\(\s*-(?P=p)\)")
#: The writer's engine keeps its own in-place float arithmetic: it must match splaTV's converter bit for bit.
_OWN_ARITHMETIC = {"splatconv.viewer", "splatconv.formats.splatv_engine"}


def test_the_viewers_sigmoid_and_logit_are_written_once():
    """Everything else calls :mod:`splatconv.viewer` (``sigmoid``, ``logit``, ``opacity``)."""
    found = [f"{module}:{text.count(chr(10), 0, m.start()) + 1}" for module, path in _modules().items()
             if module not in _OWN_ARITHMETIC
             for text in [path.read_text(encoding="utf-8")] for m in _SIGMOID_OR_LOGIT.finditer(text)]
    assert not found, found


def test_every_format_module_declares_what_it_supports():
    """formats/base.py's list: callers ask these of any module, so every module states each one."""
    from splatconv.formats import _MODULES

    declared = ("NAME", "SUFFIXES", "CAN_READ", "CAN_WRITE", "COMPAT_MODES", "DEFAULT_SORT", "HOLDS_EMPTY", "DYNAMIC",
                "STORES_TEXTURE", "PLAYS_SEGMENTS")
    for module in _MODULES:
        missing = [name for name in declared if not hasattr(module, name)]
        missing += [name for name in ("read", "write", "info_fields", "storage") if not callable(getattr(module, name, None))]
        missing += [name for name in ("splat_count", "most_splats")
                    if module.CAN_READ and not callable(getattr(module, name, None))]
        assert not missing, (module.__name__, missing)


def _all_imported_names(path: Path) -> set:
    """Every name an import statement in ``path`` names (top-level packages included)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and not node.level:
            names.add(node.module or "")
    return names


def test_the_ply_container_knows_no_splats_and_is_the_only_plyfile_user():
    """formats/ply_container.py is the PLY container (header, elements, rows); formats/ply.py maps splats.

    The container imports nothing of the model or the viewer, and is the one
    module of the package that imports plyfile (to name a bad ASCII row).
    """
    modules = _modules()
    graph = _imports(modules)
    container = "splatconv.formats.ply_container"
    assert not {m for m in graph[container] if m.startswith(("splatconv.model", "splatconv.viewer", "splatconv.ops"))}
    assert container in graph["splatconv.formats.ply"]
    users = sorted(m for m, path in modules.items() if "plyfile" in _all_imported_names(path))
    assert users == [container]

