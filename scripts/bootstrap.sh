#!/usr/bin/env bash
# Set up longslam on a fresh machine and run one task: `demo` or `test`.
#   bash scripts/bootstrap.sh demo   # installs everything, runs `longslam demo`
#   bash scripts/bootstrap.sh test   # installs everything (with test extras), runs the tests
# Extra arguments go to the task (e.g. `bash scripts/bootstrap.sh test -k metrics`).
set -euo pipefail
cd "$(dirname "$0")/.."

task="${1:-}"
shift || true
case "$task" in
  demo|test) ;;
  *) echo "usage: bash scripts/bootstrap.sh demo|test [args...]" >&2; exit 2 ;;
esac

PYTHON="${PYTHON:-python3}"
VENV="${VENV:-.venv}"

# Open3D's wheel links against libusb and libgomp, which a minimal Debian does not have.
missing=()
for lib in libusb-1.0.so.0:libusb-1.0-0 libgomp.so.1:libgomp1; do
  so="${lib%%:*}"; pkg="${lib##*:}"
  ldconfig -p 2>/dev/null | grep -q "$so" || missing+=("$pkg")
done
if ((${#missing[@]})); then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    echo "installing system packages: ${missing[*]}"
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
  else
    echo "error: Open3D needs the system packages: ${missing[*]}" >&2
    echo "install them first, e.g.: sudo apt-get install ${missing[*]}" >&2
    exit 1
  fi
fi

# The ORB-SLAM3 plugin (plugins/longslam-orbslam3, GPL-3.0) needs pyorbslam3's OpenGL/X11 runtime
# libraries even headless; without them (and no root to install them) longslam runs without it.
PLUGIN=plugins/longslam-orbslam3
plugin_missing=()
for lib in libGL.so.1:libgl1 libEGL.so.1:libegl1 libOpenGL.so.0:libopengl0 libSM.so.6:libsm6 libICE.so.6:libice6 \
           libX11.so.6:libx11-6 libXext.so.6:libxext6; do
  so="${lib%%:*}"; pkg="${lib##*:}"
  ldconfig -p 2>/dev/null | grep -q "$so" || plugin_missing+=("$pkg")
done
with_plugin=1
if ((${#plugin_missing[@]})); then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    echo "installing system packages for the orbslam3 plugin: ${plugin_missing[*]}"
    { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${plugin_missing[@]}" >/dev/null; } \
      || { echo "warning: could not install ${plugin_missing[*]}; setting up without the orbslam3 plugin" >&2; with_plugin=0; }
  else
    echo "warning: the orbslam3 plugin needs the system packages ${plugin_missing[*]} (e.g. sudo apt-get install ${plugin_missing[*]}); setting up without it" >&2
    with_plugin=0
  fi
fi

# The same pinned versions on every machine: requirements.lock (made for Python 3.11, test extras
# included, so `demo` and `test` share one environment), then longslam itself without resolving
# its ranges again.
LOCK=requirements.lock
stamp="$VENV/.installed-lock"
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ] || [ "$LOCK" -nt "$stamp" ] \
   || [ "$PLUGIN/pyproject.toml" -nt "$stamp" ] || [ "$PLUGIN/requirements.lock" -nt "$stamp" ] \
   || { [ "$with_plugin" = 1 ] && ! "$VENV/bin/python" -c "import longslam_orbslam3" 2>/dev/null; }; then
  [ -x "$VENV/bin/python" ] || "$PYTHON" -m venv "$VENV"
  version="$("$VENV/bin/python" -c 'import sys; print("%d.%d" % sys.version_info[:2])')"
  [ "$version" = 3.11 ] || echo "warning: $LOCK pins versions for Python 3.11; $VENV has Python $version" >&2
  "$VENV/bin/python" -m pip install -q --upgrade pip
  "$VENV/bin/python" -m pip install -q -r "$LOCK"
  "$VENV/bin/python" -m pip install -q --no-deps -e .
  if [ "$with_plugin" = 1 ]; then
    # A plugin like any third party's: its own distribution, reached through the entry point.
    "$VENV/bin/python" -m pip install -q --no-deps -r "$PLUGIN/requirements.lock"
    "$VENV/bin/python" -m pip install -q --no-deps -e "$PLUGIN"
  fi
  touch "$stamp"
fi

if [ "$task" = demo ]; then
  exec "$VENV/bin/longslam" demo "$@"
else
  exec "$VENV/bin/python" -m pytest "$@"
fi
