#!/bin/sh
# The Python every stage of dvc.yaml runs with, so that `dvc repro` works from any shell:
# $LOCOMAN_PYTHON if set; else the activated virtual environment's; else this checkout's
# .venv (what `make setup` creates); else python3 or python on the PATH. One that cannot
# import locoman stops here with what to do, before the stage starts. DVC runs `validate`
# first on every `dvc repro` (dvc.yaml), so a wrong interpreter stops the pipeline before
# DVC removes any other stage's outputs.
repo=$(cd "$(dirname "$0")/.." && pwd)
if [ -n "${LOCOMAN_PYTHON:-}" ]; then
    py=$LOCOMAN_PYTHON
elif [ -n "${VIRTUAL_ENV:-}" ] && [ -x "$VIRTUAL_ENV/bin/python" ]; then
    py=$VIRTUAL_ENV/bin/python
elif [ -x "$repo/.venv/bin/python" ]; then
    py=$repo/.venv/bin/python
elif command -v python3 >/dev/null 2>&1; then
    py=python3
elif command -v python >/dev/null 2>&1; then
    py=python
else
    echo "locoman: no Python on this machine: run \`make setup\` (it makes .venv)" >&2
    exit 2
fi
if ! "$py" -c "import locoman.stage" >/dev/null 2>&1; then
    echo "locoman: $py cannot import locoman and its dependencies. Run \`make setup\` (it" \
        "makes .venv, which the stages then use), or activate an environment with" \
        "\`pip install -e .\`, or set LOCOMAN_PYTHON to such a Python." >&2
    exit 2
fi
# MuJoCo renders off-screen through EGL unless told otherwise.
MUJOCO_GL=${MUJOCO_GL:-egl} PYOPENGL_PLATFORM=${PYOPENGL_PLATFORM:-egl} exec "$py" "$@"
