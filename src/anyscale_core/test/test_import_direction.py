"""The direction of dependencies between the workspace's packages: the product never reaches into
the evaluation tooling.

The product (anyscale_core, anyscale_agent_cpp) is what runs on a user's robot; the test bed
(anyscale_testbed) and the paper's Fig. 7 study (anyscale_study) use it, never the other way
round, so a robot installs no tooling. The demo application (anyscale_nav_demo) is run BY the
test bed (its world, goals and launch files), so an arrow from it into the test bed would be a
cycle: it may use neither tool package either. Every Python file (by ending or by a python
shebang), launch file and package.xml of those packages is read as text; nothing is imported.

One arrow is allowed, and only as a lazy import inside a function: `anyscale simulate` (the
one CLI, anyscale_core's cli_simulate.py) imports anyscale_study when it runs and says what to
install where the study is missing (test_cli.py checks that).

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
# file (relative to src/) -> tooling packages it may import, inside a function only
LAZY_OPTIONAL = {"anyscale_core/src/anyscale_core/cli_simulate.py": {"anyscale_study"}}
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


def python_imports(path: str, module_level_only: bool = False) -> Set[str]:
    """The top-level packages a Python file imports: import statements, wherever they stand
    (also inside functions), and importlib.import_module / __import__ of a literal name. With
    `module_level_only`, those outside any function."""
    with open(path, encoding="utf-8") as f:
        tree = ast.parse(f.read(), filename=path)
    skipped = set()
    if module_level_only:
        for func in ast.walk(tree):
            if isinstance(func, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                skipped.update(id(n) for n in ast.walk(func))
    found = set()
    for node in ast.walk(tree):
        if id(node) in skipped:
            continue
        if isinstance(node, ast.Import):
            found.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.add(node.module.split(".")[0])
        elif (isinstance(node, ast.Call) and node.args
              and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str)
              and called_name(node.func) in ("import_module", "__import__")):
            found.add(node.args[0].value.split(".")[0])
    return found


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
    assert all(os.path.isfile(os.path.join(SRC, path)) for path in LAZY_OPTIONAL)


def allowed_lazily(path: str, used: str) -> bool:
    return (used in LAZY_OPTIONAL.get(path, set())
            and used not in python_imports(os.path.join(SRC, path), module_level_only=True))


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_no_arrow_into_the_tooling(package):
    uses = dependency_graph()[package]
    wrong = {}
    for used, files in uses.items():
        files = [f for f in files if not allowed_lazily(f, used)]
        if used in FORBIDDEN[package] and files:
            wrong[used] = files
    assert not wrong, (f"{package} must not use {', '.join(sorted(wrong))}: "
                       + "; ".join(f"{used} in {', '.join(files)}"
                                   for used, files in sorted(wrong.items())))


if __name__ == "__main__":
    for package, uses in dependency_graph().items():
        print(f"{package} -> {', '.join(sorted(uses)) or '-'}")
    sys.exit(0)
