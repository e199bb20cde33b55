#!/usr/bin/env bash
# Installs what the AnyScale workspace needs (Debian 12 packages only) and builds it.
# Idempotent: packages already installed are not asked for again, and catkin_make
# rebuilds only what changed. Source it to get the workspace environment:
#   source scripts/setup.sh
# No `set -e` here: a sourced script must not change the options of the user's shell.

ANYSCALE_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# ROS tools and catkin must run on Debian's Python, not a python3 earlier on PATH
# (see ../shared/ENVIRONMENT.md: "Two Pythons").
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:$PATH"

ANYSCALE_APT_PACKAGES=(
  # build tools, ROS 1 core, build and test tooling
  cmake make g++
  ros-core-dev catkin python3-catkin-pkg
  # the linters tests/test_lint.py runs
  catkin-lint flake8 clang-format
  python3-rospy libroscpp-dev python3-roslaunch python3-rosgraph
  python3-rostest librostest-dev libgtest-dev
  python3-rostopic python3-rosnode python3-rosparam python3-rosbag
  ros-message-generation python3-genpy python3-gencpp
  # messages
  libstd-msgs-dev python3-std-msgs libstd-srvs-dev python3-std-srvs
  libgeometry-msgs-dev python3-geometry-msgs libsensor-msgs-dev python3-sensor-msgs
  libnav-msgs-dev python3-nav-msgs libvisualization-msgs-dev python3-visualization-msgs
  libdiagnostic-msgs-dev python3-diagnostic-msgs libtf2-msgs-dev python3-tf2-msgs
  # ROS libraries the nodes use
  topic-tools libtopic-tools-dev python3-topic-tools libyaml-cpp-dev
  python3-tf2-ros libtf2-ros-dev python3-message-filters
  python3-diagnostic-updater libdiagnostic-updater-dev python3-cv-bridge
  # rviz, and a virtual screen to check the rviz config in the tests
  rviz xvfb libgl1-mesa-dri
  # Python libraries for /usr/bin/python3
  python3-numpy python3-scipy python3-psutil python3-yaml python3-opencv
  python3-matplotlib python3-pil python3-pytest python3-hypothesis python3-tqdm
  # the two-scale test bed: namespaces, shaping, processes
  iproute2 procps
)

anyscale_missing_packages() {
  local pkg
  for pkg in "${ANYSCALE_APT_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || echo "$pkg"
  done
}

anyscale_install_packages() {
  local missing
  missing=$(anyscale_missing_packages)
  if [ -z "$missing" ]; then
    echo "[anyscale setup] all Debian packages present"
    return 0
  fi
  if [ "$(id -u)" -ne 0 ]; then
    echo "[anyscale setup] missing packages and not root; install them with:" >&2
    echo "  sudo apt-get install -y --no-install-recommends $(echo $missing)" >&2
    return 1
  fi
  echo "[anyscale setup] installing: $(echo $missing)"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  # shellcheck disable=SC2086
  apt-get install -y -qq --no-install-recommends $missing >/dev/null
}

# What catkin_make does, called directly: catkin_make refuses a base path that holds a
# package.xml, and the root holds the stack's metapackage manifest. Make targets (e.g.
# run_tests) may be passed as arguments.
anyscale_build() {
  echo "[anyscale setup] building the workspace ${*:-}"
  local log="$ANYSCALE_ROOT/build/build.log"
  mkdir -p "$ANYSCALE_ROOT/build"
  {
    cmake -S "$ANYSCALE_ROOT/src" -B "$ANYSCALE_ROOT/build" \
      -DCATKIN_DEVEL_PREFIX="$ANYSCALE_ROOT/devel" -DCMAKE_INSTALL_PREFIX="$ANYSCALE_ROOT/install" \
      -DPYTHON_EXECUTABLE=/usr/bin/python3 -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    && make -C "$ANYSCALE_ROOT/build" -j"$(nproc)" "$@"
  } > "$log" 2>&1 || {
    tail -n 60 "$log" >&2
    echo "[anyscale setup] build failed; full log: $log" >&2
    return 1
  }
}

anyscale_setup_main() {
  anyscale_install_packages || return 1
  anyscale_build || return 1
  # shellcheck disable=SC1091
  source "$ANYSCALE_ROOT/devel/setup.bash" || return 1
  echo "[anyscale setup] workspace ready: $ANYSCALE_ROOT/devel"
}

# Sourced: leave the environment set up. Executed: just install and build.
if [ "${BASH_SOURCE[0]}" != "$0" ]; then
  anyscale_setup_main
else
  anyscale_setup_main || exit 1
fi
