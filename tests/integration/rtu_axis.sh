#!/usr/bin/env bash
# mbpoll -m rtu, a Modbus RTU master this project did not write, moves one simulated axis of a
# serial family through the daemon's RTU port (a PTY pair paced at the line's baud rate), using
# only the axis profile page: read the position, power on and home where the axis supports it,
# write target (and velocity), command move_absolute with a new sequence number, poll the status
# until done and check the position read back is the target.
# Usage: rtu_axis.sh FAMILY FIELDGATE BUILD_DIR MODELS_DIR
# FIELDGATE_RTU_TIMEOUT: the RTU response timeout in seconds, in the daemon and in mbpoll
# (default 1; canopen under QEMU's TCG needs more).
set -euo pipefail
family=$1 fieldgate=$2 build=$3 models=$4
timeout=${FIELDGATE_RTU_TIMEOUT:-1}
here=$(cd "$(dirname "$0")" && pwd)
source "$here/lib.sh"
source "$here/axis_family.sh"
baud=19200
scratch_dir

axis_family_start "$family" "$build" "$dir"
# 8E1 on the emulated line: 11 bits a character.
"$here/rtu_wire_relay.py" "$dir/gw-rtu" "$dir/master" "$baud" 11 >"$dir/relay.log" 2>&1 &
wait_for_paths "$dir/master"
unit=${units%%,*}
distance=0 velocity="" home_velocity="" tolerance=0
set -- "${axis_args[@]}"
while [ $# -gt 0 ]; do
  case $1 in
    --distance) distance=$2; shift 2 ;;
    --velocity) velocity=$2; shift 2 ;;
    --home-velocity) home_velocity=$2; shift 2 ;;
    --tolerance) tolerance=$2; shift 2 ;;
    --expect-homed | --no-device-error) shift ;;
    *) shift 2 ;;
  esac
done

one_bus_config "$dir/gw.yaml" "$family" "modbus_rtu:
  device: $dir/gw-rtu
  baud: $baud
  parity: even
  response_timeout: ${timeout}s"
start_daemon "$fieldgate" "$dir/gw.yaml" "$dir/daemon.log" "modbus rtu: serving on"

check() {  # check NAME DETAIL COMMAND...: the check passes when COMMAND succeeds
  if "${@:3}"; then echo "ok: $1"; else echo "FAIL: $1 ($2)"; fail=1; fi
}
mbpoll_args=(-m rtu -b "$baud" -P even -o "$timeout" -a "$unit") mbpoll_target=$dir/master
write32() { mb -t 4:int -B -r "$1" -- "$2" >/dev/null; }  # write32 ADDRESS VALUE
# page: reads input registers 0-11 of the profile into the array in[] (false if no answer).
page() {
  local out
  out=$(mb -t 3 -r 0 -c 12) || return 1
  mapfile -t in < <(sed -n 's/^\[\([0-9]*\)\]:[[:space:]]*\([0-9]*\).*/\2/p' <<<"$out")
  [ "${#in[@]}" -eq 12 ]
}
position() { local v=$((in[0] * 65536 + in[1])); echo $((v >= 2147483648 ? v - 4294967296 : v)); }
status() { echo "$(position) status 0x$(printf %04x "${in[4]}") state ${in[5]} seq ${in[7]}" \
  "cmd_status ${in[8]} cmd ${in[9]} cmd_error 0x$(printf %04x "${in[10]}")"; }
supports() { [ $((in[11] >> $1 & 1)) -eq 1 ]; }
seq=0
# command CODE NAME: writes command_code and a new sequence number (function 16), then polls
# until the command is no longer busy; succeeds when it ended done.
command() {
  seq=$((seq % 65535 + 1))
  [ "$seq" -eq "${in[7]}" ] && seq=$((seq % 65535 + 1))
  local out
  if ! out=$(mb -t 4 -r 8 -- "$1" "$seq"); then
    check "$2 written" "$out" false
    return
  fi
  local seen=()
  for _ in $(seq 600); do
    page && [ "${in[7]}" -eq "$seq" ] && [ "${in[8]}" -ne 1 ] && break
    [ "${#in[@]}" -eq 12 ] && [ "${in[7]}" -eq "$seq" ] && seen+=("$(position)")
    sleep 0.05
  done
  echo "info: $2: positions read while busy: ${seen[*]:-none}"
  check "$2 done (sequence $seq)" "$(status)" ended_done
}
ended_done() { [ "${in[7]}" -eq "$seq" ] && [ "${in[8]}" -eq 2 ]; }
online() { page && [ $((in[4] >> 9 & 1)) -eq 1 ]; }
at_target() {  # at_target TARGET: within the family's tolerance and not moving
  local diff=$(($(position) - $1))
  [ "${diff#-}" -le "$tolerance" ] && [ $((in[4] >> 2 & 1)) -eq 0 ]
}

# Wait until the axis is online (status bit 9).
for _ in $(seq 100); do online && break; sleep 0.1; done
check "mbpoll rtu reads profile unit $unit online" "$(tail -n 5 "$dir/daemon.log")" online
[ $fail -eq 0 ] || exit 1
seq=${in[7]}
echo "info: start $(status)"
if [ "${in[5]}" -eq 6 ]; then command 10 reset; fi
if supports 1; then
  command 1 power_on
  # PLCopen's MC_Power: done means the axis is enabled; the next command must not find it Disabled.
  check "power_on done leaves the axis enabled, not Disabled ($(status))" "" \
    test $((in[4] & 1)) -eq 1 -a "${in[5]}" -ne 0
fi
if supports 3; then
  if [ -n "$home_velocity" ]; then
    check "mbpoll rtu writes home velocity $home_velocity" "" write32 2 "$home_velocity"
  fi
  command 3 home
fi
check "mbpoll rtu reads the position" "" page
start=$(position)
target=$((start + distance))
check "mbpoll rtu writes target $target" "" write32 0 "$target"
if [ -n "$velocity" ]; then
  check "mbpoll rtu writes velocity $velocity" "" write32 2 "$velocity"
fi
command 4 move_absolute
page || true
check "position read back by mbpoll rtu is $target (moved from $start)" "$(status)" at_target "$target"
[ $fail -eq 0 ] || { echo "--- daemon log"; tail -n 40 "$dir/daemon.log"; }
exit $fail
