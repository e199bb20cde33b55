"""The package's rviz config in a real rviz on a virtual screen (Xvfb, Mesa's software GL), as the
launch files start it (nodes/rviz_for_map): every display it names loads without an error, and
the view frames each world's whole map, centred, whatever its size (the small loop's once sat
cut off in a corner of a view set for the office floor)."""
import os
import shutil
import socket
import subprocess
import sys
import time

import numpy as np
import pytest
from anyscale_core.polling import wait_for

PKG = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
MISSING = [tool for tool in ("rviz", "Xvfb", "roscore") if not shutil.which(tool)]
# rviz prints the first on Debian's build whatever the config (it is about rospack); the second
# is Mesa's software GL linking the map display's palette shader ("active samplers with a
# different type refer to the same texture image unit"), and the map is drawn all the same: the
# framing check below sees it.
HARMLESS = ("media_export", "glsl120/indexed_8bit_image")
BACKGROUND = (48, 48, 48)       # rviz's render panel where nothing is drawn
SCREEN = (1280, 800)            # nav_demo.rviz's window size


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def master_up(port):
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=1.0):
            return True
    except OSError:
        return False


def free_display():
    for n in range(90, 140):
        if not os.path.exists(f"/tmp/.X11-unix/X{n}") and not os.path.exists(f"/tmp/.X{n}-lock"):
            return f":{n}"
    pytest.skip("no free X display number")


def stop(proc):
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def bounding_box(mask):
    """(x0, y0, x1, y1), exclusive ends, of the true pixels of a 2-D mask; None if none."""
    ys, xs = np.nonzero(mask)
    return (xs.min(), ys.min(), xs.max() + 1, ys.max() + 1) if xs.size else None


def framing_faults(rgb):
    """What is wrong with how a screenshot of rviz (an H x W x 3 array) frames the map; empty
    if nothing. The render panel is the box of the rows and columns that hold rviz's background
    (at least 2 % of them: a few pixels of that grey are in the widgets' text), the map every
    other pixel inside it."""
    background = np.all(rgb == BACKGROUND, axis=2)
    cols = np.nonzero(background.sum(axis=0) >= 0.02 * rgb.shape[0])[0]
    rows = np.nonzero(background.sum(axis=1) >= 0.02 * rgb.shape[1])[0]
    if not (cols.size and rows.size):
        return ["no render panel (rviz's background) on the screen"]
    x0, y0, x1, y1 = cols.min(), rows.min(), cols.max() + 1, rows.max() + 1
    drawn = bounding_box(~background[y0:y1, x0:x1])
    if drawn is None:
        return ["nothing drawn in the render panel: no map"]
    mx0, my0, mx1, my1 = drawn
    pw, ph, mw, mh = x1 - x0, y1 - y0, mx1 - mx0, my1 - my0
    faults = []
    if mx0 == 0 or my0 == 0 or mx1 == pw or my1 == ph:
        faults.append(f"the map reaches the panel's edge (cut off): map {drawn} in a "
                      f"{pw}x{ph} panel")
    off_x, off_y = (mx0 + mx1) / 2 - pw / 2, (my0 + my1) / 2 - ph / 2
    if abs(off_x) > 0.05 * pw or abs(off_y) > 0.05 * ph:
        faults.append(f"the map is off centre by ({off_x:.0f}, {off_y:.0f}) px")
    if max(mw / pw, mh / ph) < 0.8:
        faults.append(f"the map fills only {mw}x{mh} px of the {pw}x{ph} panel")
    return faults


@pytest.mark.skipif(bool(MISSING), reason="needs " + ", ".join(MISSING) + " (scripts/setup.sh "
                                                                          "installs them)")
@pytest.mark.parametrize("world", ["office_floor", "small_loop"])
def test_rviz_frames_the_worlds_map_and_loads_without_errors(tmp_path, world):
    from PIL import ImageGrab         # python3-pil, as scripts/setup.sh installs it
    display = free_display()
    env = dict(os.environ, DISPLAY=display, LIBGL_ALWAYS_SOFTWARE="1",
               ROS_MASTER_URI=f"http://127.0.0.1:{free_port()}", ROS_HOME=str(tmp_path))
    port = env["ROS_MASTER_URI"].rsplit(":", 1)[1]
    map_yaml = os.path.join(PKG, "maps", world + ".yaml")
    procs = []
    try:
        procs.append(subprocess.Popen(["Xvfb", display, "-screen", "0", "%dx%dx24" % SCREEN],
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        procs.append(subprocess.Popen(["roscore", "-p", port], env=env,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        assert wait_for(lambda: master_up(int(port)), 30.0, 0.2), "roscore did not come up"
        procs.append(subprocess.Popen([sys.executable, os.path.join(PKG, "nodes", "map_server"),
                                       "_map_file:=" + map_yaml], env=env,
                                      stdout=open(tmp_path / "map_server.log", "w"),
                                      stderr=subprocess.STDOUT))
        log = tmp_path / "rviz.log"
        with open(log, "w") as out:
            rviz = subprocess.Popen([sys.executable, os.path.join(PKG, "nodes", "rviz_for_map"),
                                     map_yaml], env=env, stdout=out, stderr=subprocess.STDOUT)
            procs.append(rviz)
            time.sleep(25.0)            # rviz with software GL takes ~15 s to load everything
            running = rviz.poll() is None
            screenshot = ImageGrab.grab(xdisplay=display) if running else None
        text = log.read_text()
        assert running, f"rviz exited ({rviz.returncode}):\n{text}"
        errors = [line for line in text.splitlines()
                  if "ERROR" in line and not any(h in line for h in HARMLESS)]
        assert not errors, "\n".join(errors)
        assert "Loading config file" in text or "rviz version" in text, text
        shot = tmp_path / f"rviz_{world}.png"
        screenshot.save(shot)
        faults = framing_faults(np.asarray(screenshot.convert("RGB")))
        assert not faults, f"{world}: {'; '.join(faults)} (screenshot {shot})"
    finally:
        for proc in reversed(procs):
            stop(proc)
