#!/bin/sh
# The recommended real-data fit of the FIGAROH TIAGo recordings, as one `rfsw-plan calibrate`:
#   examples/figaroh_tiago/fit.sh TRAIN.csv FITTED.toml [OTHER.csv ...]
# chooses the model on TRAIN.csv only (registration of the motion-capture frame and the marker,
# the geometry, then the effects the workbench's diagnosis finds significant), writes FITTED.toml,
# and scores each OTHER.csv with nothing refitted: the motion-capture base body is the same in
# every session, so the registration is kept (--keep-registration). The same for any recording:
#   rfsw-plan validate --robot FITTED.toml --data OTHER.csv \
#       --columns examples/figaroh_tiago/columns.toml --frame device --json
# examples/figaroh_tiago/fit.py prints more on the same choice (posture groups, arm_6's play).
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
train=$1
fitted=$2
shift 2
PYTHONPATH="$here/../..${PYTHONPATH:+:$PYTHONPATH}"
export PYTHONPATH
"$PYTHON" -m rfsw_plan.cli.main calibrate --robot tiago_arm --data "$train" \
    --columns "$here/columns.toml" --frame device --keep-registration --save-robot "$fitted"
for other in "$@"; do
    "$PYTHON" -m rfsw_plan.cli.main validate --robot "$fitted" --data "$other" \
        --columns "$here/columns.toml" --frame device --no-report --json |
        "$PYTHON" -c 'import json, sys; j = json.load(sys.stdin); print("%s: held out, nothing refitted: %.2f mm 3-D RMS of point BL over %d postures" % (sys.argv[1], j["rms_3d_mm"], j["n_samples"]))' "$(basename "$other")"
done
