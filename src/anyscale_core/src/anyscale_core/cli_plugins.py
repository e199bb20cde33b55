"""`anyscale` sub-commands of other packages, registered as ROS plugins are (pluginlib's way):
a package that depends on anyscale_core exports <anyscale_core cli="python.module"/> in its
package.xml, and that module's add_parsers(sub) adds its commands. A robot without the package
has no such command, and the core never imports it."""
import importlib
import subprocess
import sys
from typing import Callable, List, Tuple

# Commands of packages a robot need not have: what to install when one is asked for.
KNOWN_ELSEWHERE = {"simulate": "anyscale_study (the paper's Fig. 7 study)"}


def registered_modules(run: Callable = subprocess.run) -> List[Tuple[str, str]]:
    """(package, module) of every registered plugin, through `rospack plugins`; none where
    rospack is missing or fails (no ROS_PACKAGE_PATH)."""
    try:
        done = run(["rospack", "plugins", "--attrib=cli", "anyscale_core"],
                   capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        return []
    if done.returncode != 0:
        return []
    pairs = [line.split(None, 1) for line in done.stdout.splitlines() if line.strip()]
    return sorted((p[0], p[1].strip()) for p in pairs if len(p) == 2)


def add_plugin_parsers(sub, modules: List[Tuple[str, str]], warn=None):
    """Adds each registered module's commands; one that cannot be imported is named on
    stderr and left out, the others still work."""
    warn = warn or (lambda text: print(text, file=sys.stderr))
    for package, module in modules:
        try:
            importlib.import_module(module).add_parsers(sub)
        except Exception as e:      # noqa: BLE001 - a broken plugin must not break the CLI
            warn(f"anyscale: the commands of {package} ({module}) are left out: "
                 f"{type(e).__name__}: {e}")
