#!/usr/bin/env bash
# Installs fieldgate into a scratch root (cmake --install with DESTDIR) and checks the unit
# offline: `systemd-analyze verify` must pass, and `systemd-analyze security` must rate the
# exposure below 3.0 (it prints the score for docs/operations.md). Usage: unit_check.sh BUILD_DIR
set -euo pipefail
build=$1
root=$(mktemp -d)
trap 'rm -rf "$root"' EXIT
DESTDIR="$root" cmake --install "$build" >/dev/null
unit=$(find "$root" -name fieldgate.service -path '*/systemd/system/*')
[ -n "$unit" ] || { echo "FAIL: no fieldgate.service installed"; exit 1; }
for f in sysusers.d/fieldgate.conf fieldgate/models/copley-amplifier.yaml fieldgate/fieldgate.yaml; do
  find "$root" -path "*/$f" | grep -q . || { echo "FAIL: $f not installed"; exit 1; }
done
# verify resolves dependencies and commands inside --root: give it the base targets and kill.
mkdir -p "$root/usr/lib/systemd/system" "$root/bin"
cp /usr/lib/systemd/system/*.target "$root/usr/lib/systemd/system/"
cp /usr/lib/systemd/system/*.slice "$root/usr/lib/systemd/system/" 2>/dev/null || true
cp /usr/bin/kill "$root/bin/kill"
unit_in_root=${unit#"$root"}
systemd-analyze verify --root="$root" "$unit_in_root"
echo "ok: systemd-analyze verify $unit_in_root"
report=$(systemd-analyze security --offline=true --root="$root" "$unit_in_root" 2>&1)
score=$(sed -n 's/.*Overall exposure level for fieldgate.service: \([0-9.]*\).*/\1/p' <<<"$report")
[ -n "$score" ] || { echo "FAIL: no security score"; echo "$report"; exit 1; }
echo "systemd-analyze security exposure: $score"
awk -v s="$score" 'BEGIN { exit !(s < 3.0) }' || { echo "FAIL: exposure $score >= 3.0"; echo "$report"; exit 1; }
grep -q '^✓ RestrictAddressFamilies=' <<<"$report" || echo "note: address families reported as open"
echo "ok: exposure $score < 3.0"
