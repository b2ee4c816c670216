#!/usr/bin/env bash
# tools/axis.py's full cycle (power, home, moves, jogs, stop, halt, error, reset) through the
# daemon against an independent implementation of one controller family (written from the
# manuals, not the project's simulators). Usage: run.sh FAMILY FIELDGATE_BIN AXIS_PY [SCENARIO]
# With SCENARIO, scenarios.py runs that scenario (home-position, abort-jog, cross-axis,
# shared-stop, negative-target, reset-mid-move, simultaneous-axes, home-no-velocity) instead.
# Every unit gets a control socket, $dir/unit.ctl (unit_common.Control: power-cycle, state),
# which the scenarios and the done property tests use to power-cycle the unit and to read its
# own positions.
set -euo pipefail
family=$1 fieldgate=$2 axis_py=$3 scenario=${4:-}
here=$(cd "$(dirname "$0")" && pwd)
models=$(cd "$here/../../config/models" && pwd)
protocols=$(cd "$here/../../config/protocols" && pwd)
source "$here/../integration/lib.sh"
source "$here/../integration/axis_family.sh"
scratch_dir

axis_args=()
log_check=()  # patterns (grep -E) the daemon log must match after the run
control=(--control "$dir/unit.ctl")
scenario_args=()  # scenarios.py options: the unit's axis names, what a reset ends with
case $family in
  ims)
    unit=(ims_unit.py --axes A,B "${control[@]}")
    axis_family_bus ims "$dir/port" 200ms
    axis_args=(--distance 3000 --refused-target 200000)
    # A reset is not seen on the line (party mode, no sign-on); the origin becomes 0.
    scenario_args=(--unit-axes 11=A,12=B --reset-codes 0xffec,0xfffa)
    ;;
  copley | copley.pauses)
    # .pauses: the gateway amp stops answering for 230 ms every 2 s, beyond the 200 ms reply
    # timeout, then answers its backlog (issue 26).
    unit=(copley_unit.py --nodes 0,3 "${control[@]}")
    [ "$family" = copley.pauses ] && unit+=(--pause-ms 230 --pause-every-ms 2000)
    family=copley
    axis_family_bus copley "$dir/port" 200ms
    axis_args=(--distance 20000 --expect-homed)
    scenario_args=(--unit-axes 21=0,22=3 --reset-codes 0xffec,0xfffa)
    ;;
  centent | centent.*)
    # .power-up-m3: the unit powers up in Operate Mode (M3), where it discards the host's
    # instructions (see centent_unit.py).
    unit=(centent_unit.py --units 0 "${control[@]}")
    case $family in *power-up-m3*) unit+=(--power-up-mode 3) ;; esac
    axis_family_bus centent "$dir/port" 200ms 20ms
    axis_args=(--distance 1024000 --refused-target 20000000 --tolerance 4)
    # A reset is the unit's U0 (answering the leading CR of the next transmission); a move
    # interrupted early may end "away from its target" before the reset counter is read again.
    scenario_args=(--unit-axes 21=0X,22=0Y --reset-codes 0xfffa,0xffec)
    ;;
  techno-c142 | techno-it116g | techno-c142.live | techno-it116g.live | techno-*.p-cr)
    # .live: the card answers @0P during a motion (the reading the manual leaves open, p.73).
    # .p-cr: the card ends the @0P reply with a CR (the P reply's terminator is left open).
    variant=${family#techno-}
    queries=deferred
    p_cr=()
    if [ "${variant%.p-cr}" != "$variant" ]; then
      variant=${variant%.p-cr}
      p_cr=(--p-reply-cr)
    fi
    if [ "${variant%.live}" != "$variant" ]; then
      variant=${variant%.live}
      queries=live
    fi
    family=techno-$variant
    unit=(techno_unit.py --variant "$variant" --baud 19200 --queries "$queries" "${p_cr[@]}"
          "${control[@]}")
    axis_family_bus "$family" "$dir/port" 200ms 20ms
    axis_args=(--distance 2000 --refused-target 9000000)
    # A reset is the card's 4 (axes not defined) to the next command, or no acknowledge of the
    # running motion (0xfffc).
    scenario_args=(--unit-axes 31=X,32=Y,33=Z --reset-codes 4,0xfffc,0xfffa,0xffec)
    ;;
  whedco | whedco.*)
    # .non-echo: the CMC-0's DIP switch SW2-5 at "non-echo" (factory: echo). .busy-first: the
    # status words with busy at bit 0 (the manual's section 4.3.1 is missing; see whedco_unit.py);
    # .busy-first-homed: and bit 2 = homed (a homed axis at rest reads 0x0614).
    unit=(whedco_unit.py --units 4 --axes XY --baud 38400 "${control[@]}")
    case $family in *non-echo*) unit+=(--non-echo) ;; esac
    case $family in
      *busy-first-homed*) unit+=(--status-bits busy-first-homed) ;;
      *busy-first*) unit+=(--status-bits busy-first) ;;
    esac
    axis_family_bus whedco "$dir/port" 200ms 20ms
    case $family in
      *busy-first*) ;;
      *)
        # The outputs layout is a choice of the model (status_layout), not detected: no word
        # tells the layouts apart (drivers/whedco_cmc/README.md, "Status words").
        mkdir "$dir/models"
        sed 's/^model: whedco-cmc-xy$/model: whedco-cmc-xy-outputs\noptions: {status_layout: outputs}/' \
          "$models/whedco-cmc-xy.yaml" >"$dir/models/whedco-cmc-xy-outputs.yaml"
        bus=${bus//model: whedco-cmc-xy,/model: whedco-cmc-xy-outputs,}
        models="[$models, $dir/models]"
        ;;
    esac
    axis_args=(--distance 20000 --velocity 20000 --jog-velocity 2000 --home-velocity 2000
               --refused-target 2000000)
    # A reset is the Power Failure status of the restarted unit (the actions' failed: condition).
    scenario_args=(--unit-axes 41=4X,42=4Y --reset-codes 0xfffe,0xfffa,0xffec)
    ;;
  copley-file)
    # The copley-ascii family out of the configuration: the same unit, behind the protocol file
    # config/protocols/copley-ascii-file.yaml and its model copley-amplifier-file.
    unit=(copley_unit.py --nodes 0,3 "${control[@]}")
    axis_family_bus copley-ascii-file "$dir/port" 200ms
    axis_args=(--distance 20000 --expect-homed)
    ;;
  smc100)
    # Newport SMC100, run by its protocol file (config/protocols/newport-smc100.yaml): no C++
    # of its own. Positions in 0.0001 mm; the controllers' software limits are +-25 mm.
    # With the wire trace on: its lines name each command and the reply's captures.
    unit=(smc100_unit.py --addresses 1,2 "${control[@]}")
    axis_family_bus newport-smc100 "$dir/port" 200ms 20ms
    bus="trace: true
    $bus"
    log_check=("trace smc100 \([0-9.]+\) smc_1 tx ok '1TS\\\\r\\\\n' read_state\$"
      "trace smc100 \([0-9.]+\) smc_1 rx ok '1TS[0-9A-F]{6}\\\\r\\\\n' read_state errors=[0-9A-F]{4} state=[0-9A-F]{2}\$"
      "trace smc100 \([0-9.]+\) smc_2 rx ok '2TP[-0-9.]+\\\\r\\\\n' read_position position=[-0-9.]+\$")
    axis_args=(--distance 20000 --refused-target 300000 --expect-homed)
    ;;
  esp301)
    # Newport ESP301 axes 1 and 2, run by its protocol file (config/protocols/newport-esp301.yaml).
    # At start-up the file counts the axes: 1 and 2 answer MO?, 3 is error 9.
    unit=(esp301_unit.py --axes 1,2 "${control[@]}")
    axis_family_bus newport-esp301 "$dir/port" 200ms 20ms
    log_check=("bus esp301: start-up: probe_axis found 1\.\.2; probe_axis 3: device error \(read_error error 9")
    axis_args=(--distance 20000 --refused-target 300000)
    ;;
  parker6k)
    # Parker 6K2 axes 1 and 2, run by its protocol file (config/protocols/parker-6k.yaml).
    unit=(parker6k_unit.py --axes 2 "${control[@]}")
    axis_family_bus parker-6k "$dir/port" 200ms 20ms
    axis_args=(--distance 20000 --refused-target 600000 --expect-homed)
    ;;
  galil)
    # Galil DMC axes A and B of one controller, run by its protocol file
    # (config/protocols/galil-dmc.yaml). A refusal ('?') is explained by TC1.
    unit=(galil_unit.py --axes AB "${control[@]}")
    axis_family_bus galil-dmc "$dir/port" 200ms 20ms
    axis_args=(--distance 20000 --refused-target 2000000)
    scenario_args=(--unit-axes 81=A,82=B --reset-codes 0xffec,0xfffa)
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
    "${axis_args[@]}" "${control[@]}" "${scenario_args[@]}" || rc=$?
else
  # The independent units model no device fault that Modbus alone could provoke: the gateway's
  # refusals (--refused-target) are the error these runs check.
  /usr/bin/python3 "$axis_py" --port "$port" --unit "$units" "${axis_args[@]}" --no-device-error \
    -v || rc=$?
fi
for pattern in "${log_check[@]}"; do
  grep -qE "$pattern" "$dir/daemon.log" || { echo "FAIL: no log line matches $pattern"; rc=1; }
done
echo "--- unit log (command lines as received, each shown at most 3 times) ---"
cat "$dir/unit.log"
if [ "$rc" -ne 0 ] || [ -n "${INDEPENDENT_DAEMON_LOG:-}" ]; then
  echo "--- daemon log ---"
  cat "$dir/daemon.log"
fi
exit "$rc"
