#!/bin/bash
# fieldgate-sim-canopen on a kernel vcan0 with can-utils (candump, cansend) as the foreign peer.
# Runs inside scripts/vcan-run, so possibly inside User-Mode Linux: all checks share one boot.
# Under UML every fork costs 10-150 ms (more when the host is busy), so the frame log is read
# with bash builtins and only cansend is forked per request.
#   sim_canopen_vcan.sh PATH/TO/fieldgate-sim-canopen
set -u
sim=${1:?usage: sim_canopen_vcan.sh PATH/TO/fieldgate-sim-canopen}
ifname=${FIELDGATE_VCAN_IF:-vcan0}
timeout_s=10

work=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null; done
  wait 2>/dev/null
  rm -rf "$work"
}
trap cleanup EXIT

failures=0
checks=0
pass() {
  checks=$((checks + 1))
  echo "ok   $*"
}
fail() {
  checks=$((checks + 1))
  failures=$((failures + 1))
  echo "FAIL $*"
}

# A sleep without a fork: read with a timeout from a FIFO nobody writes to.
mkfifo "$work/never"
exec 5<>"$work/never"
nap() { read -r -t "${1:-0.02}" -u 5 _; }

# frames[] holds every frame candump logged so far, as "ID#DATA".
dump=$work/candump.log
frames=()
partial=""
pump() {
  local line
  while IFS= read -r -u 4 line; do
    line=$partial$line
    partial=""
    frames+=("${line##* }")
  done
  partial+=$line
}
mark() {
  pump
  M=${#frames[@]}
}

# Waits for a frame matching the regex (anchored) at index >= $2; sets FOUND.
wait_frame() {
  local pattern=$1 from=$2 limit=${3:-$timeout_s} i
  local deadline=$((SECONDS + limit))
  i=$from
  while :; do
    pump
    for (( ; i < ${#frames[@]}; i++)); do
      if [[ ${frames[i]} =~ ^${pattern}$ ]]; then
        FOUND=${frames[i]}
        return 0
      fi
    done
    ((SECONDS > deadline)) && return 1
    nap
  done
}
# True when no frame matching the regex arrives at index >= $2 within $3 seconds.
no_frame() {
  local pattern=$1 from=$2 i
  nap "$3"
  pump
  for ((i = from; i < ${#frames[@]}; i++)); do [[ ${frames[i]} =~ ^${pattern}$ ]] && return 1; done
  return 0
}

expect_eq() {  # description, got, want
  if [[ $2 == "$3" ]]; then pass "$1: $2"; else fail "$1: got '$2', want '$3'"; fi
}
expect_frame() {  # description, regex, from-index
  if wait_frame "$2" "$3"; then pass "$1: $FOUND"; else fail "$1 (no frame matching $2)"; fi
}

# SDO request to a node; sets REPLY to its response ("" when none came).
sdo() {
  local node=$1 request=$2
  REPLY=""
  mark
  local tx rx
  printf -v tx '%03X' $((0x600 + node))
  printf -v rx '%03X' $((0x580 + node))
  cansend "$ifname" "$tx#$request"
  wait_frame "$rx#[0-9A-F]{16}" "$M" && REPLY=$FOUND
}

echo "interface $ifname on $(uname -r)"
: >"$dump"
candump -L "$ifname" >"$dump" 2>"$work/candump.err" &
pids+=("$!")
exec 4<"$dump"
# candump is listening once it logs a probe frame (0x7FF is no CANopen COB-ID).
listening=false
for _ in $(seq 100); do
  cansend "$ifname" 7FF#01
  mark
  [[ " ${frames[*]} " == *" 7FF#01 "* ]] && listening=true && break
  nap 0.1
done
if ! $listening; then
  echo "FAIL candump does not log frames on $ifname"
  cat "$work/candump.err"
  exit 1
fi

mkfifo "$work/control"
: >"$work/sim.out"
mark
start=$M
"$sim" --interface "$ifname" --nodes 2,3 --heartbeat 200 --sdo-timeout 10000 \
  <"$work/control" >"$work/sim.out" 2>"$work/sim.err" &
sim_pid=$!
pids+=("$sim_pid")
exec 3>"$work/control"
trap '' PIPE  # a simulator that died must show up as failed checks, not kill this script
control() { echo "$*" >&3; }

exec 6<"$work/sim.out"
ready=""
deadline=$((SECONDS + timeout_s))
while ((SECONDS <= deadline)); do
  read -r -u 6 ready && break
  kill -0 "$sim_pid" 2>/dev/null || break
  nap 0.05
done
show_logs() {
  echo "--- candump -L $ifname"
  cat "$dump"
  echo "--- simulator stdout"
  cat "$work/sim.out"
  echo "--- simulator stderr"
  cat "$work/sim.err"
}
if [[ $ready != ready* ]]; then
  fail "simulator started"
  show_logs
  exit 1
fi
pass "simulator started: $ready"

expect_frame "boot-up of node 2" '702#00' "$start"
expect_frame "boot-up of node 3" '703#00' "$start"
expect_frame "heartbeat of node 2, pre-operational" '702#7F' "$start"
expect_frame "heartbeat of node 3, pre-operational" '703#7F' "$start"

sdo 2 4000100000000000
expect_eq "SDO upload 0x1000 from node 2" "$REPLY" 582#4300100092010200

# Segmented upload of 0x1008 from node 3, one cansend per segment.
sdo 3 4008100000000000
init=$REPLY
name=""
if [[ $init == 583#410810001B000000 ]]; then
  toggle=0
  for _ in 1 2 3 4 5 6 7 8; do
    sdo 3 "$((6 + toggle))000000000000000"
    [[ $REPLY == 583#* ]] || break
    byte0=$((16#${REPLY:4:2}))
    ((byte0 & 0xE0)) && break  # not an upload segment (an abort)
    (((byte0 >> 4 & 1) == toggle)) || break
    for ((i = 0, n = 7 - (byte0 >> 1 & 7); i < n; i++)); do
      printf -v ch '%b' "\\x${REPLY:$((6 + 2 * i)):2}"
      name+=$ch
    done
    toggle=$((1 - toggle))
    ((byte0 & 1)) && break
  done
fi
expect_eq "segmented SDO upload 0x1008 from node 3 (initiate $init, last $REPLY)" "$name" \
  "fieldgate sim CiA 402 drive"

sdo 2 2B171000F4010000
expect_eq "SDO download 0x1017 := 500 ms" "$REPLY" 582#6017100000000000
sdo 2 4034120000000000
expect_eq "SDO abort 0x06020000 for unknown object 0x1234" "$REPLY" 582#8034120000000206

mark
cansend "$ifname" 604#4000100000000000
if no_frame '584#.*' "$M" 0.5; then pass "no answer for node 4 (not simulated)"; else
  fail "node 4 is not simulated but answered"
fi

mark
cansend "$ifname" 000#0102
expect_frame "TPDO1 of node 2 on NMT start (statusword 0x0650, position 0)" '182#500600000000' "$M"
expect_frame "heartbeat of node 2, operational" '702#05' "$M"

mark
control "fault 2 0x2310"
expect_frame "EMCY of node 2 for injected fault 0x2310" '082#1023030000000000' "$M"
sdo 2 4041600000000000
expect_eq "statusword of node 2 in Fault (0x0618)" "$REPLY" 582#4B41600018060000
mark
cansend "$ifname" 602#2B40600080000000
expect_frame "EMCY code 0 from node 2 after fault reset" '082#0000000000000000' "$M"

# A profile position move in real time: enable, new setpoint, handshake, target reached.
ok=true
for request in 2F60600001000000 2B40600006000000 2B40600007000000 2B4060000F000000 \
  237A6000D0070000 move 2B4060001F000000 2B4060000F000000; do
  if [[ $request == move ]]; then
    mark
    move_start=$M
    continue
  fi
  sdo 2 "$request"
  [[ $REPLY == 582#60* ]] || ok=false
done
if $ok; then pass "node 2 enabled in profile position mode, setpoint 2000 sent"; else
  fail "enabling node 2 / sending the setpoint: last reply '$REPLY'"
fi
expect_frame "TPDO1 of node 2 while moving (statusword 0x1237 or 0x0237)" \
  '182#37[01]2[0-9A-F]{8}' "$move_start"
expect_frame "TPDO1 of node 2 at target (statusword 0x0637, position 2000)" '182#3706D0070000' \
  "$move_start"

control "power-off 3"
nap 0.3
mark
if no_frame '703#.*' "$M" 1; then pass "node 3 silent while powered off"; else
  fail "node 3 powered off but still sends"
fi
mark
control "power-on 3"
expect_frame "boot-up of node 3 after power-on" '703#00' "$M"

control "quit"
deadline=$((SECONDS + timeout_s))
while kill -0 "$sim_pid" 2>/dev/null && ((SECONDS <= deadline)); do nap 0.05; done
if kill -0 "$sim_pid" 2>/dev/null; then
  fail "simulator exits on quit"
else
  wait "$sim_pid"
  rc=$?
  expect_eq "simulator exit status on quit" "$rc" 0
fi

((failures > 0)) && show_logs
echo "$((checks - failures))/$checks checks passed"
((failures == 0))
