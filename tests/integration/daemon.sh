# Sourced by the integration scripts: starts the daemon as a job of the calling shell (so its
# EXIT trap's `kill $(jobs -p)` stops it) and waits for the default Modbus listener.
# start_daemon FIELDGATE CONFIG LOG: sets `port`; exits 1 with the log if the daemon never listens.
start_daemon() {
  # The log is created here, not by the job's redirection: the job may not have run yet when
  # the loop below first reads it.
  : >"$3"
  "$1" --config "$2" >"$3" 2>&1 &
  port=""
  for _ in $(seq 100); do
    port=$(sed -n 's/.*modbus: listening on 127.0.0.1:\([0-9]*\).*/\1/p' "$3")
    [ -n "$port" ] && break
    sleep 0.1
  done
  [ -n "$port" ] || { echo "daemon did not start"; cat "$3"; exit 1; }
}
