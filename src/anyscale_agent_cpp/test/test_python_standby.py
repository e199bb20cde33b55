"""scripts/python_standby: imports first, waits, then runs the node as if just exec'd."""
import importlib.machinery
import importlib.util
import os
import subprocess
import sys
import time

import pytest

STANDBY = os.path.join(os.path.dirname(__file__), "..", "scripts", "python_standby")

NODE = """#!/usr/bin/python3
import sys
PRELOADED = "xml.dom.minidom" in sys.modules
import os
try:
    import xml.dom.minidom
except ImportError:
    pass
import no_such_module_anywhere_xyz  # noqa  (fails only when the node itself runs)
"""

NODE_BODY = """#!/usr/bin/python3
import os
import sys
PRELOADED = "xml.dom.minidom" in sys.modules
if True:
    import xml.dom.minidom
print("argv=%s preloaded=%s name=%s comm=%s policy=%d" % (
    sys.argv[1:], PRELOADED, __name__, open("/proc/self/comm").read().strip(),
    os.sched_getscheduler(0)), flush=True)
sys.exit(3)
"""

# What catkin_install_python puts in devel space (catkin/cmake/template/script.py.in).
CATKIN_RELAY = """#!/usr/bin/python3
# generated from catkin/cmake/template/script.py.in
python_script = '{source}'
with open(python_script, 'r') as fh:
    context = {{'__builtins__': __builtins__, '__doc__': None, '__file__': python_script,
               '__name__': __name__, '__package__': None}}
    exec(compile(fh.read(), python_script, 'exec'), context)
"""


def load_standby_module():
    loader = importlib.machinery.SourceFileLoader("python_standby", STANDBY)
    module = importlib.util.module_from_spec(importlib.util.spec_from_loader(loader.name, loader))
    loader.exec_module(module)
    return module


def write(path, text):
    path.write_text(text)
    path.chmod(0o755)
    return str(path)


def comm(pid):
    with open(f"/proc/{pid}/comm") as f:
        return f.read().strip()


def wait_for(predicate, timeout_s=10.0):
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.02)
    return predicate()


@pytest.fixture
def node_script(tmp_path):
    return write(tmp_path / "my_node", NODE_BODY)


def start_standby(executable, *args):
    return subprocess.Popen([sys.executable, STANDBY, executable, *args], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


@pytest.mark.parametrize("via_catkin_relay", [False, True])
def test_start_runs_the_node_with_its_command_line_and_imports_done(tmp_path, node_script,
                                                                    via_catkin_relay):
    executable = write(tmp_path / "relay", CATKIN_RELAY.format(source=node_script)) \
        if via_catkin_relay else node_script
    proc = start_standby(executable, "scan:=/base_scan", "__name:=my_node")
    try:
        assert wait_for(lambda: comm(proc.pid).startswith("standby:"))
        # Give the imports time; the node must not have run yet.
        time.sleep(1.0)
        assert proc.poll() is None
        if os.geteuid() == 0:
            assert os.sched_getscheduler(proc.pid) == os.SCHED_IDLE
        out, _ = proc.communicate("start\n", timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 3, out
    expected_comm = os.path.basename(executable)[:15]
    assert (f"argv=['scan:=/base_scan', '__name:=my_node'] preloaded=True name=__main__ "
            f"comm={expected_comm} policy={os.SCHED_OTHER}") in out


def test_end_of_input_ends_the_standby_without_running_the_node(tmp_path):
    marker = tmp_path / "ran"
    script = write(tmp_path / "node", f"#!/usr/bin/python3\nopen({str(marker)!r}, 'w')\n")
    proc = start_standby(script)
    out, _ = proc.communicate("", timeout=30)
    assert proc.returncode == 0, out
    assert not marker.exists()


def test_sigint_ends_a_waiting_standby(node_script):
    proc = start_standby(node_script)
    try:
        assert wait_for(lambda: comm(proc.pid).startswith("standby:"))
        proc.send_signal(2)
        assert proc.wait(timeout=10) != 0
    finally:
        proc.kill()


def test_module_imports_are_the_module_level_ones_and_bad_ones_are_harmless(tmp_path):
    standby = load_standby_module()
    script = write(tmp_path / "node", NODE)
    relay = write(tmp_path / "relay", CATKIN_RELAY.format(source=script))
    expected = ["sys", "os", "xml.dom.minidom", "no_such_module_anywhere_xyz"]
    assert standby.module_imports(script) == expected
    assert standby.module_imports(relay) == expected
    assert standby.module_imports(str(tmp_path / "missing")) == []
    standby.preload(["no_such_module_anywhere_xyz"])    # no exception


def test_help_and_usage():
    assert subprocess.run([sys.executable, STANDBY, "--help"], capture_output=True,
                          text=True).stdout.startswith("A warm standby")
    assert subprocess.run([sys.executable, STANDBY], capture_output=True).returncode == 2
