"""Lint as tests: flake8 on every Python file (.flake8), catkin_lint on every package
(.catkin_lint) and clang-format in dry-run mode on every C++ file (.clang-format). Each tool
is Debian's (scripts/setup.sh installs it); a missing one fails naming the package."""
import os
import shutil
import subprocess

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SKIPPED_DIRS = {".git", "build", "devel", "install", "__pycache__"}
CPP_SUFFIXES = (".cpp", ".cc", ".h", ".hpp")


def repo_files():
    """Every file of the repository outside the build spaces, relative to ROOT, sorted."""
    found = []
    for folder, dirs, files in os.walk(ROOT):
        dirs[:] = [d for d in dirs if d not in SKIPPED_DIRS]
        found += [os.path.relpath(os.path.join(folder, f), ROOT) for f in files]
    return sorted(found)


def is_python(path):
    """A .py file, or an extension-less script whose shebang names python."""
    if path.endswith(".py"):
        return True
    if "." in os.path.basename(path):
        return False
    with open(os.path.join(ROOT, path), "rb") as f:
        first = f.readline()
    return first.startswith(b"#!") and b"python" in first


def tool(name, package):
    """The tool's path; the test fails naming the Debian package when it is not installed."""
    path = shutil.which(name)
    if path is None:
        pytest.fail(f"{name} is not installed: install the Debian package {package} "
                    f"(scripts/setup.sh does)")
    return path


def run(argv):
    return subprocess.run(argv, cwd=ROOT, capture_output=True, text=True)


def test_the_python_files_include_the_extension_less_scripts():
    files = [f for f in repo_files() if is_python(f)]
    assert "src/anyscale_core/nodes/decision_node" in files
    assert "scripts/run_evaluation.py" in files


def test_flake8_finds_nothing():
    files = [f for f in repo_files() if is_python(f)]
    done = run([tool("flake8", "flake8"), "--config", ".flake8"] + files)
    assert done.returncode == 0, done.stdout + done.stderr


def test_catkin_lint_finds_nothing_in_any_package_or_the_stack():
    done = run([tool("catkin_lint", "catkin-lint"), "-W2", "--strict", "--config", ".catkin_lint",
                "src", "."])
    assert done.returncode == 0, done.stdout + done.stderr


def test_the_cpp_is_clang_formatted():
    files = [f for f in repo_files() if f.endswith(CPP_SUFFIXES)]
    assert any(f.startswith("src/anyscale_agent_cpp/") for f in files)
    done = run([tool("clang-format", "clang-format"), "--dry-run", "--Werror", "--style=file"]
               + files)
    assert done.returncode == 0, done.stdout + done.stderr
