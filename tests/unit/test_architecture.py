"""The layers of pdem, checked on the source (AST of every module, lazy imports included).

Layers, top down: scenes (and jobs) → driver → engine; `analysis/` reads files only. The engine
(every module of pdem/ outside driver/, scenes/ and the command line) never imports the driver,
the scenes or analysis; the driver never imports the scenes; only pdem/parallel/comm.py imports
mpi4py; analysis never imports pdem; and no two modules of pdem import each other, directly or
through others (an import cycle).
"""
import ast
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
    if rel.startswith("pdem/scenes/"):
        return "scenes"
    if rel.startswith("pdem/driver/"):
        return "driver"
    return "engine"


def test_engine_imports_no_driver_scenes_or_analysis():
    bad = []
    for name, path in pdem_modules().items():
        lay = layer(path)
        for imp in imports(path):
            top = imp.split(".")[0]
            if lay == "engine" and (imp.startswith(("pdem.driver", "pdem.scenes")) or top == "analysis"):
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
           if i.split(".")[0] in ("pdem", "numba", "mpi4py")]
    assert not bad, bad


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


@pytest.mark.parametrize("name", ["pdem.driver.runloop", "pdem.scenes.box_test", "pdem.contact.loops"])
def test_modules_are_seen(name):
    """The scan covers the subpackages (guards against a walk that finds nothing)."""
    assert name in pdem_modules()
