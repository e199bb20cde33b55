"""Measured numbers written into a model YAML in place, byte for byte around them: the user's
comments, key order, flow or block style and blank lines all stay.

PyYAML has no round-trip mode, and Debian's python3-ruamel.yaml (which has one) still re-indents
flow mappings and moves comments; a model is a file the user edits by hand. So the text is
edited, not a tree: yaml.compose() gives every scalar's exact span in the text (its start and
end marks), each measured scalar is replaced there, and a block of comments saying when and how
the numbers were measured goes directly above the list item they belong to (a node or a
connection). Such a block is recognised by its prefix (`# profile: `, `# thresholds: `), so a
second run replaces the first run's block instead of piling up another. The result is parsed
again and each edited value checked, so a text edit can never silently change something else.
Nothing here talks to ROS (model_draft.py writes a new model's text the same way, by lines).
"""
import os
import tempfile
import textwrap
from dataclasses import dataclass
from typing import Dict, List, Sequence, Tuple, Union

import yaml

from .model import ModelError
from .model_draft import decimal

Path = Tuple[Union[str, int], ...]     # e.g. ("nodes", 3, "cpu_usage", "laptop")


@dataclass(frozen=True)
class NumberEdit:
    path: Path
    value: float


@dataclass(frozen=True)
class CommentBlock:
    item: Path                 # the list item it sits above, e.g. ("nodes", 3)
    prefix: str                # every line starts with "# " + prefix, e.g. "profile: "
    lines: Tuple[str, ...]


def _child(node: yaml.Node, key: Union[str, int], where: str) -> yaml.Node:
    if isinstance(key, int):
        if not isinstance(node, yaml.SequenceNode) or key >= len(node.value):
            raise ModelError(where, "", "not a list item of the model")
        return node.value[key]
    if not isinstance(node, yaml.MappingNode):
        raise ModelError(where, "", "expected a mapping")
    for key_node, value_node in node.value:
        if isinstance(key_node, yaml.ScalarNode) and key_node.value == key:
            return value_node
    raise ModelError(where, "", "missing key")


def _node_at(root: yaml.Node, path: Path, source: str) -> yaml.Node:
    node = root
    for depth, key in enumerate(path):
        node = _child(node, key, f"{source}: {_dotted(path[:depth + 1])}")
    return node


def _dotted(path: Path) -> str:
    out = ""
    for key in path:
        out += f"[{key}]" if isinstance(key, int) else (f".{key}" if out else str(key))
    return out


def update_model_text(text: str, numbers: Sequence[NumberEdit],
                      comments: Sequence[CommentBlock] = (), source: str = "<model>") -> str:
    """`text` with each number replaced in place and each comment block set above its item
    (replacing an earlier block of the same prefix there). ModelError if a path is not a plain
    scalar of the document."""
    try:
        root = yaml.compose(text)
    except yaml.YAMLError as e:
        raise ModelError(source, "", f"invalid YAML: {' '.join(str(e).split())}") from None
    if root is None:
        raise ModelError(source, "", "empty model")
    splices: List[Tuple[int, int, str]] = []
    for edit in numbers:
        node = _node_at(root, edit.path, source)
        if not isinstance(node, yaml.ScalarNode) or node.style not in (None, ""):
            raise ModelError(source, _dotted(edit.path), "expected a plain number or TODO to "
                                                         "replace")
        splices.append((node.start_mark.index, node.end_mark.index, decimal(edit.value)))
    lines = text.splitlines(keepends=True)
    for block in comments:
        item = _node_at(root, block.item, source)
        line_no = item.start_mark.line
        # A flow item `- {name: x}` and a block item `- name: x` both start on the dash's line.
        item_line = lines[line_no]
        indent = item_line[:len(item_line) - len(item_line.lstrip(" "))]
        marker = f"{indent}# {block.prefix}"
        first = line_no
        while first > 0 and lines[first - 1].startswith(marker):
            first -= 1
        start = sum(len(x) for x in lines[:first])
        end = sum(len(x) for x in lines[:line_no])
        new = "".join(f"{marker}{line}\n" for line in _wrapped(block.lines, len(marker)))
        splices.append((start, end, new))
    splices.sort(key=lambda s: s[0], reverse=True)
    for (start, end, _), (next_start, _, _) in zip(splices[1:], splices[:-1]):
        if end > next_start:
            raise ModelError(source, "", "two edits of one place")
    out = text
    for start, end, new in splices:
        out = out[:start] + new + out[end:]
    _check(out, numbers, source)
    return out


LINE_WIDTH = 100


def _wrapped(lines: Sequence[str], margin: int) -> List[str]:
    """Comment lines wrapped to LINE_WIDTH; a continuation is indented two spaces."""
    out = []
    for line in lines:
        out += textwrap.wrap(line, width=max(40, LINE_WIDTH - margin),
                             subsequent_indent="  ", break_on_hyphens=False) or [""]
    return out


def _check(text: str, numbers: Sequence[NumberEdit], source: str):
    """Reads the edited text back: each edited value must be there, as a number."""
    tree = yaml.safe_load(text)
    for edit in numbers:
        value = tree
        for key in edit.path:
            value = value[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or \
                abs(float(value) - float(decimal(edit.value))) > 1e-9 * max(1.0, abs(value)):
            raise ModelError(source, _dotted(edit.path),
                             f"edit did not read back as {edit.value!r}, got {value!r}")


def node_paths(tree: Dict) -> Dict[str, int]:
    """node name -> its index in `nodes` of a model tree (as yaml.safe_load reads it)."""
    return {n.get("name"): i for i, n in enumerate(tree.get("nodes") or [])
            if isinstance(n, dict)}


def connection_index(tree: Dict, publisher: str, subscriber: str, topic: str) -> int:
    for i, c in enumerate(tree.get("connections") or []):
        if isinstance(c, dict) and (c.get("publisher"), c.get("subscriber")) == \
                (publisher, subscriber) and str(c.get("topic", "")).lstrip("/") == \
                topic.lstrip("/"):
            return i
    raise ModelError("connections", "", f"no connection {publisher}:{subscriber}:{topic}")


def write_text_atomically(path: str, text: str):
    """Replaces `path` with `text` in one rename: an interrupted write never leaves half a
    model. The file keeps its permissions."""
    directory = os.path.dirname(os.path.abspath(path))
    try:
        mode = os.stat(path).st_mode & 0o7777
    except OSError:
        mode = 0o644
    fd, tmp = tempfile.mkstemp(prefix=".anyscale-", suffix=".yaml", dir=directory)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except OSError as e:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise ModelError(path, "", f"cannot write: {e.strerror}") from None
