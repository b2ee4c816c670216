#!/usr/bin/env bash
# A serial line where nothing answers is reopened every probe interval; the journal must not get
# a notice each time. A PTY nobody answers on, the daemon with -v and journal priorities (its
# stderr named in JOURNAL_STREAM, as systemd does): once the link has been reopened at least
# three times (debug lines), exactly one "opened" line may be a notice (<5>).
# Usage: quiet_reopen_log.sh BUILD_DIR SOURCE_DIR
set -uo pipefail
build=$1
src=$2
source "$src/tests/integration/lib.sh"
scratch_dir
models=$src/config/models
# The far end of the line: a PTY held open, never read or written.
/usr/bin/python3 -c '
import os, pty, sys, time
master, slave = pty.openpty()
os.symlink(os.ttyname(slave), sys.argv[1])
while True: time.sleep(60)' "$dir/line" &
wait_for_paths "$dir/line"
gateway_config "$dir/gw.yaml" <<YAML
  - name: silent
    protocol: copley-ascii
    serial: {device: $dir/line, baud: 9600}
    timing: {reply_timeout: 20ms, retries: 0, offline_after: 1, probe_interval: 100ms}
    nodes:
      - {name: a0, address: 0, model: copley-amplifier, unit_id: 1}
YAML
: >"$dir/daemon.log"
JOURNAL_STREAM=$(stat -c '%d:%i' "$dir/daemon.log") \
  "$build/gateway/fieldgate" -v --config "$dir/gw.yaml" >>"$dir/daemon.log" 2>&1 &
for _ in $(seq 300); do
  [ "$(grep -c '^<7>bus silent: opened ' "$dir/daemon.log")" -ge 3 ] && break
  sleep 0.1
done
quiet=$(grep -c '^<7>bus silent: opened ' "$dir/daemon.log")
noticed=$(grep -c '^<5>bus silent: opened ' "$dir/daemon.log")
[ "$quiet" -ge 3 ] && echo "ok: reopened $quiet times at debug" ||
  { echo "FAIL: the link was not reopened at debug three times"; cat "$dir/daemon.log"; fail=1; }
check "notices of 'opened'" 1 "$noticed"
# Nothing the family notes while a silent line is reopened reaches the journal either.
check "notices about the bus once it is reopened quietly" 0 \
  "$(awk '/^<7>bus silent: opened /{q=1} q && /^<[0-5]>bus silent: /{n++} END{print n+0}' "$dir/daemon.log")"
[ $fail = 0 ] || tail -n 40 "$dir/daemon.log"
exit $fail
