"""The package's shape, checked: imports run one way, formats are asked, not named.

Reads the source with :mod:`ast`; nothing is imported or run.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

from splatconv.formats import REGISTRY

PACKAGE = Path(__file__).resolve().parent.parent / "splatconv"
#: Imports allowed inside functions: moderngl is loaded only when something is drawn, av (PyAV,
#: an optional extra) only when a video is written.
LAZY_ALLOWED = {"moderngl", "av", "PIL"}  # PIL: image files only, off convert's path


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


#: The command's entry point sets the signal handlers before it imports the command line.
_ENTRY_LATE = ("splatconv.__main__", "cli")
#: Publishing draws a page's poster: the renderer loads only when a page is written, so that
#: ``splatconv.convert`` (whose jobs hand an .html output to publishing) loads none.
_POSTER_LATE = {("splatconv.publish", "render.gl"), ("splatconv.publish", "render.poster")}


def test_imports_are_at_the_top_of_each_file_except_moderngl():
    late = []
    for module, path in _modules().items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        top = set(id(n) for n in tree.body)
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)) and id(node) not in top:
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
                if not all(n.split(".")[0] in LAZY_ALLOWED for n in names) and (module, node.module) != _ENTRY_LATE \
                        and (module, node.module) not in _POSTER_LATE:
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
            # path.endswith(".splatv"): a format chosen by its suffix outside the registry.
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "endswith":
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
    """ops/ works on the model: no files, no formats, no renderer, no findings or text."""
    graph = _imports(_modules())
    forbidden = ("splatconv.io", "splatconv.files", "splatconv.zstd", "splatconv.formats", "splatconv.render",
                 "splatconv.cli", "splatconv.text", "splatconv.stats")
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


def _package_node(module: str) -> str | None:
    """The package-level node of ``module``: its sub-package of splatconv, or itself when a top-level module
    (None for the root package, which importing anything below it runs first)."""
    parts = module.split(".")
    return ".".join(parts[:2]) if len(parts) > 1 else None


def _package_graph() -> dict:
    """Sub-package or top-level module -> those it imports (its members' imports, its own members left out)."""
    graph = {}
    for module, targets in _imports(_modules()).items():
        node = _package_node(module)
        if node is None:
            continue
        edges = graph.setdefault(node, set())
        edges.update(t for t in map(_package_node, targets) if t is not None and t != node)
    return graph


def _cycles(graph: dict) -> list:
    """One path round each cycle of ``graph`` found from each node (as ``a -> b -> a`` strings)."""
    found = []
    for start in sorted(graph):
        stack, seen = [(start, [start])], set()
        while stack:
            node, trail = stack.pop()
            for nxt in sorted(graph.get(node, ())):
                if nxt == start:
                    found.append(" -> ".join(trail + [nxt]))
                elif nxt not in seen:
                    seen.add(nxt)
                    stack.append((nxt, trail + [nxt]))
    return found


def test_the_cycle_finder_sees_a_package_circle():
    assert _cycles({"p.a": {"p.b"}, "p.b": {"p.a"}, "p.c": {"p.a"}}) == ["p.a -> p.b -> p.a", "p.b -> p.a -> p.b"]
    assert _cycles({"p.a": {"p.b"}, "p.b": set()}) == []


def test_no_package_imports_one_that_imports_it_back():
    """Layers hold between packages, not only modules: a formats/html.py using web/ while web/ used formats/
    was a circle no two modules showed."""
    graph = _package_graph()
    assert "splatconv.formats" in graph and "splatconv.web" in graph  # the graph is built from the real tree
    cycles = _cycles(graph)
    assert not cycles, cycles[:5]


def test_the_player_page_is_a_leaf():
    """web/ (the page and its assets) imports only the base layer; only publishing (which writes every page)
    and the server (which serves one) use it."""
    graph = _package_graph()
    allowed = {"splatconv.errors", "splatconv.wording"}
    assert graph["splatconv.web"] <= allowed, graph["splatconv.web"] - allowed
    users = {node for node, targets in graph.items() if "splatconv.web" in targets}
    assert users == {"splatconv.publish", "splatconv.server"}, users


def test_formats_know_no_page():
    """A format describes a file, never a page: nothing in formats/ imports the page, publishing or what
    uses them (the player page left the registry; its bytes are chosen in splatconv/publish.py alone)."""
    graph = _imports(_modules())
    above = ("splatconv.web", "splatconv.publish", "splatconv.server", "splatconv.jobs", "splatconv.cli")
    found = [(module, target) for module, targets in graph.items() if module.startswith("splatconv.formats")
             for target in targets if target.startswith(above)]
    assert not found, found


def _format_modules() -> dict:
    """Modules of formats/ that declare a format (``FORMAT = ...`` at the top level), by module name."""
    found = {}
    for module, path in _modules().items():
        if not module.startswith("splatconv.formats."):
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        if any(isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "FORMAT" for t in node.targets)
               for node in tree.body):
            found[module] = tree
    return found


def test_every_format_module_fills_the_one_contract():
    """formats/base.py's Format is the contract, stated once: each format module fills it (``FORMAT``), every
    such module is registered, and none states a declaration beside it."""
    import dataclasses
    import importlib

    from splatconv.formats import FORMATS
    from splatconv.formats.base import Format

    declared = _format_modules()
    assert {importlib.import_module(m).FORMAT for m in declared} == set(FORMATS), sorted(declared)
    for fmt in FORMATS:
        assert isinstance(fmt, Format), fmt
        for f in dataclasses.fields(Format):  # the annotations are strings (postponed evaluation)
            value = getattr(fmt, f.name)
            if f.type in ("str", "bool"):
                assert type(value).__name__ == f.type, (fmt.name, f.name, value)
            elif f.type == "tuple":
                assert isinstance(value, tuple) and all(isinstance(v, str) for v in value), (fmt.name, f.name)
            elif f.type == "tuple[int, ...]":
                assert isinstance(value, tuple) and all(type(v) is int for v in value), (fmt.name, f.name)
            elif f.type.startswith("Callable"):
                assert callable(value) or (value is None and f.type.endswith("None")), (fmt.name, f.name)
        assert all(callable(getattr(fmt, name)) for name in ("info_fields", "storage")), fmt.name
        assert all(callable(getattr(fmt, name)) for name in ("read", "splat_count", "most_splats")) == fmt.can_read
    # The old spelling of the contract, module constants, is gone: a second statement of it would be a second truth.
    old = {"NAME", "SUFFIXES", "CAN_READ", "CAN_WRITE", "COMPAT_MODES", "DEFAULT_SORT", "HOLDS_EMPTY", "DYNAMIC",
           "STORES_TEXTURE", "PLAYS_SEGMENTS"}
    for module, tree in declared.items():
        names = {t.id for node in tree.body if isinstance(node, ast.Assign) for t in node.targets
                 if isinstance(t, ast.Name)}
        assert not names & old, (module, names & old)


def test_a_format_is_read_directly_never_with_getattr():
    """Outside formats/, no ``getattr``/``hasattr`` of a declaration: every Format field exists, so a default
    would only hide a misspelling."""
    import dataclasses

    from splatconv.formats.base import Format

    names = {f.name for f in dataclasses.fields(Format)} | {"can_read", "can_write", "stores_texture", "FORMAT",
                                                            "NAME", "STORES_TEXTURE", "LAYOUTS", "DEFAULT_SORT"}
    found = []
    for module, path in _modules().items():
        if module.startswith("splatconv.formats"):
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("getattr", "hasattr")
                    and len(node.args) > 1 and isinstance(node.args[1], ast.Constant) and node.args[1].value in names):
                found.append(f"{module}:{node.lineno}: {ast.unparse(node)}")
    assert not found, found


def _docstrings(tree) -> set:
    return {id(node.body[0].value) for node in ast.walk(tree)
            if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body
            and isinstance(node.body[0], ast.Expr) and isinstance(node.body[0].value, ast.Constant)}


def test_no_format_is_named_outside_formats():
    """Outside formats/, a format is found by what it declares (``format_for``, ``texture_format``,
    ``playable_format``), never by name: no import of a format's module, no suffix as a value."""
    from splatconv.formats import FORMATS

    # Suffixes, not names: "splat" is also the word for one Gaussian (comparisons with a format's name are
    # checked above).
    words = {s for fmt in FORMATS for s in fmt.suffixes}
    found = []
    for module, path in _modules().items():
        if module.startswith("splatconv.formats"):
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        docstrings = _docstrings(tree)
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                targets = _resolve(module, path, node)
                named = [t for t in targets[1:] if t.startswith("splatconv.formats.") and t != "splatconv.formats.base"]
                if targets[0].startswith("splatconv.formats.") and targets[0] != "splatconv.formats.base":
                    named.append(targets[0])
                found += [f"{module}:{node.lineno}: imports {t}" for t in named if t[len("splatconv.formats."):] in
                          {m.rsplit(".", 1)[-1] for m in _format_modules()} | {"splatv_layout", "splatv_engine"}]
            elif (isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings
                  and node.value.lower() in words):
                found.append(f"{module}:{node.lineno}: {node.value!r}")
    assert not found, found


def test_a_format_declaration_that_leaves_out_what_it_implies_is_refused():
    """A declaration is checked when it is made: a readable format that cannot count its splats, a texture
    that cannot be read, a mixed-case suffix."""
    import pytest

    from splatconv.formats import splatv
    from splatconv.formats.base import Format

    base = dict(name="x", suffixes=(".x",), default_sort="none", holds_empty=True, dynamic=False, read=None,
                write=splatv.FORMAT.write, info_fields=dict, storage=dict)
    Format(**base)  # write-only, nothing else implied
    for broken in (dict(read=splatv.FORMAT.read), dict(texture=splatv.FORMAT.texture),
                   dict(check_playable=splatv.FORMAT.check_playable), dict(suffixes=(".X",)), dict(write=None)):
        with pytest.raises(TypeError):
            Format(**{**base, **broken})


#: The file-level steps of a job (:mod:`splatconv.jobs`): the CLI calls a job, never these.
_FILE_WORK = {"write", "io.write", "write_each", "write_sequence", "check_output", "check_write_options", "refuse_empty",
              "atomic_writer", "atomic_group", "check_job"}


def test_the_cli_leaves_the_work_on_files_to_jobs():
    """A command body calls one job (splatconv.jobs) and echoes: it checks, writes and replaces no file itself."""
    found = []
    for module, path in _modules().items():
        if module == "splatconv.cli" or module.startswith("splatconv.cli."):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, ast.Call):
                    name = getattr(node.func, "id", None) or getattr(node.func, "attr", None)
                    if name == "write" and getattr(node.func, "value", None) is not None:
                        name = f"{getattr(node.func.value, 'id', '')}.write"  # io.write, not a stream's write
                    if name in _FILE_WORK:
                        found.append(f"{module}:{node.lineno} {name}")
    assert not found, found


def test_importing_splatconv_loads_no_operation_and_no_renderer():
    """``splatconv.convert`` is a job of its own module: the other jobs' operations load with their commands."""
    import subprocess
    import sys

    code = ("import sys, splatconv; splatconv.convert; print(sorted(m for m in sys.modules if m.startswith(("
            "'splatconv.ops', 'splatconv.render', 'splatconv.jobs.'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=PACKAGE.parent).stdout
    assert out.strip() == "['splatconv.jobs._steps', 'splatconv.jobs.convert']", out


# A command loads only what it uses. These run the CLI in a fresh interpreter and read its
# sys.modules (what was imported, not how long it took).
_SAMPLE = PACKAGE.parent / "sample_data" / "dancers.ply"
#: Loaded only by the commands that draw, serve or edit.
_HEAVY = ("moderngl", "http.server", "ssl", "splatconv.render", "splatconv.web", "splatconv.ops", "splatconv.jobs.segments",
          "splatconv.cli.scenes", "splatconv.cli.edit", "splatconv.cli.drawing", "splatconv.cli.web")


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
    # Nor the page: reading a scene needs no player (the registry holds scene formats only).
    assert not _loaded_of(loaded, _HEAVY + ("splatconv.publish",)), _loaded_of(loaded, _HEAVY)


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

