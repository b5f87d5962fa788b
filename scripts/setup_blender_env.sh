#!/usr/bin/env bash
# Create the Blender worker environment: a virtual environment of its own with bpy.
#
# bpy==5.0.1 is Blender as a Python module (Python 3.11 only) and pins numpy<2,
# which clashes with the project's .venv (numpy 2). The two never share a process:
# rigmap talks to `<env>/bin/python worker.py` over stdin/stdout.
#
# Usage: scripts/setup_blender_env.sh [ENV_DIR]   (default: .venv-blender next to this repo)
#   PYTHON=python3.11 picks the interpreter. Re-running is cheap: a stamp file
#   records the installed version and the script exits early when it matches.
set -euo pipefail

BPY_VERSION="5.0.1"
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
ENV_DIR="${1:-$ROOT/.venv-blender}"
PYTHON="${PYTHON:-python3.11}"
STAMP="$ENV_DIR/.installed-bpy-$BPY_VERSION"

if [[ -f "$STAMP" ]]; then
    echo "Blender environment ready: $ENV_DIR (bpy $BPY_VERSION)"
    exit 0
fi

if ! command -v "$PYTHON" >/dev/null 2>&1; then
    echo "error: $PYTHON not found; bpy $BPY_VERSION needs Python 3.11 (set PYTHON=...)" >&2
    exit 1
fi
version="$("$PYTHON" -c 'import sys; print("%d.%d" % sys.version_info[:2])')"
if [[ "$version" != "3.11" ]]; then
    echo "error: $PYTHON is Python $version; bpy $BPY_VERSION needs Python 3.11" >&2
    exit 1
fi

start=$(date +%s)
"$PYTHON" -m venv "$ENV_DIR"
"$ENV_DIR/bin/pip" install --quiet --upgrade pip
# bpy brings its own pins (numpy<2, ...); nothing else is installed here.
"$ENV_DIR/bin/pip" install --quiet "bpy==$BPY_VERSION"

# Prove it imports and Rigify can be enabled before declaring success.
"$ENV_DIR/bin/python" - <<'PY'
import bpy  # first: addon_utils only exists once bpy is imported
import addon_utils  # noqa: E402

addon_utils.enable("rigify", default_set=True)
assert hasattr(bpy.ops.object, "armature_human_metarig_add"), "Rigify did not register"
print("bpy", bpy.app.version_string, "with Rigify")
PY
touch "$STAMP"
echo "Blender environment ready: $ENV_DIR ($(( $(date +%s) - start )) s)"
