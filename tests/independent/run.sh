#!/usr/bin/env bash
# tools/axis.py's full cycle (power, home, moves, jogs, stop, halt, error, reset) through the
# daemon against an independent implementation of one controller family (written from the
# manuals, not the project's simulators). Usage: run.sh FAMILY FIELDGATE_BIN AXIS_PY [SCENARIO]
# With SCENARIO, scenarios.py runs that scenario (home-position, abort-jog, cross-axis,
# shared-stop, negative-target) instead.
set -euo pipefail
family=$1 fieldgate=$2 axis_py=$3 scenario=${4:-}
here=$(cd "$(dirname "$0")" && pwd)
models=$(cd "$here/../../config/models" && pwd)
source "$here/../integration/lib.sh"
scratch_dir

axis_args=()
case $family in
  ims)
    unit=(ims_unit.py --axes A,B)
    bus="protocol: ims-party-line
    serial: {device: $dir/port, baud: 9600}
    timing: {reply_timeout: 200ms, byte_timeout: 30ms, probe_interval: 300ms}
    nodes:
      - {name: ims_a, address: A, model: ims-indexer, unit_id: 1, profile_unit: 11,
         limits: {target: {min: -100000, max: 100000}}}
      - {name: ims_b, address: B, model: ims-indexer, unit_id: 2, profile_unit: 12,
         limits: {target: {min: -100000, max: 100000}}}"
    units=11,12
    axis_args=(--distance 3000 --refused-target 200000)
    ;;
  copley)
    unit=(copley_unit.py --nodes 0,3)
    bus="protocol: copley-ascii
    serial: {device: $dir/port, baud: 115200}
    timing: {reply_timeout: 200ms, probe_interval: 300ms}
    nodes:
      - {name: amp0, address: 0, model: copley-amplifier, unit_id: 1, profile_unit: 21}
      - {name: amp3, address: 3, model: copley-amplifier, unit_id: 2, profile_unit: 22}"
    units=21,22
    axis_args=(--distance 20000 --expect-homed)
    ;;
  centent)
    unit=(centent_unit.py --units 0)
    bus="protocol: centent-cn0170
    serial: {device: $dir/port, baud: 9600}
    timing: {reply_timeout: 200ms, byte_timeout: 20ms, probe_interval: 300ms}
    nodes:
      - {name: table_0, address: 0, model: centent-cn0170, unit_id: 1, axis_units: {x: 21, y: 22},
         limits: {x_target: {min: -10000000, max: 10000000}, y_target: {min: -10000000, max: 10000000}}}"
    units=21,22
    axis_args=(--distance 1024000 --refused-target 20000000 --tolerance 4)
    ;;
  techno-c142 | techno-it116g | techno-c142.live | techno-it116g.live)
    # .live: the card answers @0P during a motion (the reading the manual leaves open, p.73).
    variant=${family#techno-}
    queries=deferred
    if [ "${variant%.live}" != "$variant" ]; then
      variant=${variant%.live}
      queries=live
    fi
    family=techno-$variant
    unit=(techno_unit.py --variant "$variant" --baud 19200 --queries "$queries")
    if [ "$variant" = c142 ]; then
      units_yaml="axis_units: {x: 31, y: 32, z: 33}"
      units=31,32,33
    else
      units_yaml="profile_unit: 31"
      units=31
    fi
    bus="protocol: techno-c
    serial: {device: $dir/port, baud: 19200}
    timing: {reply_timeout: 200ms, byte_timeout: 20ms, probe_interval: 300ms}
    nodes:
      - {name: techno, address: 0, model: $family, unit_id: 1, $units_yaml}"
    axis_args=(--distance 2000 --refused-target 9000000)
    ;;
  whedco | whedco.*)
    # .non-echo: the CMC-0's DIP switch SW2-5 at "non-echo" (factory: echo). .busy-first: the
    # status words with busy at bit 0 (the manual's section 4.3.1 is missing; see whedco_unit.py).
    unit=(whedco_unit.py --units 4 --axes XY --baud 38400)
    case $family in *non-echo*) unit+=(--non-echo) ;; esac
    case $family in *busy-first*) unit+=(--status-bits busy-first) ;; esac
    bus="protocol: whedco-cmc
    serial: {device: $dir/port, baud: 38400}
    timing: {reply_timeout: 200ms, byte_timeout: 20ms, probe_interval: 300ms}
    nodes:
      - {name: cmc_4, address: 4, model: whedco-cmc-xy, unit_id: 1, axis_units: {x: 41, y: 42},
         limits: {x_target: {min: -1000000, max: 1000000}, y_target: {min: -1000000, max: 1000000}}}"
    units=41,42
    axis_args=(--distance 20000 --velocity 20000 --jog-velocity 2000 --home-velocity 2000
               --refused-target 2000000)
    ;;
  *)
    echo "unknown family $family"
    exit 2
    ;;
esac

start_sim "$dir/unit.log" env PYTHONDONTWRITEBYTECODE=1 /usr/bin/python3 "$here/${unit[0]}" \
  --link "$dir/port" "${unit[@]:1}"
[ -e "$dir/port" ] || { echo "the $family unit did not start"; cat "$dir/unit.log"; exit 1; }

one_bus_config "$dir/gw.yaml" "$family"
start_daemon "$fieldgate" "$dir/gw.yaml" "$dir/daemon.log"
rc=0
if [ -n "$scenario" ]; then
  /usr/bin/python3 "$here/scenarios.py" "$scenario" --port "$port" --unit "$units" \
    "${axis_args[@]}" || rc=$?
else
  # The independent units model no device fault that Modbus alone could provoke: the gateway's
  # refusals (--refused-target) are the error these runs check.
  /usr/bin/python3 "$axis_py" --port "$port" --unit "$units" "${axis_args[@]}" --no-device-error \
    -v || rc=$?
fi
echo "--- unit log (command lines as received, each shown at most 3 times) ---"
cat "$dir/unit.log"
if [ "$rc" -ne 0 ]; then
  echo "--- daemon log ---"
  cat "$dir/daemon.log"
fi
exit "$rc"
