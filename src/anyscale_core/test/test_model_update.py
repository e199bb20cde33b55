"""model_update.py: numbers replaced in place in YAML text, comment blocks above list items,
everything else byte for byte; errors for what cannot be edited."""
import os

import pytest

from anyscale_core.model import ModelError
from anyscale_core.model_update import (CommentBlock, NumberEdit, connection_index,
                                        update_model_text, write_text_atomically)

TEXT = """# user's header
nodes:
  # the user's own note on a
  - name: a        # trailing note
    cpu_usage: {robot: TODO, laptop: 3}   # leave out a scale
    memory_mb: TODO
  - {name: b, cpu_usage: {robot: 1}, memory_mb: 5}
connections:
  - {publisher: a, subscriber: b, topic: /t, freq_min: TODO, freq_opt: 10,
     tolerance: TODO}
quoted: {x: "7"}
"""


def test_numbers_replaced_in_place_and_comments_kept():
    out = update_model_text(TEXT, [NumberEdit(("nodes", 0, "cpu_usage", "robot"), 12.5),
                                   NumberEdit(("nodes", 0, "memory_mb"), 40),
                                   NumberEdit(("nodes", 1, "memory_mb"), 0.00001),
                                   NumberEdit(("connections", 0, "tolerance"), 2)])
    assert "    cpu_usage: {robot: 12.5, laptop: 3}   # leave out a scale\n" in out
    assert "    memory_mb: 40\n" in out
    # Never 1e-05, which YAML 1.1 reads back as a string.
    assert "memory_mb: 0.00001}" in out
    assert "     tolerance: 2}\n" in out
    for keep in ("# user's header", "  # the user's own note on a", "# trailing note"):
        assert keep in out


def test_comment_blocks_above_block_and_flow_items_replace_earlier_ones():
    blocks = [CommentBlock(("nodes", 0), "profile: ", ("first", "second")),
              CommentBlock(("nodes", 1), "profile: ", ("for b",)),
              CommentBlock(("connections", 0), "thresholds: ", ("found",))]
    out = update_model_text(TEXT, [], blocks)
    assert ("  # the user's own note on a\n  # profile: first\n  # profile: second\n"
            "  - name: a") in out
    assert "  # profile: for b\n  - {name: b" in out
    assert "  # thresholds: found\n  - {publisher: a" in out
    again = update_model_text(out, [], [CommentBlock(("nodes", 0), "profile: ", ("new",))])
    assert "first" not in again and "  # profile: new\n  - name: a" in again
    assert "  # the user's own note on a\n" in again


def test_long_comment_lines_wrap_under_the_prefix():
    out = update_model_text(TEXT, [], [CommentBlock(("nodes", 1), "profile: ", ("word " * 40,))])
    lines = [x for x in out.splitlines() if "# profile:" in x]
    assert len(lines) > 1 and all(len(x) <= 100 for x in lines)
    assert lines[1].startswith("  # profile:   word")


def test_what_cannot_be_edited_is_an_error():
    with pytest.raises(ModelError, match="expected a plain number"):
        update_model_text(TEXT, [NumberEdit(("quoted", "x"), 1)])
    with pytest.raises(ModelError, match="missing key"):
        update_model_text(TEXT, [NumberEdit(("nodes", 0, "nope"), 1)])
    with pytest.raises(ModelError, match="not a list item"):
        update_model_text(TEXT, [NumberEdit(("nodes", 5, "memory_mb"), 1)])
    with pytest.raises(ModelError, match="invalid YAML"):
        update_model_text("a: [", [])


def test_connection_index_and_atomic_write(tmp_path):
    import yaml
    tree = yaml.safe_load(TEXT)
    assert connection_index(tree, "a", "b", "t") == 0
    with pytest.raises(ModelError, match="no connection a:x:/t"):
        connection_index(tree, "a", "x", "/t")
    path = tmp_path / "m.yaml"
    path.write_text("old\n")
    os.chmod(path, 0o600)
    write_text_atomically(str(path), "new\n")
    assert path.read_text() == "new\n" and (os.stat(path).st_mode & 0o777) == 0o600
    assert [p.name for p in tmp_path.iterdir()] == ["m.yaml"]
