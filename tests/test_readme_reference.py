"""The READMEs are references a newcomer can read: the top README at most 200 lines and each
package README at most 350, every relative link in them and in docs/ pointing at a file that
exists, and each package README naming what its code offers: every node, private parameter,
topic and service with a literal name in the code, every launch file arg and every option of
its commands. A name counts as documented when it is a word of a `code span` in the README."""
import argparse
import glob
import os
import re

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TOP_README_MAX_LINES = 200
PACKAGE_README_MAX_LINES = 350
PACKAGES = sorted(os.path.basename(os.path.dirname(p))
                  for p in glob.glob(os.path.join(ROOT, "src", "*", "package.xml")))
MARKDOWN = sorted([os.path.join(ROOT, "README.md")]
                  + glob.glob(os.path.join(ROOT, "src", "*", "README.md"))
                  + glob.glob(os.path.join(ROOT, "docs", "**", "*.md"), recursive=True))

# What the code names, by the calls that name it (Python and C++).
PY_PRIVATE = re.compile(r'"(~\w+)(%d)?"')
PY_HELPER_PARAM = re.compile(r'\bParam\(\s*"(\w+)"')     # param_spec.Param("name", ...): ~name
PY_TOPIC = re.compile(r'rospy\.(?:Publisher|Subscriber|Service)\(\s*"([\w/]+)"')
CPP_PARAM = re.compile(r'\b(?:param|positive)(?:<[^>]*>)?\(\s*pnh_?\s*,\s*"(\w+)"'
                       r'|\bpnh_?\.(?:getParam|param)(?:<[^>]*>)?\(\s*"(\w+)"')
CPP_TOPIC = re.compile(r'\b(?:advertise<[^>]*>|subscribe|advertiseService)\([^"()]*"([\w/]+)"')
LAUNCH_ARG = re.compile(r'<arg\s+name="(\w+)"(?![^>]*\bvalue=)')
CPP_NODE = re.compile(r"^add_executable\((?!test_)(\w+)", re.M)
PY_OPTION = re.compile(r'add_argument\(\s*"(--[\w-]+)"')
# Commands whose options are the package's to document, beside the `anyscale` command.
COMMANDS = {"anyscale_testbed": ["demo_run.py", "evaluation_run.py", "soak_run.py"],
            "anyscale_study": ["simulation_report.py"],
            "anyscale_core": ["master_keeper.py"]}


def read(path):
    with open(path, encoding="utf-8") as f:
        return f.read()


def rel(path):
    return os.path.relpath(path, ROOT)


def prose(text):
    """The text without fenced code blocks."""
    return re.sub(r"^```.*?^```", "", text, flags=re.M | re.S)


def code_words(text):
    """Every word (`~name`, `/a/b`, `--opt`, `name`) of the text's code spans and blocks
    (fenced, or indented by four spaces)."""
    spans = re.findall(r"```.*?```|`[^`\n]+`|^    \S.*$", text, flags=re.S | re.M)
    return {w.rstrip("/.:") for s in spans for w in re.findall(r"[~/\w-][\w/.:-]*", s)}


def relative_links(text):
    """The relative targets of the markdown links and images outside code, anchors dropped."""
    text = re.sub(r"`[^`\n]+`", "", prose(text))
    targets = re.findall(r"\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)", text)
    return [t.split("#")[0] for t in targets
            if not re.match(r"[a-z][a-z0-9+.-]*:", t) and not t.startswith("#")]


def package_sources(pkg, pattern):
    base = os.path.join(ROOT, "src", pkg)
    return sorted(glob.glob(os.path.join(base, "nodes", "*")) + glob.glob(
        os.path.join(base, "src", "**", pattern), recursive=True))


def names_in_code(pkg):
    """(kind, name, where) of what the package's code offers under a literal name."""
    found = []
    for path in package_sources(pkg, "*.py"):
        text = read(path)
        for name, numbered in PY_PRIVATE.findall(text):
            if name != "~":
                found.append(("parameter", name + ("1" if numbered else ""), path))
        found += [("parameter", "~" + n, path) for n in PY_HELPER_PARAM.findall(text)]
        found += [("topic or service", n, path) for n in PY_TOPIC.findall(text)]
    for path in package_sources(pkg, "*.cpp"):
        text = read(path)
        found += [("parameter", "~" + (a or b), path) for a, b in CPP_PARAM.findall(text)]
        found += [("topic or service", n, path) for n in CPP_TOPIC.findall(text)]
    for path in glob.glob(os.path.join(ROOT, "src", pkg, "launch", "*.launch")):
        found += [("launch arg", n, path) for n in LAUNCH_ARG.findall(read(path))]
    for path in glob.glob(os.path.join(ROOT, "src", pkg, "nodes", "*")):
        found.append(("node", os.path.basename(path), path))
    cmake = os.path.join(ROOT, "src", pkg, "CMakeLists.txt")
    found += [("node", n, cmake) for n in CPP_NODE.findall(read(cmake))]
    for name in COMMANDS.get(pkg, []):
        path = os.path.join(ROOT, "src", pkg, "src", pkg, name)
        found += [("option", n, path) for n in PY_OPTION.findall(read(path))]
    return found


def documented(name, words):
    """A name is documented as itself, or (a topic) with or without its leading slash, or
    (a private parameter that the code names as a prefix, e.g. "~initial_pose_") by a word
    that starts with it."""
    if name in words or name.lstrip("/") in words or "/" + name in words:
        return True
    return name.endswith("_") and any(w.startswith(name) for w in words)


def test_the_top_readme_is_short_and_shows_the_two_commands():
    text = read(os.path.join(ROOT, "README.md"))
    lines = text.count("\n")
    assert lines <= TOP_README_MAX_LINES, f"README.md: {lines} lines, at most " \
        f"{TOP_README_MAX_LINES}: move measurements, histories and reasoning to docs/"
    for command in ("scripts/run_demo.sh", "scripts/run_tests.sh"):
        assert re.search(rf"^    {re.escape(command)}$", text, re.M), \
            f"README.md: the command `{command}` is not shown on a line of its own"


@pytest.mark.parametrize("pkg", PACKAGES)
def test_each_package_readme_is_at_most_350_lines(pkg):
    path = os.path.join(ROOT, "src", pkg, "README.md")
    assert os.path.exists(path), f"{rel(path)}: every package has a README"
    lines = read(path).count("\n")
    assert lines <= PACKAGE_README_MAX_LINES, f"{rel(path)}: {lines} lines, at most " \
        f"{PACKAGE_README_MAX_LINES}: move measurements, histories and reasoning to docs/"


@pytest.mark.parametrize("path", MARKDOWN, ids=rel)
def test_every_relative_link_points_at_a_file_that_exists(path):
    broken = [t for t in relative_links(read(path))
              if not os.path.exists(os.path.normpath(os.path.join(os.path.dirname(path), t)))]
    assert not broken, f"{rel(path)}: links to missing files: {', '.join(broken)}"


@pytest.mark.parametrize("pkg", PACKAGES)
def test_each_package_readme_names_what_its_code_offers(pkg):
    words = code_words(read(os.path.join(ROOT, "src", pkg, "README.md")))
    missing = sorted({(kind, name, rel(where)) for kind, name, where in names_in_code(pkg)
                      if not documented(name, words)})
    assert not missing, f"src/{pkg}/README.md lacks: " + "; ".join(
        f"{kind} `{name}` ({where})" for kind, name, where in missing)


def test_the_anyscale_commands_options_are_in_anyscale_cores_readme():
    from anyscale_core.cli import build_parser
    words = code_words(read(os.path.join(ROOT, "src", "anyscale_core", "README.md")))

    def options(parser, path):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    yield from options(sub, path + [name])
            else:
                yield from ((" ".join(path), o) for o in action.option_strings
                            if o.startswith("--") and o != "--help")
    missing = sorted({(cmd, o) for cmd, o in options(build_parser(), ["anyscale"])
                      if o not in words})
    assert not missing, "src/anyscale_core/README.md lacks: " + "; ".join(
        f"`{cmd} {o}`" for cmd, o in missing)


def test_the_link_and_name_checks_catch_what_they_are_for(tmp_path):
    """The helpers on made-up text: a missing file, a link inside code, a documented name."""
    text = ("see [a](docs/a.md#x), [web](https://x.org), [here](#top), `[no](skip.md)`,\n"
            "![img](pics/p.png)\n```\n[no](block.md)\n```\n| `~rate_hz`, `/anyscale/status` |\n")
    assert relative_links(text) == ["docs/a.md", "pics/p.png"]
    words = code_words(text)
    assert documented("~rate_hz", words) and documented("anyscale/status", words)
    assert not documented("~rate", words) and documented("~rate_", words)
