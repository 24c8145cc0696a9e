"""The layers of pdem, checked on the source (AST of every module, lazy imports included).

Layers, top down: the command line → scenes (and jobs) → driver → engine; `analysis/` reads files
only, with `pdem.format` (the file format, at the bottom). The engine (every module of pdem/
outside driver/, scenes/, format/ and the command line) never imports the driver or the scenes;
nothing of pdem but the command line imports analysis; the driver never imports the scenes; only
pdem/parallel/comm.py imports mpi4py; analysis imports of pdem only `pdem.format`; `pdem.format`
imports numpy, h5py and the standard library only (and `import pdem.format` loads nothing else of
pdem); and no two modules of pdem import each other, directly or through others (an import cycle).
"""
import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PDEM = ROOT / "pdem"
TOP = ("pdem/cli.py", "pdem/__main__.py")  # the command line (and pdem/campaign/) sit above everything


def module_name(path):
    rel = path.relative_to(ROOT).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def is_package(path):
    return path.name == "__init__.py"


def imports(path):
    """Absolute names of every module `path` imports (module level and inside functions)."""
    tree = ast.parse(path.read_text(), str(path))
    me = module_name(path)
    package = me if is_package(path) else me.rpartition(".")[0]
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module
            out.add(mod)
            for a in node.names:  # `from pkg import submodule`
                out.add(f"{mod}.{a.name}")
    return out


def pdem_modules():
    return {module_name(p): p for p in PDEM.rglob("*.py")}


def existing(names, modules):
    return {n for n in names if n in modules}


def layer(path):
    rel = path.relative_to(ROOT).as_posix()
    if rel in TOP or rel.startswith("pdem/campaign/"):
        return "top"
    if rel.startswith("pdem/format/"):
        return "format"
    if rel.startswith("pdem/scenes/"):
        return "scenes"
    if rel.startswith("pdem/driver/"):
        return "driver"
    return "engine"


def test_layers_import_downward_and_only_the_command_line_imports_analysis():
    bad = []
    for name, path in pdem_modules().items():
        lay = layer(path)
        for imp in imports(path):
            top = imp.split(".")[0]
            if lay != "top" and top == "analysis":
                bad.append(f"{name} ({lay}) imports {imp}")
            if lay == "engine" and imp.startswith(("pdem.driver", "pdem.scenes")):
                bad.append(f"{name} imports {imp}")
            if lay == "driver" and imp.startswith("pdem.scenes"):
                bad.append(f"{name} (driver) imports {imp}")
    assert not bad, "layer violations:\n" + "\n".join(bad)


def test_only_parallel_comm_imports_mpi4py():
    users = sorted(
        name for name, path in pdem_modules().items() if any(i.split(".")[0] == "mpi4py" for i in imports(path))
    )
    assert users == ["pdem.parallel.comm"], users


def test_analysis_reads_files_only():
    bad = [f"{p.name} imports {i}" for p in (ROOT / "analysis").rglob("*.py") for i in imports(p)
           if i.split(".")[0] in ("numba", "mpi4py") or (i.split(".")[0] == "pdem" and not i.startswith("pdem.format"))]
    assert not bad, bad


def test_format_imports_numpy_h5py_and_stdlib_only():
    allowed = {"numpy", "h5py", "pdem", *sys.stdlib_module_names}
    bad = [f"{name} imports {i}" for name, path in pdem_modules().items() if layer(path) == "format"
           for i in imports(path)
           if i.split(".")[0] not in allowed or (i.split(".")[0] == "pdem" and not i.startswith("pdem.format"))]
    assert not bad, bad


def test_format_and_analysis_load_no_engine():
    """``import pdem.format; import analysis`` in a fresh interpreter: no numba, nothing of pdem
    but the package itself and pdem.format (pdem/__init__.py loads its names lazily)."""
    code = ("import sys, pdem.format, pdem.format.schema, pdem.format.read, pdem.format.groups, pdem.format.campaign, "
            "analysis, analysis.__main__; print(' '.join(sorted(sys.modules)))")
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                            cwd=ROOT).stdout.split()
    assert "numba" not in loaded and "mpi4py" not in loaded
    other = [m for m in loaded if m.startswith("pdem.") and not m.startswith("pdem.format")]
    assert "pdem" in loaded and "pdem.format" in loaded and not other, other


def find_cycle(graph):
    """One import cycle of the directed graph {module: set of modules}, or None."""
    state = {}
    stack = []

    def visit(u):
        state[u] = 1
        stack.append(u)
        for v in sorted(graph[u]):
            if state.get(v) == 1:
                return stack[stack.index(v):] + [v]
            if v not in state:
                found = visit(v)
                if found:
                    return found
        stack.pop()
        state[u] = 2
        return None

    for u in sorted(graph):
        if u not in state:
            found = visit(u)
            if found:
                return found
    return None


def test_no_import_cycle_in_pdem():
    mods = pdem_modules()
    graph = {}
    for name, path in mods.items():
        deps = existing(imports(path), mods)
        # importing pkg.sub runs pkg/__init__ first, but that is not a dependency of pkg.sub on pkg
        graph[name] = {
            d for d in deps if d != name and not (d in mods and is_package(mods[d]) and name.startswith(d + "."))
        }
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_cycle_finder_finds_a_cycle():
    """The check above can fail: a made-up graph with a cycle through three modules."""
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


@pytest.mark.parametrize("name", ["pdem.driver.runloop", "pdem.scenes.box_test", "pdem.contact.loops",
                                  "pdem.format.schema"])
def test_modules_are_seen(name):
    """The scan covers the subpackages (guards against a walk that finds nothing)."""
    assert name in pdem_modules()
