# Sourced by the axis tests: starts one family's simulator on $dir/port and sets, for the
# daemon's config and the axis drivers, bus (the bus's YAML after its name, for a line indented
# four spaces), units (the profile unit IDs, comma-separated) and axis_args (tools/axis.py
# options fitting the family). The simulator is a job of the calling shell; its control channel
# (stdin) is the FIFO $dir/sim.in, through which --fault-command injects a device fault.
# The error each family can give (tools/axis.py): Techno refuses a move beyond its travel ('2');
# Copley and Whedco report a latched fault (injected); Copley also refuses motion while disabled.
# IMS and Centent have no error to provoke: their manuals define no error reply to a well-formed
# command (Centent's only one is for syntax) and no fault state; IMS's encoder-error input (]1
# bit 2, encoder option) has no stated active level, so the model does not map it, and the
# simulator has no encoder. The gateway's limit refusal is checked instead.
# Usage: axis_family_start FAMILY BUILD_DIR DIR
axis_family_start() {
  local family=$1 build=$2 dir=$3 variant units_yaml
  axis_args=()
  mkfifo "$dir/sim.in"
  # Held open read-write by the calling shell: the simulator never reads EOF, a writer never blocks.
  exec {sim_control}<>"$dir/sim.in"
  case $family in
    copley)
      "$build/sim/copley/fieldgate-sim-copley" --link "$dir/port" --nodes 0,3 <"$dir/sim.in" \
        >"$dir/sim.log" 2>&1 &
      bus="protocol: copley-ascii
    serial: {device: $dir/port, baud: 115200}
    timing: {reply_timeout: 150ms, probe_interval: 300ms}
    nodes:
      - {name: amp0, address: 0, model: copley-amplifier, unit_id: 1, profile_unit: 21}
      - {name: amp3, address: 3, model: copley-amplifier, unit_id: 2, profile_unit: 22}"
      units=21,22
      # Following error (0xa4 bit 9) on the amplifier of the axis under test.
      axis_args=(--distance 20000 --expect-homed --fault-command
                 'case {unit} in 21) n=0 ;; *) n=3 ;; esac; echo "fault $n 512" >'"$dir/sim.in")
      ;;
    copley-slow-poll)
      # Copley with its status polled once a second: power_on's confirmation comes long before
      # the poll that shows the axis enabled (the profile's power_on must wait for that poll).
      "$build/sim/copley/fieldgate-sim-copley" --link "$dir/port" --nodes 0 <"$dir/sim.in" \
        >"$dir/sim.log" 2>&1 &
      bus="protocol: copley-ascii
    serial: {device: $dir/port, baud: 115200}
    timing: {reply_timeout: 150ms, probe_interval: 300ms}
    nodes:
      - {name: amp0, address: 0, model: copley-amplifier, unit_id: 1, profile_unit: 21,
         poll: {fast: 1s}}"
      units=21
      axis_args=(--distance 20000 --expect-homed)
      ;;
    ims)
      "$build/sim/ims/fieldgate-sim-ims" --link "$dir/port" --axes A,B <"$dir/sim.in" \
        >"$dir/sim.log" 2>&1 &
      bus="protocol: ims-party-line
    serial: {device: $dir/port, baud: 9600}
    timing: {reply_timeout: 100ms, byte_timeout: 30ms, probe_interval: 300ms}
    nodes:
      - {name: ims_a, address: A, model: ims-indexer, unit_id: 1, profile_unit: 11,
         limits: {target: {min: -100000, max: 100000}}}
      - {name: ims_b, address: B, model: ims-indexer, unit_id: 2, profile_unit: 12,
         limits: {target: {min: -100000, max: 100000}}}"
      units=11,12
      axis_args=(--distance 3000 --refused-target 200000 --no-device-error)
      ;;
    centent)
      "$build/sim/centent/fieldgate-sim-centent" --link "$dir/port" --units 0 --power-up \
        <"$dir/sim.in" >"$dir/sim.log" 2>&1 &
      bus="protocol: centent-cn0170
    serial: {device: $dir/port, baud: 9600}
    timing: {reply_timeout: 200ms, byte_timeout: 20ms, probe_interval: 300ms}
    nodes:
      - {name: table_0, address: 0, model: centent-cn0170, unit_id: 1, axis_units: {x: 21, y: 22},
         limits: {x_target: {min: -10000000, max: 10000000}, y_target: {min: -10000000, max: 10000000}}}"
      units=21,22
      axis_args=(--distance 1024000 --refused-target 20000000 --tolerance 4 --no-device-error)
      ;;
    whedco)
      "$build/sim/whedco/fieldgate-sim-whedco" --link "$dir/port" --units 4 --axes XY \
        --baud 38400 <"$dir/sim.in" >"$dir/sim.log" 2>&1 &
      bus="protocol: whedco-cmc
    serial: {device: $dir/port, baud: 38400}
    timing: {reply_timeout: 50ms, byte_timeout: 10ms, probe_interval: 300ms}
    nodes:
      - {name: cmc_4, address: 4, model: whedco-cmc-xy, unit_id: 1, axis_units: {x: 41, y: 42},
         limits: {x_target: {min: -1000000, max: 1000000}, y_target: {min: -1000000, max: 1000000}}}"
      units=41,42
      # Excessive following error (code 3) on the axis under test.
      axis_args=(--distance 20000 --velocity 20000 --jog-velocity 2000 --home-velocity 2000
                 --refused-target 2000000 --fault-command
                 'case {unit} in 41) a=X ;; *) a=Y ;; esac; echo "fault 4 $a 3" >'"$dir/sim.in")
      ;;
    whedco-cmc)
      "$build/sim/whedco/fieldgate-sim-whedco" --link "$dir/port" --units 4 --axes WXYZ \
        --baud 38400 <"$dir/sim.in" >"$dir/sim.log" 2>&1 &
      bus="protocol: whedco-cmc
    serial: {device: $dir/port, baud: 38400}
    timing: {reply_timeout: 50ms, byte_timeout: 10ms, probe_interval: 300ms}
    nodes:
      - {name: cmc_4, address: 4, model: whedco-cmc, unit_id: 1,
         axis_units: {x: 41, y: 42, w: 43, z: 44},
         limits: {x_target: {min: -1000000, max: 1000000}, y_target: {min: -1000000, max: 1000000},
                  w_target: {min: -1000000, max: 1000000}, z_target: {min: -1000000, max: 1000000}}}"
      units=41,42,43,44
      # Excessive following error (code 3) on the axis under test.
      axis_args=(--distance 20000 --velocity 20000 --jog-velocity 2000 --home-velocity 2000
                 --refused-target 2000000 --fault-command
                 'case {unit} in 41) a=X ;; 42) a=Y ;; 43) a=W ;; *) a=Z ;; esac
                  echo "fault 4 $a 3" >'"$dir/sim.in")
      ;;
    techno-c10 | techno-c116 | techno-c142 | techno-it116g)
      variant=${family#techno-}
      "$build/sim/techno/fieldgate-sim-techno" --link "$dir/port" --variant "$variant" \
        --baud 19200 <"$dir/sim.in" >"$dir/sim.log" 2>&1 &
      case $variant in
        c10)
          units_yaml="axis_units: {x: 31, y: 32}"
          units=31,32
          ;;
        c116 | c142)
          units_yaml="axis_units: {x: 31, y: 32, z: 33}"
          units=31,32,33
          ;;
        *)
          units_yaml="profile_unit: 31"
          units=31
          ;;
      esac
      bus="protocol: techno-c
    serial: {device: $dir/port, baud: 19200}
    timing: {reply_timeout: 100ms, byte_timeout: 20ms, probe_interval: 300ms}
    nodes:
      - {name: techno, address: 0, model: $family, unit_id: 1, $units_yaml}"
      # Beyond the simulator's travel (100000 steps from the home switch): the controller
      # answers 2, "outside the reach of the axes".
      axis_args=(--distance 2000 --refused-target 9000000 --beyond 200000)
      ;;
    canopen)
      # Needs a kernel SocketCAN interface: run under scripts/vcan-run (tests/vcan).
      "$build/sim/canopen/fieldgate-sim-canopen" --interface "${FIELDGATE_VCAN_IF:-vcan0}" \
        --nodes 2 <"$dir/sim.in" >"$dir/sim.log" 2>&1 &
      bus="protocol: canopen
    can: {interface: ${FIELDGATE_VCAN_IF:-vcan0}}
    timing: {reply_timeout: 500ms, retries: 1, offline_after: 3, probe_interval: 300ms,
             heartbeat_timeout: 500ms, start_nodes: true}
    nodes:
      - {name: drive_2, address: 2, model: canopen-cia402, unit_id: 1, profile_unit: 21}"
      units=21
      axis_args=(--distance 4000 --no-device-error)
      for _ in $(seq 100); do grep -q '^ready' "$dir/sim.log" && return 0; sleep 0.1; done
      echo "the CANopen simulator did not start"
      cat "$dir/sim.log"
      return 1
      ;;
    *)
      echo "unknown family $family"
      return 2
      ;;
  esac
  for _ in $(seq 50); do [ -e "$dir/port" ] && break; sleep 0.1; done
}
