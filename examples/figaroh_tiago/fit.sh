#!/bin/sh
# The recommended real-data fit of the FIGAROH TIAGo recordings (see fit.py):
#   examples/figaroh_tiago/fit.sh TRAIN.csv FITTED.toml [OTHER.csv ...]
# chooses the model on TRAIN.csv only, writes FITTED.toml (the robot with its effects and the
# motion-capture registration), and scores each OTHER.csv by posture group with nothing
# refitted. Then, for any other recording:
#   rfsw-plan validate --robot FITTED.toml --data OTHER.csv \
#       --columns examples/figaroh_tiago/columns.toml --frame device --json
# PYTHON selects the interpreter (default: the project's .venv, else python3).
set -eu
here=$(cd "$(dirname "$0")" && pwd)
if [ -z "${PYTHON:-}" ]; then
    if [ -x "$here/../../.venv/bin/python" ]; then PYTHON="$here/../../.venv/bin/python"; else PYTHON=python3; fi
fi
if [ "$#" -lt 2 ]; then
    echo "usage: $0 TRAIN.csv FITTED.toml [OTHER.csv ...]" >&2
    exit 2
fi
exec "$PYTHON" "$here/fit.py" "$@"
