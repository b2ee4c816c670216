# Sourced after lib.sh by the axis tests, and by tests/independent/run.sh for the bus alone: one
# family's bus and simulator. The error each family can give (tools/axis.py): Techno refuses a
# move beyond its travel ('2'); Copley and Whedco report a latched fault (injected); Copley also
# refuses motion while disabled. IMS and Centent have no error to provoke: their manuals define
# no error reply to a well-formed command (Centent's only one is for syntax) and no fault state;
# IMS's encoder-error input (]1 bit 2, encoder option) has no stated active level, so the model
# does not map it, and the simulator has no encoder. The gateway's limit refusal is checked
# instead.

# axis_family_bus FAMILY DEVICE [REPLY_TIMEOUT [BYTE_TIMEOUT]]: sets bus (the bus's YAML after
# its name, for a line indented four spaces) and units (the profile unit IDs, comma-separated)
# for FAMILY's units on DEVICE. The timeouts default to what the project's simulator needs.
axis_family_bus() {
  local family=$1 device=$2 reply=${3:-} byte=${4:-} protocol baud timing nodes
  local target="{min: -1000000, max: 1000000}"
  case $family in
    copley)
      protocol=copley-ascii baud=115200 timing="reply_timeout: ${reply:-150ms}"
      nodes="      - {name: amp0, address: 0, model: copley-amplifier, unit_id: 1, profile_unit: 21}
      - {name: amp3, address: 3, model: copley-amplifier, unit_id: 2, profile_unit: 22}"
      units=21,22
      ;;
    copley-slow-poll)
      # Copley with its status polled once a second: power_on's confirmation comes long before
      # the poll that shows the axis enabled (the profile's power_on must wait for that poll).
      protocol=copley-ascii baud=115200 timing="reply_timeout: ${reply:-150ms}"
      nodes="      - {name: amp0, address: 0, model: copley-amplifier, unit_id: 1, profile_unit: 21,
         poll: {fast: 1s}}"
      units=21
      ;;
    ims)
      protocol=ims-party-line baud=9600
      timing="reply_timeout: ${reply:-100ms}, byte_timeout: ${byte:-30ms}"
      nodes="      - {name: ims_a, address: A, model: ims-indexer, unit_id: 1, profile_unit: 11,
         limits: {target: {min: -100000, max: 100000}}}
      - {name: ims_b, address: B, model: ims-indexer, unit_id: 2, profile_unit: 12,
         limits: {target: {min: -100000, max: 100000}}}"
      units=11,12
      ;;
    centent)
      protocol=centent-cn0170 baud=9600
      timing="reply_timeout: ${reply:-200ms}, byte_timeout: ${byte:-20ms}"
      nodes="      - {name: table_0, address: 0, model: centent-cn0170, unit_id: 1, axis_units: {x: 21, y: 22},
         limits: {x_target: {min: -10000000, max: 10000000}, y_target: {min: -10000000, max: 10000000}}}"
      units=21,22
      ;;
    whedco)
      # 150 ms, not the 50 a CMC needs: on a loaded test host (eight tests on two cores) the
      # simulator answered after 50 ms, and the profile's home then failed with 0x0b.
      protocol=whedco-cmc baud=38400
      timing="reply_timeout: ${reply:-150ms}, byte_timeout: ${byte:-30ms}"
      nodes="      - {name: cmc_4, address: 4, model: whedco-cmc-xy, unit_id: 1, axis_units: {x: 41, y: 42},
         limits: {x_target: $target, y_target: $target}}"
      units=41,42
      ;;
    whedco-slow-poll)
      # Whedco with the axis status polled every 3 s, slower than the profile's 2 s patience for a
      # jog to show (as at the CMC's factory 1200 baud): jog_positive must not end done, nor the
      # axis read Standstill, before a status read after the jog began shows it moving.
      protocol=whedco-cmc baud=38400
      timing="reply_timeout: ${reply:-150ms}, byte_timeout: ${byte:-30ms}"
      nodes="      - {name: cmc_4, address: 4, model: whedco-cmc-xy, unit_id: 1, axis_units: {x: 41, y: 42},
         limits: {x_target: $target, y_target: $target}, poll: {medium: 3s}}"
      units=41
      ;;
    whedco-cmc)
      protocol=whedco-cmc baud=38400
      timing="reply_timeout: ${reply:-150ms}, byte_timeout: ${byte:-30ms}"
      nodes="      - {name: cmc_4, address: 4, model: whedco-cmc, unit_id: 1,
         axis_units: {x: 41, y: 42, w: 43, z: 44},
         limits: {x_target: $target, y_target: $target,
                  w_target: $target, z_target: $target}}"
      units=41,42,43,44
      ;;
    techno-c10 | techno-c116 | techno-c142 | techno-it116g)
      # 200 ms: a CI run on a loaded host (eight tests on two cores) failed techno-c142 (its
      # output was not kept); the same load made the Whedco and Copley simulators answer late.
      protocol=techno-c baud=19200
      timing="reply_timeout: ${reply:-200ms}, byte_timeout: ${byte:-30ms}"
      local units_yaml
      case ${family#techno-} in
        c10) units_yaml="axis_units: {x: 31, y: 32}" units=31,32 ;;
        c116 | c142) units_yaml="axis_units: {x: 31, y: 32, z: 33}" units=31,32,33 ;;
        *) units_yaml="profile_unit: 31" units=31 ;;
      esac
      nodes="      - {name: techno, address: 0, model: $family, unit_id: 1, $units_yaml}"
      ;;
    copley-ascii-file)
      # The seed family copley-ascii re-expressed as a protocol file
      # (config/protocols/copley-ascii-file.yaml), at the amplifiers' power-up 9600 baud.
      protocol=copley-ascii-file baud=9600 timing="reply_timeout: ${reply:-150ms}"
      nodes="      - {name: amp0, address: 0, model: copley-amplifier-file, unit_id: 1, profile_unit: 21}
      - {name: amp3, address: 3, model: copley-amplifier-file, unit_id: 2, profile_unit: 22}"
      units=21,22
      ;;
    newport-smc100 | newport-esp301 | parker-6k)
      # Controllers described by protocol files (config/protocols/FAMILY.yaml), two axes at
      # addresses 1 and 2 (SMC100 controllers, ESP301 axes, 6K axes).
      local name first limit
      case $family in
        newport-smc100) baud=57600 name=smc first=51 limit=245000 ;;
        newport-esp301) baud=19200 name=esp first=61 limit=245000 ;;
        parker-6k) baud=9600 name=axis first=71 limit=400000 ;;
      esac
      protocol=$family
      timing="reply_timeout: ${reply:-100ms}, byte_timeout: ${byte:-20ms}"
      nodes="      - {name: ${name}_1, address: 1, model: $family, unit_id: 1, profile_unit: $first,
         limits: {target: {min: -$limit, max: $limit}}}
      - {name: ${name}_2, address: 2, model: $family, unit_id: 2, profile_unit: $((first + 1)),
         limits: {target: {min: -$limit, max: $limit}}}"
      units=$first,$((first + 1))
      ;;
    galil-dmc)
      # A Galil DMC described by its protocol file (config/protocols/galil-dmc.yaml): axes A and
      # B of one controller on one node (address 0: RS-232 has none).
      protocol=galil-dmc baud=115200
      timing="reply_timeout: ${reply:-100ms}, byte_timeout: ${byte:-20ms}"
      nodes="      - {name: dmc, address: 0, model: galil-dmc, unit_id: 1, axis_units: {a: 81, b: 82},
         limits: {a_target: $target, b_target: $target}}"
      units=81,82
      ;;
    canopen)
      # Needs a kernel SocketCAN interface: run under scripts/vcan-run (tests/vcan).
      bus="protocol: canopen
    can: {interface: ${FIELDGATE_VCAN_IF:-vcan0}}
    timing: {reply_timeout: 500ms, retries: 1, offline_after: 3, probe_interval: 300ms,
             heartbeat_timeout: 500ms, start_nodes: true}
    nodes:
      - {name: drive_2, address: 2, model: canopen-cia402, unit_id: 1, profile_unit: 21,
         limits: {target: {min: -10000000, max: 10000000}}}"
      units=21
      return 0
      ;;
    *)
      echo "unknown family $family"
      return 2
      ;;
  esac
  bus="protocol: $protocol
    serial: {device: $device, baud: $baud}
    timing: {$timing, probe_interval: 300ms}
    nodes:
$nodes"
}

# axis_family_start FAMILY BUILD_DIR DIR: starts FAMILY's simulator on DIR/port and sets bus and
# units (axis_family_bus) and axis_args (tools/axis.py options fitting the family). The simulator
# is a job of the calling shell; its control channel (stdin) is the FIFO DIR/sim.in, through
# which --fault-command injects a device fault.
axis_family_start() {
  local family=$1 build=$2 dir=$3 sim
  axis_family_bus "$family" "$dir/port" || return
  mkfifo "$dir/sim.in"
  # Held open read-write by the calling shell: the simulator never reads EOF, a writer never blocks.
  exec {sim_control}<>"$dir/sim.in"
  case $family in
    copley)
      sim=("$build/sim/copley/fieldgate-sim-copley" --nodes 0,3)
      # Following error (0xa4 bit 9) on the amplifier of the axis under test.
      axis_args=(--distance 20000 --expect-homed --fault-command
                 'case {unit} in 21) n=0 ;; *) n=3 ;; esac; echo "fault $n 512" >'"$dir/sim.in")
      ;;
    copley-slow-poll)
      sim=("$build/sim/copley/fieldgate-sim-copley" --nodes 0)
      axis_args=(--distance 20000 --expect-homed)
      ;;
    canopen)
      "$build/sim/canopen/fieldgate-sim-canopen" --interface "${FIELDGATE_VCAN_IF:-vcan0}" \
        --nodes 2 <"$dir/sim.in" >"$dir/sim.log" 2>&1 &
      # The refused target leaves the drive enabled: the reset after it must not switch it off.
      axis_args=(--distance 4000 --refused-target 20000000 --no-device-error)
      for _ in $(seq 100); do grep -q '^ready' "$dir/sim.log" && return 0; sleep 0.1; done
      echo "the CANopen simulator did not start"
      cat "$dir/sim.log"
      return 1
      ;;
    ims)
      sim=("$build/sim/ims/fieldgate-sim-ims" --axes A,B)
      axis_args=(--distance 3000 --refused-target 200000 --no-device-error)
      ;;
    centent)
      sim=("$build/sim/centent/fieldgate-sim-centent" --units 0 --power-up)
      axis_args=(--distance 1024000 --refused-target 20000000 --tolerance 4 --no-device-error)
      ;;
    whedco | whedco-slow-poll | whedco-cmc)
      local axes=XY letters='41) a=X ;;'
      [ "$family" = whedco-cmc ] && axes=WXYZ letters='41) a=X ;; 42) a=Y ;; 43) a=W ;;'
      sim=("$build/sim/whedco/fieldgate-sim-whedco" --units 4 --axes "$axes" --baud 38400)
      # Excessive following error (code 3) on the axis under test.
      axis_args=(--distance 20000 --velocity 20000 --jog-velocity 2000 --home-velocity 2000
                 --refused-target 2000000 --fault-command
                 "case {unit} in $letters *) a=${axes: -1} ;; esac; echo \"fault 4 \$a 3\" >$dir/sim.in")
      ;;
    galil-dmc)
      # The Galil protocol file against its independent unit (tests/independent/galil_unit.py).
      axis_family_bus "$family" "$dir/port" 200ms 20ms
      protocols=$(cd "$(dirname "${BASH_SOURCE[0]}")/../../config/protocols" && pwd)
      sim=(/usr/bin/python3 "$(cd "$(dirname "${BASH_SOURCE[0]}")/../independent" && pwd)/galil_unit.py"
           --axes AB)
      axis_args=(--distance 20000 --refused-target 2000000 --no-device-error)
      ;;
    newport-smc100 | newport-esp301 | parker-6k)
      # Controllers described by protocol files, against the simulators written apart from those
      # files (tests/independent/); Python, so their reply timeouts are those run.sh gives them.
      axis_family_bus "$family" "$dir/port" 200ms 20ms
      protocols=$(cd "$(dirname "${BASH_SOURCE[0]}")/../../config/protocols" && pwd)
      local independent
      independent=$(cd "$(dirname "${BASH_SOURCE[0]}")/../independent" && pwd)
      case $family in
        newport-smc100)
          sim=(/usr/bin/python3 "$independent/smc100_unit.py" --addresses 1,2)
          axis_args=(--distance 20000 --refused-target 300000 --expect-homed --no-device-error)
          ;;
        newport-esp301)
          sim=(/usr/bin/python3 "$independent/esp301_unit.py" --axes 1,2)
          axis_args=(--distance 20000 --refused-target 300000 --no-device-error)
          ;;
        parker-6k)
          sim=(/usr/bin/python3 "$independent/parker6k_unit.py" --axes 2)
          axis_args=(--distance 20000 --refused-target 600000 --expect-homed --no-device-error)
          ;;
      esac
      ;;
    techno-*)
      sim=("$build/sim/techno/fieldgate-sim-techno" --variant "${family#techno-}" --baud 19200)
      # Beyond the simulator's travel (100000 steps from the home switch): the controller
      # answers 2, "outside the reach of the axes".
      axis_args=(--distance 2000 --refused-target 9000000 --beyond 200000)
      ;;
  esac
  if [ "${sim[0]}" = /usr/bin/python3 ]; then
    PYTHONDONTWRITEBYTECODE=1 "${sim[@]}" --link "$dir/port" <"$dir/sim.in" >"$dir/sim.log" 2>&1 &
  else
    "${sim[0]}" --link "$dir/port" "${sim[@]:1}" <"$dir/sim.in" >"$dir/sim.log" 2>&1 &
  fi
  wait_for_paths "$dir/port"
}
