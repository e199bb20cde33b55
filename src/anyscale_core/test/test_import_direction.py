"""The direction of dependencies between the workspace's packages: the product never reaches into
the evaluation tooling.

The product (anyscale_core, anyscale_agent_cpp) is what runs on a user's robot; the test bed
(anyscale_testbed) and the paper's Fig. 7 study (anyscale_study) use it, never the other way
round, so a robot installs no tooling. The demo application (anyscale_nav_demo) is run BY the
test bed (its world, goals and launch files), so an arrow from it into the test bed would be a
cycle: it may use neither tool package either. Every Python file (by ending or by a python
shebang), launch file and package.xml of those packages is read as text; nothing is imported.

A path into another package counts as using it too (a string constant naming a file or
folder there: "anyscale_nav_demo/config/x.yaml", os.path.join(..., "anyscale_nav_demo", ...)),
as does a launch file's $(find ...). The Fig. 7 study's `anyscale simulate` is registered by the
study's package.xml (anyscale_core/cli_plugins.py), not imported by the core.

`/usr/bin/python3 test_import_direction.py` prints the package-level graph it checks.
"""
import ast
import os
import re
import sys
from collections import defaultdict
from typing import Dict, Iterator, List, Set, Tuple

import pytest

SRC = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
TOOLING = {"anyscale_testbed", "anyscale_study"}
# package -> the workspace packages it must not use (Python imports, launch files, manifest)
FORBIDDEN: Dict[str, Set[str]] = {
    "anyscale_core": TOOLING | {"anyscale_nav_demo"},
    "anyscale_agent_cpp": TOOLING | {"anyscale_nav_demo"},
    "anyscale_nav_demo": TOOLING,
}
WORKSPACE_PACKAGES = sorted(d for d in os.listdir(SRC)
                            if os.path.isfile(os.path.join(SRC, d, "package.xml")))
# In launch and rostest files: <node pkg="X" ...>, <include file="$(find X)/...">.
LAUNCH_PACKAGE = re.compile(r'pkg="([A-Za-z0-9_]+)"|\$\(find ([A-Za-z0-9_]+)\)')
MANIFEST_DEPEND = re.compile(r"<(?:\w+_)?depend>([A-Za-z0-9_]+)</")


def package_files(package: str) -> Iterator[Tuple[str, str]]:
    """(path, kind) of every file of `package` that can name another package: kind "python",
    "launch" or "manifest"."""
    for root, dirs, files in os.walk(os.path.join(SRC, package)):
        dirs[:] = [d for d in dirs if not d.startswith(".") and d != "__pycache__"]
        for name in files:
            path = os.path.join(root, name)
            if name.endswith(".py") or (not os.path.splitext(name)[1] and is_python_script(path)):
                yield path, "python"
            elif name.endswith((".launch", ".test")):
                yield path, "launch"
            elif name == "package.xml":
                yield path, "manifest"


def is_python_script(path: str) -> bool:
    try:
        with open(path, "rb") as f:
            first = f.readline(200)
    except OSError:
        return False
    return first.startswith(b"#!") and b"python" in first


def python_imports(path: str) -> Set[str]:
    """The top-level packages a Python file imports: import statements, wherever they stand
    (also inside functions), importlib.import_module / __import__ of a literal name, and the
    workspace packages its string constants reach by path."""
    with open(path, encoding="utf-8") as f:
        tree = ast.parse(f.read(), filename=path)
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            found.update(packages_in_path(node.value))
        elif isinstance(node, ast.Call) and called_name(node.func) == "join":
            found.update(a.value for a in node.args if isinstance(a, ast.Constant)
                         and a.value in WORKSPACE_PACKAGES)
        if isinstance(node, ast.Import):
            found.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.add(node.module.split(".")[0])
        elif (isinstance(node, ast.Call) and node.args
              and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str)
              and called_name(node.func) in ("import_module", "__import__")):
            found.add(node.args[0].value.split(".")[0])
    return found


def packages_in_path(text: str) -> Set[str]:
    """Workspace packages a string names as a component of a path with a slash in it (a
    package's bare name, or prose that mentions one, is not a path)."""
    if "/" not in text or "\n" in text or " " in text:
        return set()
    return {part for part in text.split("/") if part in WORKSPACE_PACKAGES}


def called_name(func: ast.expr) -> str:
    if isinstance(func, ast.Attribute):
        return func.attr
    return func.id if isinstance(func, ast.Name) else ""


def packages_named(path: str, kind: str) -> Set[str]:
    if kind == "python":
        return python_imports(path)
    with open(path, encoding="utf-8") as f:
        text = f.read()
    if kind == "launch":
        return {a or b for a, b in LAUNCH_PACKAGE.findall(text)}
    return set(MANIFEST_DEPEND.findall(text))


def dependency_graph() -> Dict[str, Dict[str, List[str]]]:
    """package -> workspace package it uses -> the files (relative to src/) that use it."""
    graph: Dict[str, Dict[str, List[str]]] = {}
    for package in WORKSPACE_PACKAGES:
        uses = defaultdict(list)
        for path, kind in package_files(package):
            if os.path.abspath(path) == os.path.abspath(__file__):
                continue        # this test names the packages whose arrows it checks
            for used in packages_named(path, kind) & set(WORKSPACE_PACKAGES) - {package}:
                uses[used].append(os.path.relpath(path, SRC))
        graph[package] = dict(uses)
    return graph


def test_the_graph_covers_the_product():
    """Guards the test itself: it must read the files that matter."""
    read = {os.path.relpath(p, SRC) for p, _ in package_files("anyscale_core")}
    assert "anyscale_core/src/anyscale_core/cli.py" in read
    assert "anyscale_core/scripts/anyscale" in read            # a script without .py
    assert "anyscale_core/package.xml" in read
    assert set(FORBIDDEN) <= set(WORKSPACE_PACKAGES)
    assert TOOLING <= set(WORKSPACE_PACKAGES)


def test_a_path_into_another_package_counts_as_using_it(tmp_path):
    script = tmp_path / "uses_by_path.py"
    script.write_text('import os\nM = os.path.join(HERE, "..", "anyscale_nav_demo", "config")\n'
                      'N = "../anyscale_study/data/x.yaml"\n'
                      'S = "the anyscale_testbed package runs it"\n')
    assert python_imports(str(script)) == {"os", "anyscale_nav_demo", "anyscale_study"}


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_no_arrow_into_the_tooling(package):
    uses = dependency_graph()[package]
    wrong = {}
    for used, files in uses.items():
        if used in FORBIDDEN[package]:
            wrong[used] = files
    assert not wrong, (f"{package} must not use {', '.join(sorted(wrong))}: "
                       + "; ".join(f"{used} in {', '.join(files)}"
                                   for used, files in sorted(wrong.items())))


def module_graph(package_root: str, package: str) -> Dict[str, Set[str]]:
    """module -> the modules of the same Python package it imports (anywhere in the file, also
    inside functions or `if TYPE_CHECKING`), by absolute or relative import."""
    modules = {}
    for root, _, files in os.walk(os.path.join(package_root, package)):
        for name in files:
            if name.endswith(".py"):
                path = os.path.join(root, name)
                module = os.path.relpath(path, package_root)[:-3].replace(os.sep, ".")
                modules[module[:-len(".__init__")] if module.endswith(".__init__")
                        else module] = path
    graph: Dict[str, Set[str]] = {m: set() for m in modules}
    for module, path in modules.items():
        with open(path, encoding="utf-8") as f:
            tree = ast.parse(f.read(), filename=path)
        base = module if path.endswith("__init__.py") else module.rpartition(".")[0]
        for node in ast.walk(tree):
            targets = []
            if isinstance(node, ast.ImportFrom):
                parts = base.split(".")[:len(base.split(".")) - max(node.level - 1, 0)]
                target = ".".join(parts + [node.module] if node.module else parts) \
                    if node.level else (node.module or "")
                targets = [target] + [f"{target}.{a.name}" for a in node.names]
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            graph[module].update(t for t in targets if t in modules and t != module)
    return graph


def circles(graph: Dict[str, Set[str]]) -> List[List[str]]:
    """The groups of modules that import each other, directly or round a circle
    (strongly connected components of more than one module)."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components
    names = sorted(graph)
    index = {n: i for i, n in enumerate(names)}
    rows = [index[a] for a in names for _ in graph[a]]
    cols = [index[b] for a in names for b in sorted(graph[a])]
    matrix = csr_matrix(([1] * len(rows), (rows, cols)), shape=(len(names), len(names)))
    _, labels = connected_components(matrix, directed=True, connection="strong")
    groups = defaultdict(list)
    for name, label in zip(names, labels):
        groups[label].append(name)
    return sorted(g for g in groups.values() if len(g) > 1)


@pytest.mark.parametrize("package", [p for p in WORKSPACE_PACKAGES
                                     if os.path.isdir(os.path.join(SRC, p, "src", p))])
def test_no_circle_between_the_modules_of_a_package(package):
    found = circles(module_graph(os.path.join(SRC, package, "src"), package))
    assert not found, f"modules of {package} that import each other: {found}"


def test_a_circle_is_found_also_through_a_lazy_import(tmp_path):
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from .b import B\n")
    (pkg / "b.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                              "    from pkg.c import C\n")
    (pkg / "c.py").write_text("def f():\n    from . import a\n")
    assert circles(module_graph(str(tmp_path), "pkg")) == [["pkg.a", "pkg.b", "pkg.c"]]


if __name__ == "__main__":
    for package, uses in dependency_graph().items():
        print(f"{package} -> {', '.join(sorted(uses)) or '-'}")
    sys.exit(0)
