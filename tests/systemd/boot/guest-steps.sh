#!/bin/bash
# The steps of scripts/boot-test, run inside the guest by fieldgate-boot-test.service once the
# boot is done. Boot "install" installs the packages with dpkg and powers off; boot "steps"
# checks the first boot after the install, then start, reloads, sandbox, watchdog, journal and
# stop. Every line starts with "boot-test:"; the last is PASS or FAIL. The guest powers off at
# the end either way.
set -u
here=/opt/fieldgate-boot-test
log=$here/steps.log
exec > >(tee -a "$log") 2>&1
boot=$(sed -n 's/.*fieldgate\.boot=\([a-z]*\).*/\1/p' /proc/cmdline)
failed=0
t0=$(date +%s%N)
ms() { echo $((($(date +%s%N) - $1) / 1000000)); }
say() { echo "boot-test: $*"; }
ok() { say "ok: $*"; }
bad() {
  say "FAIL: $*"
  failed=$((failed + 1))
}
expect() {  # NAME EXPECTED ACTUAL
  if [ "$2" = "$3" ]; then ok "$1 ($3)"; else bad "$1: expected '$2', got '$3'"; fi
}
step() { say "--- $* (at $(ms "$t0") ms)"; }
prop() { systemctl show -P "$1" fieldgate; }
finish() {
  say "journal of fieldgate.service, this boot:"
  journalctl -b -u fieldgate --no-pager -o short-monotonic | sed 's/^/boot-test: | /' | tail -n 80
  if [ "$failed" = 0 ]; then say "PASS (boot $boot, $(ms "$t0") ms)"; else say "FAIL: $failed check(s) failed (boot $boot)"; fi
  sync
  systemctl poweroff --no-block
  exit 0
}

state=$(systemctl is-system-running --wait)
say "boot $boot: system $state, $(systemctl --version | head -n 1), kernel $(uname -r)"

if [ "$boot" = install ]; then
  step "install the packages with dpkg (maintainer scripts under systemd)"
  if dpkg -i "$here"/debs/*.deb; then ok "dpkg -i"; else bad "dpkg -i failed"; fi
  expect "the unit is enabled" enabled "$(systemctl is-enabled fieldgate)"
  expect "the unit is not started" inactive "$(systemctl is-active fieldgate)"
  id fieldgate >/dev/null 2>&1 && ok "user fieldgate exists: $(id fieldgate)" || bad "no user fieldgate"
  warnings=$(journalctl -b --no-pager -p warning -o cat | grep -i -E 'fieldgate\.service|riscv_hwprobe|uretprobe')
  [ -z "$warnings" ] && ok "no warning about the unit when systemd loaded it" ||
    bad "systemd warned about the unit: $warnings"
  [ "$failed" = 0 ] && say "install done"
  finish
fi

# --- boot "steps" ------------------------------------------------------------------------------
step "first boot after the install: the unit started by the boot, the shipped configuration"
for _ in $(seq 100); do [ "$(systemctl is-active fieldgate)" = activating ] || break; sleep 0.2; done
expect "started at boot" active "$(systemctl is-active fieldgate)"
pid=$(prop MainPID)
say "StatusText: $(prop StatusText)"
journalctl -b -u fieldgate -o cat | grep -q 'no field bus configured' &&
  ok "the journal says no field bus is configured" || bad "no journal line about the missing buses"
devices=$(ls -l /proc/"$pid"/fd 2>/dev/null | grep -E '/dev/tty|/dev/pts|socket' | sed 's/.*-> //' | sort | uniq -c | tr '\n' ' ')
if ls -l /proc/"$pid"/fd | grep -q -E '/dev/(tty|pts)'; then bad "the shipped configuration opened a terminal: $devices"; else ok "no serial port open (fds: $devices)"; fi
warnings=$(journalctl -b --no-pager -p warning -o cat | grep -i -E 'fieldgate\.service|riscv_hwprobe|uretprobe')
[ -z "$warnings" ] && ok "no warning about the unit at boot" || bad "systemd warned about the unit: $warnings"

step "a site configuration on simulators: Copley on a PTY, CANopen on vcan0, an empty UART"
systemctl stop fieldgate
mkdir -p /run/fieldgate-sim
/usr/lib/fieldgate/sim/fieldgate-sim-copley --link /run/fieldgate-sim/copley --nodes 0,3 \
  </dev/null >/run/fieldgate-sim/copley.log 2>&1 &
/usr/lib/fieldgate/sim/fieldgate-sim-canopen -i vcan0 -n 2 </dev/null >/run/fieldgate-sim/canopen.log 2>&1 &
for _ in $(seq 100); do [ -e /run/fieldgate-sim/copley ] && break; sleep 0.1; done
# A serial device of group dialout, as udev makes them.
pts=$(readlink -f /run/fieldgate-sim/copley)
chgrp dialout "$pts" && chmod 660 "$pts"
# The ttyUSB and ttyACM nodes of an adapter whose driver is not loaded.
mknod -m 660 /dev/ttyUSB7 c 188 7 && chgrp dialout /dev/ttyUSB7
mknod -m 660 /dev/ttyACM7 c 166 7 && chgrp dialout /dev/ttyACM7
chgrp dialout /dev/ttyS2 /dev/ttyS3 && chmod 660 /dev/ttyS2 /dev/ttyS3
site_config() {  # EXTRA_COPLEY_NODE
  cat <<YAML
modbus:
  listen: 0.0.0.0:502
  writes_enabled: false
models: /usr/share/fieldgate/models
buses:
  - name: copley
    protocol: copley-ascii
    serial: {device: /run/fieldgate-sim/copley, baud: 9600}
    timing: {reply_timeout: 100ms, retries: 1, offline_after: 3, probe_interval: 2s}
    nodes:
      - {name: a0, address: 0, model: copley-amplifier, unit_id: 1}
$1
  - name: can
    protocol: canopen
    can: {interface: vcan0}
    timing: {reply_timeout: 500ms, retries: 1, offline_after: 3, probe_interval: 1s}
    nodes:
      - {name: drive_2, address: 2, model: canopen-cia402, unit_id: 3}
  - name: empty
    protocol: copley-ascii
    serial: {device: /dev/ttyS2, baud: 9600}
    timing: {reply_timeout: 50ms, retries: 0, offline_after: 1, probe_interval: 500ms}
    nodes:
      - {name: nobody, address: 0, model: copley-amplifier, unit_id: 10}
YAML
}
site_config "" >/etc/fieldgate/fieldgate.yaml
/usr/bin/fieldgate check /etc/fieldgate/fieldgate.yaml && ok "fieldgate check" || bad "fieldgate check refused the site configuration"

step "systemctl start"
t=$(date +%s%N)
systemctl start fieldgate
rc=$?
took=$(ms "$t")
expect "systemctl start: status" 0 "$rc"
say "systemctl start took $took ms (returns once READY=1 arrived: Type=notify)"
expect "active after start" active "$(prop ActiveState)"
journalctl -b -u fieldgate -o cat | grep -q '^ready: ' && ok "READY logged" || bad "no 'ready:' line"
status=$(prop StatusText)
say "StatusText: $status"
[[ $status == "config #1 ("*"in force; buses up "* || $status == "config #1 ("*"; buses up "* ]] &&
  ok "StatusText names the configuration in force" || bad "StatusText: '$status'"
pid=$(prop MainPID)

step "a Modbus client on unit 1 for the rest of the test"
/opt/fieldgate-boot-test/modbus_watch.py 127.0.0.1 502 1 /run/watch.state &
watch_pid=$!
for _ in $(seq 300); do grep -q ' ok=[1-9]' /run/watch.state 2>/dev/null && break; sleep 0.1; done
say "client: $(cat /run/watch.state 2>/dev/null)"
grep -q ' ok=[1-9]' /run/watch.state || bad "the client never read unit 1"
counts() { sed -n "s/.* $1=\([0-9]*\).*/\1/p" /run/watch.state; }

step "sandbox: what the running daemon holds"
fds=$(ls -l /proc/"$pid"/fd | sed -n 's/.*-> //p' | sort | uniq -c | tr -s ' ' | tr '\n' ';')
say "daemon fds: $fds"
[[ $fds == *"$pts"* ]] && ok "the PTY of group dialout is open" || bad "the PTY $pts is not open"
[[ $fds == *"/dev/ttyS2"* ]] && ok "/dev/ttyS2 is open" || bad "/dev/ttyS2 is not open"
# Both simulated nodes answer (the PTY's Copley amplifier, the CANopen drive through its CAN
# socket); the empty UART's node cannot.
for _ in $(seq 150); do [[ $(prop StatusText) == *"nodes online 2/3"* ]] && break; sleep 0.2; done
status=$(prop StatusText)
[[ $status == *"nodes online 2/3"* ]] && ok "the Copley and CANopen nodes are online: $status" || bad "nodes not online: $status"
[[ $fds == *"socket:"* ]] && ok "the daemon holds sockets (CAN, Modbus)" || bad "no socket open"
ss -ltnp 2>/dev/null | grep -q ':502 .*fieldgate' && ok "listening on port 502" ||
  { grep -q ':01F6 ' /proc/net/tcp && ok "listening on port 502" || bad "not listening on 502"; }

step "sandbox: the unit's restrictions applied to a probe (systemd-run with the unit's settings)"
props=()
while IFS= read -r line; do
  case $line in
    '' | '#'* | '['* | Type=* | NotifyAccess=* | Exec* | Restart* | Watchdog* | Timeout* | Description=* | Documentation=* | After=* | Wants=* | WantedBy=* | RuntimeDirectory=*) ;;
    *) props+=(-p "$line") ;;
  esac
done < <(systemctl cat fieldgate | sed -n '/^\[Service\]/,/^\[Install\]/p')
probe=$(systemd-run --quiet --wait --pipe --collect "${props[@]}" /usr/bin/python3 /opt/fieldgate-boot-test/sandbox_probe.py 2>&1)
echo "$probe" | sed 's/^/boot-test: probe: /'
for want in "allowed serial /dev/ttyS3" "allowed CAN raw socket" "allowed TCP listen on port 503" \
  "refused block device" "refused AF_PACKET" "refused write to /etc/fieldgate" "refused chroot" "refused setuid(0)"; do
  grep -q "^$want" <<<"$probe" && ok "sandbox: $want" || bad "sandbox: expected '$want'"
done
for node in ttyUSB ttyACM; do
  grep -q -E "^(allowed|absent) $node" <<<"$probe" && ok "sandbox: a $node node reaches its (missing) driver" ||
    bad "sandbox: the $node rule does not let the node through: $(grep "$node" <<<"$probe")"
done

step "systemctl reload with a good configuration (the watched bus: a node added and a0's poll period; its neighbour bus: its timing)"
before_ok=$(counts ok)
before_conn=$(counts connections)
before_fail=$(($(counts failures) + $(counts exceptions)))
site_config "      - {name: a3, address: 3, model: copley-amplifier, unit_id: 4}" |
  sed -e 's/probe_interval: 500ms}/probe_interval: 700ms}/' \
    -e 's/unit_id: 1}/unit_id: 1, poll: {slow: 2s}}/' >/etc/fieldgate/fieldgate.yaml
t=$(date +%s%N)
systemctl reload fieldgate
rc=$?
say "systemctl reload took $(ms "$t") ms"
expect "good reload: systemctl reload status" 0 "$rc"
sleep 2
expect "good reload: same main pid" "$pid" "$(prop MainPID)"
status=$(prop StatusText)
say "StatusText: $status"
[[ $status == "config #2 ("* ]] && ok "StatusText names config #2" || bad "StatusText: '$status'"
expect "good reload: the client kept its connection" "$before_conn" "$(counts connections)"
expect "good reload: no read failed" "$before_fail" "$(($(counts failures) + $(counts exceptions)))"
[ "$(counts ok)" -gt "$before_ok" ] && ok "reads go on" || bad "no read after the reload"
summary=$(journalctl -b -u fieldgate -o cat | grep 'reloaded:' | tail -n 1)
say "journal: $summary"
[[ $summary == *"(1 of them with node changes applied in place)"* ]] &&
  ok "the watched bus took its node changes in place, its link not reopened" || bad "the watched bus was not changed in place"
journalctl -b -u fieldgate -o cat | grep -q 'bus copley: node a3 (3) added' && ok "node a3 added to the running bus" || bad "no 'node a3 (3) added' line"

step "systemctl reload with a broken configuration"
cp /etc/fieldgate/fieldgate.yaml /run/good.yaml
sed -i 's/^    timing: {reply_timeout: 100ms/    timing: {reply_timeout: 100parsecs/' /etc/fieldgate/fieldgate.yaml
t=$(date +%s%N)
systemctl reload fieldgate
rc=$?
say "systemctl reload took $(ms "$t") ms, status $rc"
[ "$rc" != 0 ] && ok "broken reload: systemctl reload failed" || bad "broken reload: systemctl reload returned 0"
expect "broken reload: still active" active "$(prop ActiveState)"
expect "broken reload: same main pid" "$pid" "$(prop MainPID)"
status=$(prop StatusText)
say "StatusText: $status"
[[ $status == "config #2 ("* ]] && ok "StatusText still names config #2" || bad "StatusText: '$status'"
errors=$(journalctl -b -u fieldgate -p err -o cat | grep 'fieldgate.yaml:[0-9]*:[0-9]*')
say "journal: $(tail -n 2 <<<"$errors" | tr '\n' ' ')"
[ -n "$errors" ] && ok "the error is in the journal at file:line:column" || bad "no error in the journal"
journalctl -b -o cat | grep -q -i 'reload failed\|Reload failed\|control process exited' &&
  ok "systemd logged the failed reload" || say "note: no systemd line about the failed reload"
step "the daemon's own refusal (fieldgate reload --no-check, as root outside the unit)"
/usr/bin/fieldgate reload --no-check --pid "$pid" --runtime-dir /run/fieldgate
rc=$?
[ "$rc" != 0 ] && ok "refused by the daemon: fieldgate reload failed" || bad "fieldgate reload --no-check returned 0"
status=$(prop StatusText)
say "StatusText: $status"
[[ $status == "config #2 ("*"(reload #"*"refused)"* ]] && ok "StatusText says the reload was refused" || bad "StatusText: '$status'"
cp /run/good.yaml /etc/fieldgate/fieldgate.yaml
expect "the client kept its connection through the refusals" "$before_conn" "$(counts connections)"

step "journalctl -p warning: the daemon's warnings at their priority"
journalctl -b -u fieldgate -p warning --no-pager -o verbose --output-fields=PRIORITY,MESSAGE |
  grep -E '^\s+(PRIORITY|MESSAGE)=' | paste - - | sed 's/^\s*/boot-test: | /' | tail -n 12
n4=$(journalctl -b -u fieldgate -p warning..warning -o cat | wc -l)
n3=$(journalctl -b -u fieldgate -p err..err -o cat | wc -l)
say "fieldgate lines at warning: $n4, at error: $n3"
[ "$n4" -gt 0 ] || [ "$n3" -gt 0 ] && ok "the daemon's warnings and errors carry their priority" ||
  bad "no warning or error from the daemon (the empty UART should give some)"
reopens=$(journalctl -b -u fieldgate -o cat | grep -c 'opened /dev/ttyS2')
say "'opened /dev/ttyS2' lines in the journal since the start: $reopens"
[ "$reopens" -le 2 ] && ok "the empty UART's reopens are not logged each time" || bad "the empty UART's reopens fill the journal ($reopens lines)"

step "watchdog: SIGSTOP the daemon"
watchdog=$(prop WatchdogUSec)
t=$(date +%s%N)
kill -STOP "$pid"
for _ in $(seq 1200); do
  now=$(prop MainPID)
  [ "$now" != "$pid" ] && [ "$now" != 0 ] && [ "$(prop ActiveState)" = active ] && break
  sleep 0.1
done
took=$(ms "$t")
newpid=$(prop MainPID)
say "restarted as pid $newpid after $took ms (WatchdogSec $watchdog)"
[ "$newpid" != "$pid" ] && [ "$(prop ActiveState)" = active ] && ok "restarted by the watchdog" || bad "not restarted"
[ "$took" -ge 10000 ] && ok "not before WatchdogSec" || bad "restarted after $took ms, before WatchdogSec"
journalctl -b -u fieldgate -o cat | grep -q -i 'watchdog timeout' && ok "systemd logged the watchdog timeout" ||
  bad "no watchdog timeout in the journal"
pid=$newpid

step "systemctl stop"
kill "$watch_pid" 2>/dev/null
wait "$watch_pid" 2>/dev/null
say "client at the end: $(cat /run/watch.state)"
t=$(date +%s%N)
systemctl stop fieldgate
rc=$?
say "systemctl stop took $(ms "$t") ms"
expect "systemctl stop: status" 0 "$rc"
expect "stop: result" success "$(prop Result)"
expect "stop: the daemon's exit status" 0 "$(prop ExecMainStatus)"
journalctl -b -u fieldgate -o cat | grep -q 'stopping' && ok "the daemon logged its stop (STOPPING=1 sent with it)" || bad "no stop line"

finish
