#!/usr/bin/env bash
# tools/axis.py, which knows only the axis profile page, against the real daemon and one family's
# simulator: power, home, moves, jogs, stop, halt, an error and its reset, every transition
# checked. Usage: axis_profile.sh FAMILY FIELDGATE BUILD_DIR MODELS_DIR AXIS_PY
set -euo pipefail
family=$1 fieldgate=$2 build=$3 models=$4 axis_py=$5
here=$(cd "$(dirname "$0")" && pwd)
source "$here/lib.sh"
source "$here/axis_family.sh"
scratch_dir

axis_family_start "$family" "$build" "$dir"
one_bus_config "$dir/gw.yaml" "$family"
start_daemon "$fieldgate" "$dir/gw.yaml" "$dir/daemon.log"
rc=0
/usr/bin/python3 "$axis_py" --port "$port" --unit "$units" "${axis_args[@]}" -v || rc=$?
if [ "$rc" -ne 0 ]; then
  echo "--- daemon log ---"
  cat "$dir/daemon.log"
fi
exit "$rc"
