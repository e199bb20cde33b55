"""The test bed's calibration file (anyscale_nav_demo/config/testbed_calibration.yaml) and the
nav demo's files: the CPU quotas each scale runs at unless told otherwise, and the host-speed
reference of --normalise-cpu. Errors end the command with one line that names the file and key."""
import os
import subprocess
import sys

import yaml


def nav_demo_path(*parts) -> str:
    out = subprocess.run(["rospack", "find", "anyscale_nav_demo"], capture_output=True,
                         text=True)
    if out.returncode != 0:
        sys.exit("run_testbed: anyscale_nav_demo not found; source devel/setup.bash first")
    return os.path.join(out.stdout.strip(), *parts)


def calibrated_cores(path: str):
    """(robot, laptop) CPU quota in cores from the calibration file."""
    try:
        with open(path) as f:
            calibration = yaml.safe_load(f) or {}
        return float(calibration["robot_cpu_cores"]), float(calibration["laptop_cpu_cores"])
    except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError) as e:
        sys.exit(f"run_testbed: {path}: robot_cpu_cores / laptop_cpu_cores: {e}")


def calibrated_reference_ms(path: str) -> float:
    """The host-speed workload's CPU ms at which the calibration's quotas were right."""
    try:
        with open(path) as f:
            reference = float((yaml.safe_load(f) or {})["reference_cpu_ms"])
    except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError) as e:
        sys.exit(f"run_testbed: --normalise-cpu: {path}: reference_cpu_ms: {e}")
    if not reference > 0:
        sys.exit(f"run_testbed: --normalise-cpu: {path}: reference_cpu_ms must be positive, "
                 f"got {reference:g}")
    return reference


def quota_cores(robot_cpu, laptop_cpu):
    """(robot, laptop) CPU quota in cores: those given, the calibration file's for a None."""
    if robot_cpu is None or laptop_cpu is None:
        calibrated = calibrated_cores(nav_demo_path("config", "testbed_calibration.yaml"))
        robot_cpu = calibrated[0] if robot_cpu is None else robot_cpu
        laptop_cpu = calibrated[1] if laptop_cpu is None else laptop_cpu
    return robot_cpu, laptop_cpu
