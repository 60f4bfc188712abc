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


# A command loads only what it uses. These run the CLI in a fresh interpreter and read its
# sys.modules (what was imported, not how long it took).
_SAMPLE = PACKAGE.parent / "sample_data" / "dancers.ply"
#: Loaded only by the commands that draw, serve or edit.
_HEAVY = ("moderngl", "http.server", "ssl", "splatconv.render", "splatconv.web", "splatconv.ops", "splatconv.clips",
          "splatconv.cli.scenes", "splatconv.cli.edit", "splatconv.cli.drawing", "splatconv.cli.web")
#: What reading any scene still loads: the format registry holds formats/html.py, which builds
#: the player page with web/page.py (a light module: strings and the page's template).
_READING_LOADS = {"splatconv.web", "splatconv.web.page"}


def _modules_loaded_by(*args: str) -> set:
    import subprocess
    import sys

    code = ("import sys\nfrom splatconv.cli import main\ntry:\n    main(sys.argv[1:])\nexcept SystemExit as e:\n"
            "    assert not e.code, e.code\nsys.stderr.write('\\n'.join(sys.modules))")
    done = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, cwd=PACKAGE.parent)
    assert done.returncode == 0, done.stderr
    return set(done.stderr.splitlines())


def _loaded_of(loaded: set, prefixes) -> list:
    return sorted(m for m in loaded for p in prefixes if m == p or m.startswith(p + "."))


def test_the_groups_help_loads_no_command_and_no_library():
    loaded = _modules_loaded_by("--help")
    assert not _loaded_of(loaded, _HEAVY + ("splatconv.io", "splatconv.formats", "splatconv.stats",
                                            "splatconv.cli.facts", "splatconv.cli._base")), loaded


def test_info_loads_no_renderer_server_or_operation():
    loaded = _modules_loaded_by("info", str(_SAMPLE))
    assert "splatconv.cli.facts" in loaded  # the check can fail: the command did run
    assert set(_loaded_of(loaded, _HEAVY)) <= _READING_LOADS, _loaded_of(loaded, _HEAVY)


def test_the_groups_help_lists_each_commands_own_summary():
    """``--help`` lists the summaries declared with the lazy map: each is its command's own, at any width."""
    import click

    from splatconv.cli import commands
    from splatconv.cli._group import COMMANDS

    loaded = commands()
    assert set(loaded) == set(COMMANDS)
    for name, (module, summary) in COMMANDS.items():
        assert loaded[name].callback.__module__ == f"splatconv.cli.{module}", name
        for limit in range(20, 140):
            assert click.Command(name, help=summary).get_short_help_str(limit) == loaded[name].get_short_help_str(limit)


#: The only modules that load others late, by name, each from the table named here.
_LAZY_LOADERS = {"splatconv": "_LAZY", "splatconv.cli._group": "COMMANDS"}


def test_modules_are_loaded_late_only_through_the_declared_tables():
    """``importlib.import_module`` (which the import-graph checks above cannot follow) is called only by
    the package's ``__getattr__`` (its ``_LAZY`` names) and the CLI group (its ``COMMANDS``)."""
    found = set()
    for module, path in _modules().items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Attribute) and node.attr == "import_module" or (
                    isinstance(node, ast.Name) and node.id == "__import__"):
                found.add(module)
    assert found == set(_LAZY_LOADERS), found
